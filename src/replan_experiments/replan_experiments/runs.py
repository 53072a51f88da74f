"""The runs of the experiments: each scenario run's folder is named after a hash of its
document and read again instead of made again (``Runner.run``), at most ``jobs`` runs at once,
each on its own ROS_DOMAIN_ID, with a progress line (``Progress``)."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import yaml

from replan_experiments.plan import ExperimentError
from replan_ros.launch.domain import domain_slot, loopback_dds
from replan_ros.launch.param_files import DEFAULT_ROBOT

DEFAULT_DOMAIN_BASE = 150      # the node tests reserve 2..101 (test/harness.py)


# What shapes a run besides its scenario document: the code of the core and of everything a
# scenario run starts or reads (nodes, messages, parameters, launch, scenario and analysis),
# the node parameter files, profiles, scenarios and robot files, and the URDF. Not what only
# reads runs (the plan and the page) nor what a scenario never runs (benchmarks, tests): of
# this package, the scenario runner, the analysis and the tools a scenario run calls shape it.
_SHAPING = ('src/replan_core/replan_core/**/*.py', 'src/replan_ros/replan_ros/**/*.py',
            'src/replan_experiments/replan_experiments/**/*.py',
            'config/*.yaml', 'config/profiles/**/*', 'config/scenarios/**/*',
            'config/robots/**/*', 'config/gaits/**/*', 'urdf/**/*')
_NOT_SHAPING = ('config/experiments.yaml', 'replan_experiments/page.py',
                'replan_experiments/page_plots.py',
                'replan_experiments/claims.py', 'replan_experiments/plan.py',
                'replan_experiments/runner.py', 'replan_experiments/runs.py',
                'replan_experiments/push_effects.py', 'replan_experiments/stats.py',
                'replan_experiments/page_push.py',
                'replan_experiments/page_variants.py',
                'replan_experiments/motion_effects.py',
                'replan_experiments/findings.py', 'replan_experiments/ray_runs.py',
                'config/robots_page.yaml', 'replan_experiments/robots_page.py',
                'replan_experiments/robots_plan.py', 'replan_experiments/robot_info.py',
                'replan_experiments/robots_render.py',
                'replan_experiments/page_status.py',
                'replan_experiments/benchmarks/', 'replan_experiments/planner_loop.py',
                # Read finished runs' bags; no run imports them.
                'replan_experiments/gait_report.py',
                'replan_experiments/response_variants.py',
                # Runs the cores alone, outside any run.
                'replan_experiments/response_loop.py',
                # Which domain a graph runs on, never what it does (one graph per domain).
                'replan_ros/launch/domain.py',
                # What a viewer is shown (the bag's derived /tf and markers), never what the
                # robot does or what a measure reads.
                'replan_ros/view/state_view.py')


# The OpenBLAS kernel classes scripts/env.sh chooses between (OPENBLAS_CORETYPE).
BLAS_CLASSES = ('SkylakeX', 'Haswell')


def code_fingerprint(root: Path, robot: str | None = None,
                     blas_class: str | None = None) -> str:
    """A hash of every file under ``root`` (the repository) that shapes a run (``_SHAPING``):
    a change to any of them gives every run a new key, so the cache never serves a run of
    other code. With ``robot`` (a name of ``config/robots/``), of the robot files only those
    that shape that robot's runs count (its own, the scaling rules, the reference robot's):
    a file added or changed for another robot leaves its runs' keys as they were. The BLAS
    kernel class (``OPENBLAS_CORETYPE``, set by scripts/env.sh) counts too: the two classes
    give runs other last bits (docs/ARCHITECTURE.md, "Bit-exact runs"); ``blas_class`` names
    one (``BLAS_CLASSES``) instead of this process's."""
    if blas_class is None:
        blas_class = os.environ.get('OPENBLAS_CORETYPE', '')
    digest = hashlib.sha1()
    digest.update(b'blas\0' + blas_class.encode() + b'\0')
    files = {path for pattern in _SHAPING for path in root.glob(pattern) if path.is_file()}
    robot_files = _robot_files(root, robot) if robot else None
    for path in sorted(files):
        rel = path.relative_to(root).as_posix()
        if '__pycache__' in rel or any(part in rel for part in _NOT_SHAPING):
            continue
        if robot_files is not None and rel.startswith(_ROBOTS) and rel not in robot_files:
            continue
        digest.update(rel.encode() + b'\0' + path.read_bytes() + b'\0')
    return digest.hexdigest()[:12]


_ROBOTS = 'config/robots/'


def _robot_files(root: Path, robot: str) -> set[str] | None:
    """The robot files that shape a run of ``robot``: its file, ``scaling.yaml`` and the
    reference robot's file it names; None (every robot file) for a robot given as a path."""
    if '/' in robot or robot.endswith('.yaml'):
        return None
    from replan_core.bench import scaling_rules
    from replan_core.robot.robot_file import RobotFileError
    try:
        reference = scaling_rules(root)['reference']
    except RobotFileError as err:
        # A key without the reference robot's file would reuse runs made with another one.
        raise ExperimentError(f'cannot read the reference robot: {err}') from err
    return {f'{_ROBOTS}{robot}.yaml', f'{_ROBOTS}scaling.yaml', f'{_ROBOTS}{reference}.yaml'}


def git_revision(root: Path) -> str:
    """The checkout's short revision, marked when tracked files differ from it."""
    try:
        rev = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=root,
                             capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(['git', 'status', '--porcelain', '--untracked-files=no'],
                               cwd=root, capture_output=True, text=True,
                               timeout=10).stdout.strip()
        return (rev + (' (with uncommitted changes)' if dirty else '')) if rev else 'unknown'
    except (OSError, subprocess.SubprocessError):
        return 'unknown'


def run_key(doc: dict, code: str = '', plan: str | None = None) -> str:
    """Folder name of the run of scenario document ``doc`` made by code ``code``
    (``code_fingerprint``): its name and a hash of both. A confirmatory run's key also holds
    the hash of the plan it was made for (``plan.plan_hash``), in the hash and readable in the
    name: a run made for another plan (or before any) is never served as one of this plan's.
    Without ``plan`` the key is the same as before plans had hashes."""
    content = {'scenario': doc, 'code': code} | ({'plan': plan} if plan else {})
    digest = hashlib.sha1(yaml.safe_dump(content, sort_keys=True).encode()).hexdigest()[:10]
    return f'{doc.get("name", "run")}-' + (f'plan{plan}-' if plan else '') + digest


@dataclass
class RunResult:
    key: str
    doc: dict
    metrics: dict
    folder: Path
    plan: str | None = None     # the plan hash of a confirmatory run (its key holds it)

    @property
    def ok(self) -> bool:
        """The run completed and its metrics can be used (a fall is a valid outcome): its
        graph ran to the scenario's duration and exited cleanly (``completed``). A run cut
        short, e.g. by a stopped call, still writes metrics of what it ran: never used."""
        return (bool(self.metrics.get('sim_time_s')) and self.metrics.get('fell') is not None
                and self.metrics.get('completed') is True)

    @property
    def fell(self) -> bool:
        return bool(self.metrics.get('fell'))


def bag_gaps(results, control_period: float) -> dict:
    """How complete the bags of the completed, unfallen ``results`` (RunResults) are: a run's
    analysis pairs the estimate (``/odom``) with the truth at every tick both hold
    (``estimator.samples``); a bag that lacks some ticks of either holds fewer than the run's
    ticks (sim time / ``control_period`` + 1). The recorder writes what DDS delivered to it:
    ``runs`` counted, ``short`` of them with fewer, ``most_missing`` ticks of one run, and
    that run's ``ticks``."""
    out = {'runs': 0, 'short': 0, 'most_missing': 0, 'ticks': 0}
    for result in results:
        if not isinstance(result, RunResult) or not result.ok or result.fell:
            continue
        # The recorder's own count (its bag's completeness), in runs analysed since it exists:
        # ``counted`` bags, ``incomplete`` of them.
        if result.metrics.get('bag_complete') is not None:
            out['counted'] = out.get('counted', 0) + 1
            out['incomplete'] = out.get('incomplete', 0) + (not result.metrics['bag_complete'])
        samples = (result.metrics.get('estimator') or {}).get('samples')
        if samples is None:
            continue
        ticks = round(float(result.metrics['sim_time_s']) / control_period) + 1
        out['runs'] += 1
        if samples < ticks:
            out['short'] += 1
            if ticks - samples > out['most_missing']:
                out['most_missing'], out['ticks'] = ticks - samples, ticks
    return out


class Progress:
    """One line: runs done, running, left (an upper bound where a bisection may stop early)
    and the time to go at the pace so far."""

    def __init__(self, total: int, stream=sys.stdout, quiet: bool = False) -> None:
        self.total, self.stream, self.quiet = total, stream, quiet
        self.done = self.running = self.reused = 0
        self.start = time.monotonic()
        self.lock = threading.Lock()

    def update(self, *, started: int = 0, finished: int = 0, reused: int = 0,
               skipped: int = 0) -> None:
        with self.lock:
            self.running += started - finished
            self.done += finished + reused
            self.reused += reused
            self.total -= skipped
            if self.quiet:
                return
            made = self.done - self.reused
            elapsed = time.monotonic() - self.start
            left = max(self.total - self.done, 0)
            eta = f'{elapsed / made * left / 60:.0f} min' if made else '?'
            self.stream.write(f'\r[experiments] {self.done}/{self.total} runs done '
                              f'({self.reused} reused), {self.running} running, {left} left, '
                              f'about {eta} to go   ')
            self.stream.flush()

    def close(self) -> None:
        if not self.quiet:
            self.stream.write('\n')
            self.stream.flush()


def read_scenario(config_dir: Path, name: str) -> dict:
    """The document of the scenario file ``config_dir/scenarios/<name>.yaml``."""
    path = config_dir / 'scenarios' / f'{name}.yaml'
    try:
        return yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ExperimentError(f'cannot read scenario {path}: {err}') from err


class Runner:
    """Makes scenario runs, at most ``jobs`` at a time, each on its own ROS_DOMAIN_ID."""

    def __init__(self, out_dir: Path, config_dir: Path, *, jobs: int = 1,
                 domain_base: int = DEFAULT_DOMAIN_BASE, fresh: bool = False,
                 progress: Progress | None = None,
                 lock_file: Path | None = None, robot: str | None = None) -> None:
        self.out_dir, self.config_dir = out_dir, config_dir
        self.robot = robot          # None: each scenario's own robot (HyQ unless it names one)
        # The whole checkout's (the page names it; Ray nodes must run it); a run's key has
        # its robot's (``code_for``).
        self.code = code_fingerprint(config_dir.resolve().parent)
        self._robot_codes: dict[str, str] = {}
        self.lock_file = lock_file
        self.fresh, self.progress = fresh, progress
        self.domain_base = domain_base
        self.slots = threading.BoundedSemaphore(jobs)     # runs at once
        self.results: dict[str, RunResult | threading.Event] = {}
        self.lock = threading.Lock()
        self.failures: list[str] = []

    def code_for(self, doc: dict) -> str:
        """The fingerprint in the key of scenario ``doc``'s run: the code and configuration
        that shape a run of its robot (``code_fingerprint`` with the robot)."""
        robot = str(doc.get('robot') or DEFAULT_ROBOT)
        if robot not in self._robot_codes:
            self._robot_codes[robot] = code_fingerprint(self.config_dir.resolve().parent, robot)
        return self._robot_codes[robot]

    def scenario(self, name: str) -> dict:
        """The scenario file ``name``; with ``robot``, its document runs that robot (a
        top-level ``robot:`` key; without one the document, and so its run key, is as before)."""
        doc = read_scenario(self.config_dir, name)
        if self.robot:
            doc['robot'] = self.robot
        return doc

    def run(self, doc: dict, bag: bool = False, plan: str | None = None) -> RunResult:
        """The run of scenario ``doc``: made now, or read if made before or under way.
        ``bag``: keep its bag (in its folder's ``bag/``); a run made before without one, in an
        earlier call or in this one (two experiments can share a run), is made again.
        ``plan``: the plan hash of a confirmatory run (``run_key``); it does not change the
        run."""
        key = run_key(doc, self.code_for(doc), plan)
        while True:
            with self.lock:
                entry = self.results.get(key)
                if entry is None or (isinstance(entry, RunResult) and bag
                                     and not (entry.folder / 'bag').is_dir()):
                    event = threading.Event()
                    self.results[key] = event
                    break
            if isinstance(entry, RunResult):
                if self.progress:
                    self.progress.update(reused=1)
                return entry
            entry.wait()            # under way: look again when it is done
        try:
            result = self._make(key, doc, bag, plan)
        except (OSError, subprocess.SubprocessError, ValueError) as err:
            self.failures.append(f'{key}: {err}')
            result = RunResult(key, doc, {}, self.out_dir / 'runs' / key, plan)
        with self.lock:
            self.results[key] = result
        event.set()
        return result

    @contextlib.contextmanager
    def machine_lock(self):
        """Hold ``lock_file`` (flock) for the run, if one was given: graphs of other tools
        that take the same lock then never run at the same time as this one."""
        if self.lock_file is None:
            yield
            return
        with open(self.lock_file, 'a') as handle:
            fcntl.flock(handle, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(handle, fcntl.LOCK_UN)

    def _make(self, key: str, doc: dict, bag: bool = False,
              plan: str | None = None) -> RunResult:
        folder = self.out_dir / 'runs' / key
        text = yaml.safe_dump(doc, sort_keys=False)
        metrics_file = folder / 'metrics.json'
        if (not self.fresh and metrics_file.exists()
                and (folder / 'input.yaml').exists()
                and (folder / 'input.yaml').read_text() == text
                and (not bag or (folder / 'bag').is_dir())):
            result = RunResult(key, doc, json.loads(metrics_file.read_text()), folder, plan)
            if result.ok:
                if self.progress:
                    self.progress.update(reused=1)
                return result
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        (folder / 'input.yaml').write_text(text)
        code = self._execute(folder, bag)
        metrics = json.loads(metrics_file.read_text()) if metrics_file.exists() else {}
        result = RunResult(key, doc, metrics, folder, plan)
        if not result.ok:
            log = folder / 'output.log'
            tail = (log.read_text()[-400:].strip().splitlines() if log.exists() else [])
            self.failures.append(f'{key}: exit {code}: {tail[-1] if tail else "no output"}')
        return result

    @staticmethod
    def scenario_options(bag: bool) -> list[str]:
        """The options of each scenario run: no plots; no bag unless asked."""
        return ['--quiet', '--no-plots'] + ([] if bag else ['--no-bag'])

    def _execute(self, folder: Path, bag: bool) -> int:
        """Make the run of ``folder/input.yaml`` on this machine, on a free ROS_DOMAIN_ID;
        its output (metrics.json, output.log, the bag if ``bag``) in ``folder``; returns the
        exit code."""
        with self.slots, domain_slot(self.domain_base) as (domain, fd):
            if self.progress:
                self.progress.update(started=1)
            env = loopback_dds(dict(os.environ, ROS_DOMAIN_ID=str(domain)),
                               self.config_dir.resolve())
            try:
                # The graph keeps the domain's claim (fd) if this process is killed.
                with open(folder / 'output.log', 'w') as output, self.machine_lock():
                    return subprocess.run(
                        [sys.executable, '-m', 'replan_experiments.scenario',
                         str(folder / 'input.yaml'), '--out', str(folder),
                         *self.scenario_options(bag)],
                        env=env, stdout=output, stderr=subprocess.STDOUT, pass_fds=(fd,),
                        timeout=3600).returncode
            finally:
                if self.progress:
                    self.progress.update(finished=1)
