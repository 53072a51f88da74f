"""Node-graph test harness: isolated DDS domains, real node processes, a test-side probe node.

Used through the fixtures of ``test/conftest.py``. Nothing here mocks ROS: nodes are the
installed console scripts started as processes, and the probe is a real rclpy node.
"""

from __future__ import annotations

import contextlib
import os
import random
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import rclpy
from ament_index_python.packages import get_package_prefix
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from replan_ros.launch.domain import HELD_ENV, claim, loopback_dds

REPO_ROOT = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO_ROOT / 'config'
# Domain ids that map to valid DDS ports on Linux, below the ones a user picks by hand (0, 42).
_DOMAIN_RANGE = range(101, 1, -1)
_LOCK_PORT_BASE = 22119    # the same scheme as ROS 2's domain_coordinator: one port per domain


class DomainReservation:
    """Holds a ROS_DOMAIN_ID for as long as this object lives: its claim
    (replan_ros/launch/domain.py) and a local port.

    The claim is the one every graph starter honours: a user's script refuses the domain, and
    an experiment runner's domain pool (``domain_slot``, used by tests with ``--domain-base``)
    skips it, so a runner started by one test session never lands on another session's
    domain. The port is ROS 2's domain_coordinator scheme, for tools that follow that one. A
    script the tests start on this domain passes the claim (``graph_env`` sets ``HELD_ENV``).
    """

    def __init__(self) -> None:
        ids = list(_DOMAIN_RANGE)
        random.Random(os.getpid()).shuffle(ids)
        for domain_id in ids:
            held = claim(domain_id)
            if held is None:
                continue
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                sock.bind(('127.0.0.1', _LOCK_PORT_BASE + domain_id))
            except OSError:
                sock.close()
                os.close(held)
                continue
            self.domain_id = domain_id
            self._claim = held
            self._socket = sock
            return
        raise RuntimeError('no free ROS_DOMAIN_ID left to reserve')

    def release(self) -> None:
        self._socket.close()
        os.close(self._claim)


def graph_env(domain_id: int) -> dict[str, str]:
    env = loopback_dds(dict(os.environ), CONFIG_DIR, keep_set=False)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env[HELD_ENV] = str(domain_id)      # the test session holds the claim (DomainReservation)
    env['PYTHONUNBUFFERED'] = '1'
    return env


def executable(name: str, package: str = 'replan_ros') -> str:
    path = Path(get_package_prefix(package)) / 'lib' / package / name
    if not path.exists():
        raise FileNotFoundError(f'{path} not found: run scripts/setup.sh')
    return str(path)


def _param_value(value: object) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_param_value(v) for v in value) + ']'
    if isinstance(value, str):
        return value if value else "''"
    return repr(value)


def domain_processes(domain_id: int) -> dict[int, str]:
    """pid -> command line of every process of this machine, but this one, whose environment
    has ``ROS_DOMAIN_ID=domain_id``: the nodes, launchers and scripts of the test session's
    domain (a graph started by a script inherits the variable)."""
    marker = f'ROS_DOMAIN_ID={domain_id}'.encode()
    found: dict[int, str] = {}
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if marker not in (entry / 'environ').read_bytes().split(b'\0'):
                continue
            found[int(entry.name)] = (entry / 'cmdline').read_bytes().replace(
                b'\0', b' ').decode(errors='replace').strip()
        except OSError:             # gone meanwhile, or not ours to read
            continue
    return {pid: cmd for pid, cmd in found.items() if cmd}    # zombies have no command line


def parent_pid(pid: int) -> int | None:
    """The parent of process ``pid`` (None once it is gone)."""
    try:
        status = Path(f'/proc/{pid}/status').read_text()
    except OSError:
        return None
    return next((int(line.split()[1]) for line in status.splitlines()
                 if line.startswith('PPid:')), None)


def descends_from(pid: int, ancestor: int) -> bool:
    """True if ``ancestor`` is among the parents of process ``pid`` (a graph that a launcher
    of this test process still supervises, however deep); False once ``pid`` is orphaned."""
    seen = 0
    while pid > 1 and seen < 64:
        pid = parent_pid(pid) or 0
        if pid == ancestor:
            return True
        seen += 1
    return False


def reap_leftovers(domain_id: int, before: set[int], grace: float = 10.0,
                   keep: Callable[[int], bool] = lambda pid: False) -> dict[int, str]:
    """Processes of the domain that were not there at ``before``, are not ``keep(pid)`` and are
    still alive after ``grace`` s: killed (SIGKILL); returns what they were."""
    end = time.monotonic() + grace
    while True:
        left = {pid: cmd for pid, cmd in domain_processes(domain_id).items()
                if pid not in before and not keep(pid)}
        if not left or time.monotonic() >= end:
            break
        time.sleep(0.2)
    for pid in left:
        with contextlib.suppress(OSError):        # gone meanwhile
            os.kill(pid, signal.SIGKILL)
    return left


_DIE_WITH_PARENT = ('setpriv', '--pdeathsig', 'TERM') if shutil.which('setpriv') else ()


@dataclass
class ExperimentsCall:
    """One call of scripts/experiments.sh and what it wrote, read at once: a later call on the
    same folder rewrites the page and results.json."""

    out: Path
    done: subprocess.CompletedProcess
    page: str
    results: str

    @property
    def output(self) -> str:
        return self.done.stdout + self.done.stderr


def experiments(args: list[str], out: Path, env: dict[str, str], *, timeout: float = 900.0,
                wrap: Callable[[list[str]], list[str]] = lambda cmd: cmd) -> ExperimentsCall:
    """scripts/experiments.sh ARGS --out OUT (``wrap``: e.g. in a namespace of its own)."""
    cmd = wrap([str(REPO_ROOT / 'scripts' / 'experiments.sh'), *args, '--out', str(out)])
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    page, results = out / 'results.md', out / 'results.json'
    return ExperimentsCall(out, done, page.read_text() if page.exists() else '',
                           results.read_text() if results.exists() else '')


class NodeProcess:
    """One node process in its own process group, its output in a log file."""

    def __init__(self, name: str, cmd: list[str], env: dict[str, str], log_path: Path) -> None:
        self.name = name
        self.cmd = cmd
        self.log_path = log_path
        self._log_file = open(log_path, 'wb')  # noqa: SIM115  (closed in stop())
        # SIGTERM when this test process dies, as the launcher does for its nodes.
        self.process = subprocess.Popen([*_DIE_WITH_PARENT, *cmd], env=env,
                                        stdout=self._log_file, stderr=subprocess.STDOUT,
                                        stdin=subprocess.DEVNULL, start_new_session=True)

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def log(self) -> str:
        if not self._log_file.closed:
            self._log_file.flush()
        return self.log_path.read_text(errors='replace')

    def signal(self, sig: int) -> None:
        if self.alive:
            os.killpg(self.process.pid, sig)

    def stop(self, timeout: float = 10.0) -> int | None:
        """SIGINT to the group, SIGKILL after ``timeout``; returns the exit code."""
        if self.alive:
            self.signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGKILL)
                self.process.wait(5)
        self._log_file.close()
        return self.process.returncode


class Launcher:
    """Starts nodes on one domain and stops them all at the end of a test."""

    def __init__(self, domain_id: int, log_dir: Path) -> None:
        self.domain_id = domain_id
        self.log_dir = log_dir
        self.processes: list[NodeProcess] = []

    def start(self, executable_name: str, *, name: str | None = None,
              params_file: str | Path | None = None, params: dict | None = None,
              args: Iterable[str] = (), ros_args: Iterable[str] = ()) -> NodeProcess:
        """Start ``executable_name`` (a replan_ros console script) with parameters.

        ``params_file`` defaults to nothing; pass ``CONFIG_DIR / 'sim.yaml'`` for the shipped one.
        """
        cmd = [executable(executable_name), *args, '--ros-args']
        if name:
            cmd += ['-r', f'__node:={name}']
        if params_file:
            cmd += ['--params-file', str(params_file)]
        for key, value in (params or {}).items():
            cmd += ['-p', f'{key}:={_param_value(value)}']
        cmd += list(ros_args)
        label = name or executable_name
        log_path = self.log_dir / f'{label}-{len(self.processes)}.log'
        proc = NodeProcess(label, cmd, graph_env(self.domain_id), log_path)
        self.processes.append(proc)
        return proc

    def stop_all(self) -> None:
        for proc in reversed(self.processes):
            proc.stop()

    def logs(self, tail: int = 200) -> str:
        out = []
        for proc in self.processes:
            lines = proc.log().splitlines()[-tail:]
            out.append(f'===== {proc.name} (exit {proc.process.returncode}) '
                       f'{" ".join(proc.cmd)}\n' + '\n'.join(lines))
        return '\n'.join(out)


class Probe:
    """A real rclpy node in the test process, on its own context and domain."""

    def __init__(self, domain_id: int, name: str = 'test_probe', use_sim_time: bool = False):
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node(name, context=self.context, parameter_overrides=[
            Parameter('use_sim_time', Parameter.Type.BOOL, use_sim_time)])
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.05, max(end - time.monotonic(), 0.0)))

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Spin until ``predicate()`` is true; False on timeout."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.05)
        return predicate()

    def topics(self) -> dict[str, list[str]]:
        return dict(self.node.get_topic_names_and_types())

    def wait_for_topics(self, names: Iterable[str], timeout: float = 20.0) -> bool:
        wanted = {n if n.startswith('/') else '/' + n for n in names}
        return self.spin_until(lambda: wanted <= set(self.topics()), timeout)

    def collect(self, msg_type: type, topic: str, qos, count: int = 1,
                timeout: float = 10.0) -> list:
        """Subscribe and return the first ``count`` messages (fewer on timeout)."""
        received: list = []
        sub = self.node.create_subscription(msg_type, topic, received.append, qos)
        try:
            self.spin_until(lambda: len(received) >= count, timeout)
        finally:
            self.node.destroy_subscription(sub)
        return received

    def subscribe(self, msg_type: type, topic: str, qos) -> list:
        """Subscribe for the rest of the test; messages accumulate in the returned list."""
        received: list = []
        self.node.create_subscription(msg_type, topic, received.append, qos)
        return received

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
