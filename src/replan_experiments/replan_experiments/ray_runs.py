"""The runs of the experiments as Ray tasks (``experiments.sh --ray ADDRESS``): the cache stays
with the caller (``Runner.run``), each run to be made becomes one task that runs the scenario's
process graph on a node, on a ROS_DOMAIN_ID no other task of that node holds, and sends the
run's folder back (the bag only when asked). Ray retries a task whose worker or node died;
a run that fails for its own reasons comes back and is reported as with ``--jobs``.

Ray is optional (``scripts/setup.sh --with-ray``): it is imported only here, and only when a
``RayRunner`` is made. docs/cluster.md says how to start a cluster and what a node needs.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

from replan_experiments.plan import ExperimentError
from replan_experiments.runs import (
    DEFAULT_DOMAIN_BASE,
    Runner,
    code_fingerprint,
    git_revision,
)
from replan_ros.launch.domain import domain_slot, loopback_dds

GRAPH_SLOT = 'graph_slot'      # Ray custom resource: process graphs a node runs at once
# A run whose worker or node dies is made again by Ray (a system failure); a run is never
# retried for an exception of ours: that is a bug to see, not to hide.
MAX_RETRIES = 3
RUN_TIMEOUT_S = 3600.0          # as the local runner's


def _node_root() -> Path:
    """The checkout this node runs (the shell that started ``ray start`` sourced its
    scripts/env.sh, which exports REPLAN_ROOT)."""
    root = os.environ.get('REPLAN_ROOT')
    if not root:
        raise ExperimentError(f'node {socket.gethostname()}: REPLAN_ROOT is not set: start '
                              'ray there from a shell that sourced scripts/env.sh')
    return Path(root)


def node_code() -> dict:
    """What this node runs: host, checkout, its code fingerprint and git revision."""
    root = _node_root()
    config = Path(os.environ.get('REPLAN_CONFIG', root / 'config')).resolve()
    return {'host': socket.gethostname(), 'root': str(root),
            'code': code_fingerprint(config.parent), 'revision': git_revision(root),
            'blas': os.environ.get('OPENBLAS_CORETYPE', '')}


def mismatch(node: dict, code: str, revision: str) -> str | None:
    """The one line that refuses a node running other code than the caller, else None."""
    if node['code'] == code:
        return None
    return (f'node {node["host"]} runs other code ({node["root"]}: revision '
            f'{node["revision"]}, code {node["code"]}, BLAS kernels '
            f'{node.get("blas") or "unset"}) than this checkout (revision {revision}, code '
            f'{code}, BLAS kernels {os.environ.get("OPENBLAS_CORETYPE") or "unset"}): check out '
            'the same revision there, run scripts/setup.sh --with-ray, and start Ray there '
            'from a shell that sourced scripts/env.sh')


_OWNER = '.owner'     # in a run folder: the lock its worker holds while the run lasts


def _unowned(owner: Path) -> bool:
    """Whether nobody holds the lock of ``owner``: its worker is gone."""
    try:
        with open(owner, 'a') as handle:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
    except OSError:         # held (BlockingIOError), or removed by its worker meanwhile
        return False


@contextlib.contextmanager
def work_folder(base: Path | None = None):
    """A fresh folder for one run on this node, in ``base`` (default /tmp/replan-ray-runs),
    removed on leaving. Its worker holds an flock on the folder's ``.owner`` file while it is
    in use; the folders of runs whose worker was killed (no clean-up ran, the kernel dropped
    the lock) are removed here. A lock and not a pid says who is alive: workers of two
    clusters on one machine may live in PID namespaces of their own (``unshare --pid``), where
    the other's pids do not exist, and must not remove each other's runs."""
    base = base or Path(tempfile.gettempdir()) / 'replan-ray-runs'
    base.mkdir(exist_ok=True)
    for old in base.iterdir():
        # Without an owner file it is being made (its lock is taken before it is named).
        if (old / _OWNER).is_file() and _unowned(old / _OWNER):
            shutil.rmtree(old, ignore_errors=True)
    folder = Path(tempfile.mkdtemp(prefix=f'{os.getpid()}-', dir=base))
    taking = folder / (_OWNER + '.new')
    with open(taking, 'w') as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        taking.rename(folder / _OWNER)      # named only once locked: never seen free
        try:
            yield folder
        finally:
            shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def _held(lock_file: str | None):
    """The caller's --lock FILE, taken on this node for the run (as the local runner does)."""
    if lock_file is None:
        yield
        return
    with open(lock_file, 'a') as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield


def _unblock_signals() -> None:
    """In the scenario process before it starts: SIGINT and SIGTERM unblocked. A Ray worker
    blocks SIGINT, and the signal mask is inherited across fork and exec, so the graph's nodes
    would never see the launcher's SIGINT and be killed before the recorder closes the bag."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})


def read_back(folder: Path, bag: bool) -> dict[str, bytes]:
    """The run folder's files (relative path -> bytes), without the bag unless ``bag`` and
    without the worker's lock."""
    files = {}
    for path in sorted(folder.rglob('*')):
        rel = path.relative_to(folder).as_posix()
        if path.is_file() and rel != _OWNER and (bag or not rel.startswith('bag/')):
            files[rel] = path.read_bytes()
    return files


def make_run(input_yaml: str, code: str, revision: str, options: list[str],
             domain_base: int, lock_file: str | None) -> dict:
    """The Ray task: one scenario run on this node. Returns {'refused': line} if the node
    runs other code, else {'exit': code, 'folder': the node's run folder, 'files': the run
    folder's files, 'host': ...}."""
    node = node_code()
    refused = mismatch(node, code, revision)
    if refused:
        return {'refused': refused}
    with work_folder() as folder:
        (folder / 'input.yaml').write_text(input_yaml)
        # The graph ends with the worker: a worker killed by the test or the OOM killer must
        # not leave its graph running while Ray makes the run again elsewhere.
        die = ['setpriv', '--pdeathsig', 'TERM'] if shutil.which('setpriv') else []
        with domain_slot(domain_base) as (domain, fd), _held(lock_file), \
                open(folder / 'output.log', 'w') as output:
            # Each graph on its own machine, whatever the worker's environment says.
            env = loopback_dds(dict(os.environ, ROS_DOMAIN_ID=str(domain)),
                               _node_root() / 'config', keep_set=False)
            exit_code = subprocess.run(
                [*die, sys.executable, '-m', 'replan_experiments.scenario',
                 str(folder / 'input.yaml'), '--out', str(folder), *options],
                env=env, stdout=output, stderr=subprocess.STDOUT, pass_fds=(fd,),
                preexec_fn=_unblock_signals, timeout=RUN_TIMEOUT_S).returncode
        return {'exit': exit_code, 'folder': str(folder), 'host': node['host'],
                'files': read_back(folder, '--no-bag' not in options)}


def _import_ray():
    try:
        import ray
    except ImportError as err:
        raise ExperimentError('--ray needs Ray, which is not installed here: '
                              'scripts/setup.sh --with-ray') from err
    return ray


class RayRunner(Runner):
    """``Runner`` whose runs are Ray tasks on the cluster at ``address`` (``ray.init``'s:
    ``auto``, ``HOST:PORT``, ``ray://HOST:10001``), or on a private one (``local``) with
    ``slots`` graph slots. Every node that offers graph slots is checked first: one running
    other code than this checkout refuses the call (ExperimentError)."""

    def __init__(self, out_dir: Path, config_dir: Path, *, address: str, slots: int = 1,
                 domain_base: int = DEFAULT_DOMAIN_BASE, **kwargs) -> None:
        super().__init__(out_dir, config_dir, jobs=1, domain_base=domain_base, **kwargs)
        self.ray = _import_ray()
        self.domain_base = domain_base
        self.revision = git_revision(config_dir.resolve().parent)
        self.refused: str | None = None
        # Ray reports nothing home and logs only what goes wrong: the progress line is ours.
        os.environ.setdefault('RAY_USAGE_STATS_ENABLED', '0')
        warnings.filterwarnings('ignore', category=FutureWarning, module=r'ray\.')
        settings = dict(logging_level=logging.WARNING, log_to_driver=False)
        try:
            if address == 'local':
                self.ray.init(num_cpus=slots, resources={GRAPH_SLOT: slots},
                              include_dashboard=False,
                              _system_config={'enable_metrics_collection': False},
                              **settings)
            else:
                self.ray.init(address=address, **settings)
        except (ConnectionError, RuntimeError, ValueError) as err:
            raise ExperimentError(f'--ray {address}: cannot connect: {err}') from err
        self.task = self.ray.remote(make_run).options(
            num_cpus=0, resources={GRAPH_SLOT: 1}, max_retries=MAX_RETRIES,
            retry_exceptions=False)
        self.graph_slots = self._check_nodes()

    def _check_nodes(self) -> int:
        """Graph slots of the cluster, after checking that each node that offers some runs
        this checkout's code."""
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy
        nodes = [n for n in self.ray.nodes()
                 if n.get('Alive') and n.get('Resources', {}).get(GRAPH_SLOT)]
        if not nodes:
            self.close()
            raise ExperimentError(f'the Ray cluster has no node with the resource '
                                  f'{GRAPH_SLOT}: start its nodes with --resources '
                                  f'\'{{"{GRAPH_SLOT}": N}}\' (docs/cluster.md)')
        probe = self.ray.remote(node_code)
        try:
            found = self.ray.get([probe.options(
                num_cpus=0, max_retries=MAX_RETRIES,
                scheduling_strategy=NodeAffinitySchedulingStrategy(n['NodeID'], soft=False)
            ).remote() for n in nodes])
        except self.ray.exceptions.RayError as err:
            self.close()
            lines = str(err).strip().splitlines()
            raise ExperimentError(f'a node cannot run the project: {lines[-1]}') from err
        for node in found:
            refused = mismatch(node, self.code, self.revision)
            if refused:
                self.close()
                raise ExperimentError(refused)
        return int(sum(n['Resources'][GRAPH_SLOT] for n in nodes))

    def close(self) -> None:
        """Disconnect (and stop the private cluster of ``local``)."""
        self.ray.shutdown()

    def _execute(self, folder: Path, bag: bool) -> int:
        """The run of ``folder/input.yaml`` as a Ray task; its folder's files (the bag only if
        ``bag``) written into ``folder``, the node's folder name in their text replaced by
        ``folder``."""
        if self.refused:
            (folder / 'output.log').write_text(self.refused + '\n')
            return -1
        if self.progress:      # "running" counts the runs handed to the cluster
            self.progress.update(started=1)
        try:
            reply = self.ray.get(self.task.remote(
                (folder / 'input.yaml').read_text(), self.code, self.revision,
                self.scenario_options(bag), self.domain_base,
                str(self.lock_file) if self.lock_file else None))
        except self.ray.exceptions.RayError as err:
            # The task raised (ours) or its retries were used up (worker or node deaths).
            lines = str(err).strip().splitlines()
            (folder / 'output.log').write_text(f'Ray: {lines[-1] if lines else err!r}\n')
            return -1
        finally:
            if self.progress:
                self.progress.update(finished=1)
        if 'refused' in reply:
            self.refused = reply['refused']
            (folder / 'output.log').write_text(self.refused + '\n')
            return -1
        for rel, data in reply['files'].items():
            path = folder / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            if rel.endswith(('.json', '.log', '.yaml')):
                data = data.replace(reply['folder'].encode(), str(folder).encode())
            path.write_bytes(data)
        return int(reply['exit'])
