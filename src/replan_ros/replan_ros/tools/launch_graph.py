"""Start the node graph (sim, gait, mpc, wbc, optionally the recorder) and supervise it.

There is no `ros2 launch` in the PyPI wheels; this is the project's launcher, behind
``scripts/launch.sh``. Before anything starts, every parameter file of the run (the node files,
the profile, ``--params``) is checked against the nodes' parameter tables
(``replan_ros/params.py``): an unknown key (with the closest name), a wrong type, a value out
of range or not among the choices, or two nodes that disagree (``wbc.control_rate`` and
``sim.control_period``; ``sim.command_timeout`` must exceed ``wbc.plan_timeout``) stops the
start with one line, e.g. ``config error: /tmp/x.yaml: gait.replan_window = 0 is out of range
[1, 8]``. Each node is its own process (own process group) with its log in the run folder. A
node that dies is reported (which, when, exit code) and started again after a back-off of 1 s,
2 s, 4 s ...; a node that dies 3 times within 30 s stops the graph and its last 20 log lines
are printed. With ``--no-respawn`` the first death stops the rest. Ctrl-C, SIGTERM or the
sim-time ``--duration`` stop everything cleanly (SIGINT, then SIGKILL after a timeout).

Exit codes: 0 done; 1 a node died (``--no-respawn``); 2 bad command line or configuration
(nothing was started); 3 wall-time limit (scenarios); 4 a node kept dying (respawn limit).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from ament_index_python.packages import get_package_prefix
from geometry_msgs.msg import TwistStamped, WrenchStamped
from rclpy.context import Context
from rclpy.duration import Duration as RclpyDuration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from replan_ros import qos
from replan_ros.on_demand import helper_name
from replan_ros.params import TABLES, ConfigError, Source, check_run, load_param_file, load_yaml

NODES = ('sim', 'gait', 'mpc', 'wbc')
# Published by sim, gait and mpc as soon as they are up; with a recorder in the graph the wbc,
# whose first command lets the sim advance, starts only once the recorder listens to all of them.
RECORDED_BEFORE_START = ('/clock', '/joint_states', '/imu', '/ground_truth/odom',
                         '/ground_truth/contacts', '/applied_wrench', '/footholds',
                         '/velocity_setpoint', '/com_plan', '/zmp_plan')
PROFILES = ('realistic', 'ideal')
DEFAULT_PROFILE = 'realistic'
RECORDER_WAIT = 20.0    # s, wall
DELIVERY_WAIT = 30.0    # s, wall: scheduled inputs acknowledged by the nodes that use them
STOP_TIMEOUT = 10.0     # s, SIGINT -> SIGKILL
RESPAWN_DELAY = 1.0     # s, wall: first back-off, doubled at each further death
RESPAWN_LIMIT = 3       # deaths of one node within RESPAWN_WINDOW that stop the graph
RESPAWN_WINDOW = 30.0   # s, wall
LOG_TAIL = 20           # lines of a node's log printed when it keeps dying
EXIT_DONE, EXIT_DIED, EXIT_CONFIG, EXIT_WALL_TIME, EXIT_RESPAWN_LIMIT = 0, 1, 2, 3, 4


def _executable(name: str) -> str:
    return str(Path(get_package_prefix('replan_ros')) / 'lib' / 'replan_ros' / name)


def profile_file(config_dir: Path, profile: str) -> Path:
    """The parameter file of a profile: a name in ``config/profiles/`` or a path."""
    path = Path(profile)
    if path.suffix in ('.yaml', '.yml'):
        if not path.is_file():
            raise ValueError(f'profile file {path} does not exist')
        return path
    path = config_dir / 'profiles' / f'{profile}.yaml'
    if not path.is_file():
        known = sorted(p.stem for p in (config_dir / 'profiles').glob('*.yaml'))
        raise ValueError(f'unknown profile {profile!r} (known: {", ".join(known)})')
    return path


def check_run_files(config_dir: Path, param_files, extra_params=None):
    """Check the node files of ``config_dir``, then ``param_files`` in order (the profile and
    the user's files: paths, or ``params.Source`` for parameters not in a file yet), then the
    ``-p`` values of ``extra_params`` ({node: {name: text}}), against the parameter tables and
    each other; returns the effective values (``params.Resolved``). ConfigError names the
    file, the node, the key, the value and what is allowed."""
    sources = []
    for name in TABLES:
        path = config_dir / f'{name}.yaml'
        if path.is_file():
            sources.append(Source(str(path), load_param_file(path), nodes=(name,)))
    sources += [item if isinstance(item, Source) else Source(str(item), load_param_file(item))
                for item in param_files]
    for name, values in (extra_params or {}).items():
        sources.append(Source('command line (-p)', {
            name: {key: load_yaml(str(text)) for key, text in values.items()}}, nodes=(name,)))
    return check_run(sources, TABLES)


def _stamp() -> str:
    return datetime.datetime.now().strftime('%H:%M:%S')


@dataclass
class ManagedNode:
    name: str
    cmd: list[str]
    log_path: Path
    respawn: bool
    process: subprocess.Popen | None = None
    starts: int = 0
    log_file: object = field(default=None, repr=False)
    deaths: list[float] = field(default_factory=list)   # monotonic times, within the window
    respawn_at: float | None = None                       # monotonic time of the next start

    def start(self, env: dict[str, str]) -> None:
        if self.log_file is None:
            self.log_file = open(self.log_path, 'ab')  # noqa: SIM115 (closed in stop)
        self.starts += 1
        self.log_file.write(f'\n[launch {_stamp()}] start #{self.starts}: '
                            f'{" ".join(self.cmd)}\n'.encode())
        self.log_file.flush()
        self.process = subprocess.Popen(self.cmd, env=env, stdout=self.log_file,
                                        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                        start_new_session=True)

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def signal(self, sig: int) -> None:
        if self.alive:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.process.pid, sig)

    def log_tail(self, lines: int = LOG_TAIL) -> list[str]:
        """The last ``lines`` lines of the node's log."""
        if self.log_file is not None:
            self.log_file.flush()
        try:
            return self.log_path.read_text(errors='replace').splitlines()[-lines:]
        except OSError:
            return []

    def close(self) -> None:
        if self.log_file is not None:
            self.log_file.close()
            self.log_file = None


class Graph:
    """The node graph of one run: start, supervise, stop."""

    def __init__(self, run_dir: Path, *, config_dir: Path, param_files: list[Path] = (),
                 profile: str | None = DEFAULT_PROFILE,
                 record_dir: Path | None = None, gui: bool = False, respawn: bool = True,
                 extra_params: dict[str, dict[str, str]] | None = None,
                 env: dict[str, str] | None = None, log=print) -> None:
        """ConfigError (nothing started, nothing written) when a parameter file of the run
        does not pass ``params.check_run``."""
        extra_params = extra_params or {}
        if profile is not None:
            param_files = [profile_file(config_dir, profile), *param_files]
        self.resolved = check_run_files(config_dir, param_files, extra_params)
        self.run_dir = run_dir
        self.log_dir = run_dir / 'logs'
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = dict(env or os.environ)
        self.env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        self.env['PYTHONUNBUFFERED'] = '1'
        self.log = log
        self.nodes: list[ManagedNode] = []
        # The node files are the ideal world; the profile's settings come on top of them and
        # the user's files last (None: the files already hold one, as in a re-run).
        self.profile = profile
        names = (['recorder'] if record_dir is not None else []) + list(NODES)
        for name in names:
            cmd = [_executable(f'{name}_node'), '--ros-args', '-r', f'__node:={name}',
                   '--params-file', str(config_dir / f'{name}.yaml')]
            for extra in param_files:
                cmd += ['--params-file', str(extra)]
            if name == 'sim' and gui:
                cmd += ['-p', 'gui:=true']
            if name == 'wbc' and record_dir is not None:
                # The estimate (odom, contacts) comes from the wbc, which starts last: its first
                # command waits until the recorder listens, so the bag holds it from t = 0.
                cmd += ['-p', f'first_command_waits_for:=[{helper_name("recorder")}]']
            if name == 'recorder':
                cmd += ['-p', f'output_dir:={record_dir}']
                cmd += ['-p', 'config_files:=[' + ', '.join(
                    str(p) for p in [*(config_dir / f'{n}.yaml' for n in NODES), *param_files])
                    + ']']
            for key, value in extra_params.get(name, {}).items():
                cmd += ['-p', f'{key}:={value}']
            self.nodes.append(ManagedNode(name, cmd, self.log_dir / f'{name}.log', respawn))
        self.failed: list[str] = []
        self.peak_memory_mb: dict[str, float] = {}     # filled by run_graph before stopping
        self.real_time_factor: float | None = None     # sim s per wall s from the first tick

    def start(self, watch: ClockWatch | None = None, deliveries=()) -> None:
        """Start every node. With a ``watch`` node, the wbc (whose first command lets the sim
        advance) starts only once the recorder, if any, subscribed to the graph's topics (the
        bag then holds the run from t = 0) and every ``deliveries`` entry (publisher, topic,
        consumer node name) was received by its consumer (scheduled inputs are then in place
        before sim time moves, so a run never depends on start-up speed)."""
        recording = any(n.name == 'recorder' for n in self.nodes)
        for node in self.nodes:
            if node.name == 'wbc' and watch is not None:
                if recording:
                    self._wait_for_recorder(watch)
                for publisher, topic, consumer in deliveries:
                    self._wait_for_delivery(watch, publisher, topic, consumer)
            node.start(self.env)
            self.log(f'[launch {_stamp()}] started {node.name} (pid {node.process.pid}), '
                     f'log {node.log_path}')

    def _wait_for_delivery(self, watch: ClockWatch, publisher, topic: str,
                           consumer: str) -> None:
        deadline = time.monotonic() + DELIVERY_WAIT
        while time.monotonic() < deadline:
            if any(info.node_name == consumer
                   for info in watch.node.get_subscriptions_info_by_topic(topic)):
                break
            watch.spin(0.1)
        remaining = max(deadline - time.monotonic(), 0.1)
        if not publisher.wait_for_all_acked(RclpyDuration(seconds=remaining)):
            self.log(f'[launch {_stamp()}] {topic}: {consumer} did not acknowledge the '
                     f'scheduled inputs within {DELIVERY_WAIT} s; starting anyway (the run may '
                     'differ from a re-run)')

    def _wait_for_recorder(self, watch: ClockWatch) -> None:
        deadline = time.monotonic() + RECORDER_WAIT
        missing = list(RECORDED_BEFORE_START)
        while time.monotonic() < deadline:
            missing = [t for t in RECORDED_BEFORE_START
                       if not any(info.node_name == helper_name('recorder') for info in
                                  watch.node.get_subscriptions_info_by_topic(t))]
            if not missing:
                return
            watch.spin(0.1)
        self.log(f'[launch {_stamp()}] recorder not subscribed to {missing} after '
                 f'{RECORDER_WAIT} s; starting anyway (the bag may miss the first messages)')

    def poll(self) -> int | None:
        """Check the nodes once; respawn the dead ones after their back-off. None while the
        graph runs on, else the exit code it must stop with (EXIT_DIED without respawn,
        EXIT_RESPAWN_LIMIT when a node died RESPAWN_LIMIT times within RESPAWN_WINDOW)."""
        now = time.monotonic()
        for node in self.nodes:
            if node.respawn_at is not None:
                if now >= node.respawn_at:
                    node.respawn_at = None
                    node.start(self.env)
                    self.log(f'[launch {_stamp()}] respawned {node.name} '
                             f'(pid {node.process.pid})')
                continue
            if node.process is None or node.alive:
                continue
            code = node.process.returncode
            self.log(f'[launch {_stamp()}] node {node.name} died (exit code {code}) '
                     f'after start #{node.starts}; log {node.log_path}')
            self.failed.append(node.name)
            if not node.respawn:
                return EXIT_DIED
            node.deaths = [t for t in node.deaths if now - t <= RESPAWN_WINDOW] + [now]
            if len(node.deaths) >= RESPAWN_LIMIT:
                tail = node.log_tail()
                self.log(f'[launch {_stamp()}] {node.name} died {len(node.deaths)} times '
                         f'within {RESPAWN_WINDOW:.0f} s: stopping the graph. The last '
                         f'{len(tail)} lines of {node.log_path}:')
                for line in tail:
                    self.log(f'    {line}')
                return EXIT_RESPAWN_LIMIT
            # Back-off: a node that dies at start would otherwise restart in a tight loop.
            delay = RESPAWN_DELAY * 2 ** (len(node.deaths) - 1)
            node.respawn_at = now + delay
            self.log(f'[launch {_stamp()}] respawning {node.name} in {delay:.0f} s')
        return None

    def memory_peaks_mb(self) -> dict[str, float]:
        """Peak resident memory (VmHWM, MB) of each running node process."""
        peaks = {}
        for node in self.nodes:
            if not node.alive:
                continue
            try:
                status = Path(f'/proc/{node.process.pid}/status').read_text()
            except OSError:
                continue
            for line in status.splitlines():
                if line.startswith('VmHWM:'):
                    peaks[node.name] = int(line.split()[1]) / 1024.0
        return peaks

    def stop(self) -> None:
        """SIGINT to every node, the recorder last (it drains what it has not written yet),
        SIGKILL to any that does not exit within STOP_TIMEOUT."""
        producers = [n for n in self.nodes if n.name != 'recorder']
        recorders = [n for n in self.nodes if n.name == 'recorder']
        for group in (producers, recorders):
            for node in reversed(group):
                node.signal(signal.SIGINT)
            deadline = time.monotonic() + STOP_TIMEOUT
            for node in group:
                if node.process is None:
                    continue
                try:
                    node.process.wait(max(deadline - time.monotonic(), 0.1))
                except subprocess.TimeoutExpired:
                    self.log(f'[launch {_stamp()}] {node.name} ignored SIGINT, killing it')
                    node.signal(signal.SIGKILL)
                    node.process.wait(5)
                node.close()
        self.log(f'[launch {_stamp()}] all nodes stopped')


class ScheduledInputs:
    """Timed inputs sent before sim time moves: stamped set-points for the gait node and
    external wrenches for the sim, on the transient-local schedule topics (qos.SCHEDULE)."""

    def __init__(self, setpoints: list[TwistStamped], wrenches: list[WrenchStamped]) -> None:
        self.setpoints = list(setpoints)
        self.wrenches = list(wrenches)

    def publish(self, node: Node) -> list:
        """Publish them all from ``node``; returns the (publisher, topic, consumer node)
        deliveries for ``run_graph`` to wait on before the sim may advance."""
        deliveries = []
        for msg_type, topic, consumer, messages in (
                (TwistStamped, '/cmd_vel_stamped', 'gait', self.setpoints),
                (WrenchStamped, '/external_wrench', 'sim', self.wrenches)):
            if not messages:
                continue
            publisher = node.create_publisher(msg_type, topic, qos.SCHEDULE)
            for msg in messages:
                publisher.publish(msg)
            deliveries.append((publisher, topic, consumer))
        return deliveries


class ClockWatch:
    """Follows /clock from the launcher's own process, to stop after a sim-time duration."""

    def __init__(self, env: dict[str, str]) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=int(env.get('ROS_DOMAIN_ID', '0')))
        self.node = Node('launch_clock_watch', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim_time = 0.0
        self.node.create_subscription(
            Clock, '/clock', self._on_clock,
            QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.sec + msg.clock.nanosec * 1e-9

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=max(end - time.monotonic(), 0.0))

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def run_graph(graph: Graph, duration: float | None, wall_timeout: float | None = None,
              on_start=None, on_tick=None) -> int:
    """Start, supervise until the sim-time duration, Ctrl-C, a death (no respawn) or a wall
    timeout; stop. ``on_start(node)`` gets the launcher's own rclpy node before the graph
    starts, to publish inputs; it may return (publisher, topic, consumer node) entries that
    must be delivered before the sim may advance. ``on_tick(sim_time)`` is called about every
    0.1 s. Returns an
    exit code: 0 done, 1 a node died without respawn, 3 wall-time limit."""
    stop_requested = []

    def request_stop(signum, _frame):
        stop_requested.append(signum)

    old_int = signal.signal(signal.SIGINT, request_stop)
    old_term = signal.signal(signal.SIGTERM, request_stop)
    watch = ClockWatch(graph.env)
    code = 0
    start_wall = time.monotonic()
    first_tick: tuple[float, float] | None = None      # (wall, sim) when the sim first moved
    try:
        deliveries = on_start(watch.node) if on_start is not None else None
        graph.start(watch, deliveries or ())
        while not stop_requested:
            watch.spin(0.1)
            if first_tick is None and watch.sim_time > 0.0:
                first_tick = (time.monotonic(), watch.sim_time)
            if on_tick is not None:
                on_tick(watch.sim_time)
            result = graph.poll()
            if result is not None:
                if result == EXIT_DIED:
                    graph.log(f'[launch {_stamp()}] --no-respawn: stopping the rest')
                code = result
                break
            if duration is not None and watch.sim_time >= duration:
                graph.log(f'[launch {_stamp()}] reached {duration} s of sim time')
                break
            if wall_timeout is not None and time.monotonic() - start_wall > wall_timeout:
                graph.log(f'[launch {_stamp()}] wall-time limit {wall_timeout} s reached at '
                          f'sim time {watch.sim_time:.2f} s')
                code = 3
                break
        if stop_requested:
            graph.log(f'[launch {_stamp()}] signal {stop_requested[0]}: stopping')
        graph.peak_memory_mb = graph.memory_peaks_mb()
        if first_tick is not None and watch.sim_time > first_tick[1]:
            wall = time.monotonic() - first_tick[0]
            graph.real_time_factor = (watch.sim_time - first_tick[1]) / wall
            graph.log(f'[launch {_stamp()}] {watch.sim_time:.1f} s of sim time, real-time '
                      f'factor {graph.real_time_factor:.2f} (from the first tick); peak memory '
                      f'{sum(graph.peak_memory_mb.values()):.0f} MB in '
                      f'{len(graph.peak_memory_mb)} nodes')
    finally:
        graph.stop()
        watch.close()
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
    return code


def default_run_dir(root: Path) -> Path:
    return root / 'runs' / datetime.datetime.now().strftime('%Y%m%d-%H%M%S')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='launch.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--gui', action='store_true', help='PyBullet GUI window')
    parser.add_argument('--record', metavar='DIR', type=Path,
                        help='record an mcap bag into DIR')
    parser.add_argument('--params', metavar='FILE', type=Path, nargs='+', default=[],
                        help='extra parameter YAML files (sections per node name)')
    parser.add_argument('--profile', default=DEFAULT_PROFILE, metavar='NAME',
                        help=f'world profile: {" | ".join(PROFILES)} (config/profiles/NAME.yaml) '
                             f'or a YAML file; default {DEFAULT_PROFILE}')
    parser.add_argument('--duration', metavar='SIM_SECONDS', type=float,
                        help='stop after this much sim time')
    parser.add_argument('--no-respawn', action='store_true',
                        help='if a node dies, stop the others and exit non-zero')
    parser.add_argument('--run-dir', type=Path, help='folder for logs (default runs/<time>)')
    parser.add_argument('--config-dir', type=Path,
                        default=Path(os.environ.get('REPLAN_CONFIG', 'config')))
    args = parser.parse_args(argv)
    for path in args.params:
        if not path.is_file():
            parser.error(f'parameter file {path} does not exist')
    root = Path(os.environ.get('REPLAN_ROOT', '.'))
    run_dir = args.run_dir or default_run_dir(root)
    try:
        profile_file(args.config_dir, args.profile)
    except ValueError as err:
        parser.error(str(err))
    try:
        graph = Graph(run_dir, config_dir=args.config_dir, param_files=args.params,
                      profile=args.profile, record_dir=args.record, gui=args.gui,
                      respawn=not args.no_respawn)
    except ConfigError as err:
        print(f'config error: {err}', file=sys.stderr)
        return EXIT_CONFIG
    print(f'[launch] run folder {run_dir} (domain {os.environ.get("ROS_DOMAIN_ID", "0")}), '
          f'profile {args.profile}')
    return run_graph(graph, args.duration)


if __name__ == '__main__':
    sys.exit(main())
