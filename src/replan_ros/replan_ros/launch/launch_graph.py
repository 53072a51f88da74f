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

While the graph runs, a progress line shows the sim time, the real-time factor (last 5 wall
seconds and overall), the distance from the start (``/ground_truth/odom`` when the run is
recorded, as scenarios and re-runs are; else the estimate ``/odom``, so that nothing but the
recorder reads the truth) and the re-plans: refreshed in place on a terminal, one plain line
every 5 s otherwise; ``--quiet`` turns it off.

Exit codes: 0 done; 1 a node died (``--no-respawn``); 2 bad command line or configuration
(nothing was started); 3 wall-time limit (scenarios); 4 a node kept dying (respawn limit).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from ament_index_python.packages import get_package_prefix
from geometry_msgs.msg import TwistStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.duration import Duration as RclpyDuration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2

from replan_ros.params import TABLES, ConfigError, Source, check_run, load_param_file, load_yaml
from replan_ros.transport import qos
from replan_ros.transport.on_demand import OnDemandSubscriptions, helper_name

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
PROGRESS_TTY_PERIOD = 1.0      # s, wall: refresh of the in-place progress line on a terminal
PROGRESS_PLAIN_PERIOD = 5.0    # s, wall: one progress line per period otherwise (CI logs)
PROGRESS_RTF_WINDOW = 5.0      # s, wall: window of the recent real-time factor
LIVE_DEFAULT_PORT = 8765       # Foxglove's default WebSocket port
LIVE_HOST = '127.0.0.1'        # config/live_view.yaml's host: this machine only (ssh -L)


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


# A node gets SIGTERM when the launcher dies, however it dies: a launcher killed with SIGKILL
# (or by a test's timeout) left its nodes running in their own sessions, and a stray sim
# published into the next run on the same domain. setpriv (util-linux, in every Debian) sets
# the parent-death signal and execs the node, which keeps it across the ROS wheels' re-exec.
_SETPRIV = shutil.which('setpriv')
_DIE_WITH_LAUNCHER = (_SETPRIV, '--pdeathsig', 'TERM') if _SETPRIV else ()


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
        self.process = subprocess.Popen([*_DIE_WITH_LAUNCHER, *self.cmd], env=env,
                                        stdout=self.log_file, stderr=subprocess.STDOUT,
                                        stdin=subprocess.DEVNULL, start_new_session=True)

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
                 env: dict[str, str] | None = None, log=print,
                 live_port: int | None = None, stop_time: float | None = None) -> None:
        """ConfigError (nothing started, nothing written) when a parameter file of the run
        does not pass ``params.check_run``. With ``live_port`` the live view
        (``replan_ros.view.live_view``, a Foxglove WebSocket on that port) runs with the graph.
        ``stop_time`` (sim s, a run's duration): the sim steps no further than the first tick
        at or after it, so the run ends at the same tick every time."""
        extra_params = extra_params or {}
        if stop_time is not None:
            sim = {**extra_params.get('sim', {}), 'stop_time': repr(float(stop_time))}
            extra_params = {**extra_params, 'sim': sim}
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
        if live_port is not None:
            # First, so that viewers see the graph from its start; it publishes nothing the
            # graph waits for (docs/usage.md, "Watch the robot").
            cmd = [sys.executable, '-m', 'replan_ros.view.live_view', '--ros-args',
                   '-r', '__node:=live_view',
                   '--params-file', str(config_dir / 'live_view.yaml')]
            for extra in param_files:
                cmd += ['--params-file', str(extra)]
            cmd += ['-p', f'port:={live_port}']
            for key, value in extra_params.get('live_view', {}).items():
                cmd += ['-p', f'{key}:={value}']
            self.nodes.insert(0, ManagedNode('live_view', cmd, self.log_dir / 'live_view.log',
                                             respawn))
        self.failed: list[str] = []
        self.peak_memory_mb: dict[str, float] = {}     # filled by run_graph before stopping
        self.real_time_factor: float | None = None     # sim s per wall s from the first tick
        # CPU time (user + system) per sim s of each node, ms, from the first tick to the stop:
        # the graph's cost that does not depend on how loaded the machine was.
        self.cpu_ms_per_sim_s: dict[str, float] = {}

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

    def cpu_seconds(self) -> dict[str, float]:
        """CPU time used so far (user + system, s) by each running node process, by pid, so
        that a respawned node does not count its predecessor's."""
        ticks = os.sysconf('SC_CLK_TCK')
        used = {}
        for node in self.nodes:
            if node.process is None or node.process.poll() is not None:
                continue
            try:
                stat = Path(f'/proc/{node.process.pid}/stat').read_text()
            except OSError:
                continue
            # Fields after the command name (which may hold spaces): utime, stime are 14, 15.
            fields = stat.rsplit(')', 1)[1].split()
            used[f'{node.name}:{node.process.pid}'] = (int(fields[11]) + int(fields[12])) / ticks
        return used

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


# The odometry the progress line reads: the newest sample is all it needs, and a best-effort
# reader of the sim's reliable writer never makes the writer wait (qos.SENSOR_PUB).
PROGRESS_ODOM_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                               reliability=ReliabilityPolicy.BEST_EFFORT,
                               durability=DurabilityPolicy.VOLATILE)


class ClockWatch:
    """Follows /clock from the launcher's own process, to stop after a sim-time duration.

    With ``follow_run`` it also counts the re-plans (distinct /footholds stamps) and follows
    the base position for the progress line: ``/ground_truth/odom`` if ``truth``, else
    ``/odom`` (the estimate). The odometry (a sample per tick) is read on demand
    (``on_demand``) once per ``spin``, so it never wakes the launcher in between."""

    def __init__(self, env: dict[str, str], *, follow_run: bool = False,
                 truth: bool = True) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=int(env.get('ROS_DOMAIN_ID', '0')))
        self.node = Node('launch_clock_watch', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim_time = 0.0
        self.node.create_subscription(
            Clock, '/clock', self._on_clock,
            QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.plan_stamps: set[tuple[int, int]] = set()
        self.start_position: tuple[float, float] | None = None
        self.position: tuple[float, float] | None = None
        self.odom_topic = '/ground_truth/odom' if truth else '/odom'
        self._odom: OnDemandSubscriptions | None = None
        if follow_run:
            # Same profile as the writer (reliable, transient local, depth 1): a late start
            # still gets the newest plan, and a reliable KEEP_LAST reader never blocks it.
            self.node.create_subscription(PointCloud2, '/footholds', self._on_footholds,
                                          qos.LATCHED, event_callbacks=qos.INTERNAL_SUB_EVENTS)
            self._odom = OnDemandSubscriptions(self.node)
            self._odom.subscribe(Odometry, self.odom_topic, PROGRESS_ODOM_QOS, self._on_odom,
                                 raw=False)

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.sec + msg.clock.nanosec * 1e-9

    def _on_footholds(self, msg: PointCloud2) -> None:
        # A respawned gait node may send a plan again: a re-plan is a new stamp.
        self.plan_stamps.add((msg.header.stamp.sec, msg.header.stamp.nanosec))

    def _on_odom(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        self.position = (p.x, p.y)
        if self.start_position is None:
            self.start_position = self.position

    @property
    def replans(self) -> int:
        return len(self.plan_stamps)

    def distance(self) -> float | None:
        """Straight-line distance (m, in the plane) of the base from its first position."""
        if self.position is None or self.start_position is None:
            return None
        return math.hypot(self.position[0] - self.start_position[0],
                          self.position[1] - self.start_position[1])

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=max(end - time.monotonic(), 0.0))
        if self._odom is not None:
            # The newest sample only (depth 1); taken at each look from the start on, so the
            # first one is the pose the robot started from.
            self._odom.drain()

    def close(self) -> None:
        if self._odom is not None:
            self._odom.destroy()
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# Words of the launcher's event lines that tests and users grep for; a progress line must
# never contain them (test/test_launch.py, test/test_config_errors.py).
EVENT_WORDS = ('started', 'died', 'respawn', 'real-time factor', 'reached', 'stopping',
               'stopped', 'error', 'deviation')


def format_progress(sim_time: float, duration: float | None, rtf_recent: float | None,
                    rtf_total: float | None, distance: float | None, *,
                    estimated: bool = False, replans: int = 0,
                    events: tuple[int, int] | None = None) -> str:
    """One progress line: sim time (of ``duration``), real-time factor over the last few wall
    seconds and since the first tick, distance from the start, re-plans, and for scenarios the
    timed inputs whose time has come out of those sent (``events``: (due, sent))."""
    if duration:
        parts = [f'sim {sim_time:5.1f} / {duration:.1f} s '
                 f'({min(100.0, 100.0 * sim_time / duration):3.0f} %)']
    else:
        parts = [f'sim {sim_time:5.1f} s']
    if rtf_total is None:
        parts.append('waiting for the first tick')
    else:
        recent = f'{rtf_recent:.2f}' if rtf_recent is not None else '-'
        parts.append(f'RTF {recent} now, {rtf_total:.2f} overall')
    if distance is not None:
        parts.append(f'distance {distance:.2f} m' + (' (estimated)' if estimated else ''))
    parts.append(f're-plans {replans}')
    if events is not None:
        parts.append(f'events {events[0]}/{events[1]}')
    return '[progress] ' + ' | '.join(parts)


def is_terminal(stream) -> bool:
    """True if ``stream`` is an interactive terminal that understands \\r and ESC[K."""
    try:
        return bool(stream.isatty()) and os.environ.get('TERM', '') != 'dumb'
    except (AttributeError, ValueError):      # no isatty, or a closed stream
        return False


class ProgressLine:
    """Prints progress lines: refreshed in place on a terminal (every PROGRESS_TTY_PERIOD),
    else as plain lines every PROGRESS_PLAIN_PERIOD, so that logs stay readable."""

    def __init__(self, stream=None, *, in_place: bool | None = None,
                 period: float | None = None) -> None:
        self.stream = stream if stream is not None else sys.stdout
        self.in_place = is_terminal(self.stream) if in_place is None else in_place
        self.period = period if period is not None else (
            PROGRESS_TTY_PERIOD if self.in_place else PROGRESS_PLAIN_PERIOD)
        self._next: float | None = None
        self._shown = False

    def due(self, now: float) -> bool:
        """True when a new line should be shown (the first one a period after the first call)."""
        if self._next is None:
            self._next = now + self.period
        return now >= self._next

    def show(self, text: str, now: float) -> None:
        self._next = now + self.period
        if self.in_place:
            # A line longer than the terminal would wrap, and \r would then only rewrite its
            # last row.
            width = shutil.get_terminal_size((120, 24)).columns
            self.stream.write('\r' + text[:max(width - 1, 20)] + '\x1b[K')
            self._shown = True
        else:
            self.stream.write(text + '\n')
        self.stream.flush()

    def clear(self) -> None:
        """Erase the in-place line, before another line is printed or at the end."""
        if self._shown:
            self.stream.write('\r\x1b[K')
            self.stream.flush()
            self._shown = False


class RunProgress:
    """Real-time factors from (wall, sim) samples and the progress text of a run."""

    def __init__(self, duration: float | None, event_times=(),
                 window: float = PROGRESS_RTF_WINDOW) -> None:
        self.duration = duration
        self.event_times = sorted(event_times)
        self.window = window
        self._first: tuple[float, float] | None = None    # (wall, sim) when the sim moved
        self._recent: deque[tuple[float, float]] = deque()
        self.sim_time = 0.0

    def sample(self, wall: float, sim_time: float) -> None:
        self.sim_time = sim_time
        if sim_time <= 0.0:
            return
        if self._first is None:
            self._first = (wall, sim_time)
        self._recent.append((wall, sim_time))
        while len(self._recent) > 2 and wall - self._recent[1][0] >= self.window:
            self._recent.popleft()

    def real_time_factors(self) -> tuple[float | None, float | None]:
        """(over the last ``window`` wall seconds, since the first tick); None before the sim
        moved (or too soon to tell)."""
        if self._first is None:
            return None, None
        last_wall, last_sim = self._recent[-1]
        total = ((last_sim - self._first[1]) / (last_wall - self._first[0])
                 if last_wall > self._first[0] else 0.0)
        wall0, sim0 = self._recent[0]
        recent = (last_sim - sim0) / (last_wall - wall0) if last_wall > wall0 else None
        return recent, total

    def text(self, distance: float | None, *, estimated: bool = False,
             replans: int = 0) -> str:
        recent, total = self.real_time_factors()
        events = None
        if self.event_times:
            due = sum(1 for t in self.event_times if t <= self.sim_time + 1e-9)
            events = (due, len(self.event_times))
        return format_progress(self.sim_time, self.duration, recent, total, distance,
                               estimated=estimated, replans=replans, events=events)


def run_graph(graph: Graph, duration: float | None, wall_timeout: float | None = None,
              on_start=None, on_tick=None, progress: ProgressLine | None = None,
              event_times=()) -> int:
    """Start, supervise until the sim-time duration, Ctrl-C, a death (no respawn) or a wall
    timeout; stop. ``on_start(node)`` gets the launcher's own rclpy node before the graph
    starts, to publish inputs; it may return (publisher, topic, consumer node) entries that
    must be delivered before the sim may advance. ``on_tick(sim_time)`` is called about every
    0.1 s. With ``progress``, a progress line (``RunProgress``) is printed on it; the sim times
    of the timed inputs (``event_times``) count as events there. Returns an
    exit code: 0 done, 1 a node died without respawn, 3 wall-time limit."""
    stop_requested = []

    def request_stop(signum, _frame):
        stop_requested.append(signum)

    old_int = signal.signal(signal.SIGINT, request_stop)
    old_term = signal.signal(signal.SIGTERM, request_stop)
    # The truth only when the run records it anyway: a plain launch has no reader of the
    # simulator's truth at all (test/test_launch.py checks it), so it shows the estimate.
    recording = any(n.name == 'recorder' for n in graph.nodes)
    watch = ClockWatch(graph.env, follow_run=progress is not None, truth=recording)
    tracker = RunProgress(duration, event_times)
    log = graph.log
    if progress is not None:
        def log_clear(text: str) -> None:     # an event line must not land on the progress
            progress.clear()
            log(text)
        graph.log = log_clear
    code = 0
    start_wall = time.monotonic()
    first_tick: tuple[float, float] | None = None      # (wall, sim) when the sim first moved
    cpu_at_first_tick: dict[str, float] = {}
    try:
        deliveries = on_start(watch.node) if on_start is not None else None
        graph.start(watch, deliveries or ())
        while not stop_requested:
            watch.spin(0.1)
            if first_tick is None and watch.sim_time > 0.0:
                first_tick = (time.monotonic(), watch.sim_time)
                cpu_at_first_tick = graph.cpu_seconds()
            if on_tick is not None:
                on_tick(watch.sim_time)
            if progress is not None:
                now = time.monotonic()
                tracker.sample(now, watch.sim_time)
                if progress.due(now):
                    progress.show(tracker.text(watch.distance(), estimated=not recording,
                                               replans=watch.replans), now)
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
            sim = watch.sim_time - first_tick[1]
            graph.real_time_factor = sim / wall
            graph.cpu_ms_per_sim_s = cpu_per_sim_s(cpu_at_first_tick, graph.cpu_seconds(), sim)
            graph.log(f'[launch {_stamp()}] {watch.sim_time:.1f} s of sim time, real-time '
                      f'factor {graph.real_time_factor:.2f} (from the first tick); peak memory '
                      f'{sum(graph.peak_memory_mb.values()):.0f} MB in '
                      f'{len(graph.peak_memory_mb)} nodes')
            if graph.cpu_ms_per_sim_s:
                graph.log(f'[launch {_stamp()}] CPU time per sim s since the first tick: '
                          + ', '.join(f'{name} {ms:.0f} ms' for name, ms
                                      in graph.cpu_ms_per_sim_s.items())
                          + f'; all {sum(graph.cpu_ms_per_sim_s.values()):.0f} ms')
    finally:
        if progress is not None:
            progress.clear()
        graph.stop()
        graph.log = log
        watch.close()
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
    return code


def cpu_per_sim_s(before: dict[str, float], after: dict[str, float],
                  sim_seconds: float) -> dict[str, float]:
    """CPU ms per sim s of each node (``name:pid`` keys of ``Graph.cpu_seconds``) between two
    samples; for a node respawned meanwhile, its new process's whole CPU time (the old
    process's went with it)."""
    used: dict[str, float] = {}
    for key, seconds in after.items():
        name = key.split(':', 1)[0]
        used[name] = used.get(name, 0.0) + seconds - before.get(key, 0.0)
    return {name: 1e3 * seconds / sim_seconds for name, seconds in used.items()}


def add_live_option(parser: argparse.ArgumentParser) -> None:
    """``--live [PORT]``, shared by launch.sh and scenario.sh."""
    parser.add_argument('--live', nargs='?', const=LIVE_DEFAULT_PORT, type=int, metavar='PORT',
                        help='serve the run to Foxglove/Lichtblick: a WebSocket on '
                             f'{LIVE_HOST}:PORT (default {LIVE_DEFAULT_PORT}); from another '
                             f'machine: ssh -L {LIVE_DEFAULT_PORT}:localhost:{LIVE_DEFAULT_PORT} '
                             'HOST')


def live_argv(argv: list[str] | None) -> list[str]:
    """``argv`` with a bare ``--live`` that is followed by something other than a port given
    its default port, so that ``scenario.sh --live FILE`` does not take FILE for the port
    (argparse's optional value would)."""
    args = list(sys.argv[1:] if argv is None else argv)
    out = []
    for i, arg in enumerate(args):
        following = args[i + 1] if i + 1 < len(args) else None
        if arg == '--live' and following is not None and not following.isdigit():
            arg = f'--live={LIVE_DEFAULT_PORT}'
        out.append(arg)
    return out


def check_live_port(parser: argparse.ArgumentParser, port: int | None) -> None:
    """Refuse (usage error, nothing started) a port out of range or already taken: the live
    view would die at start and stop the graph."""
    if port is None:
        return
    if not 1 <= port <= 65535:
        parser.error(f'--live {port}: a port is 1..65535')
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((LIVE_HOST, port))
        except OSError as err:
            parser.error(f'--live {port}: port not free on {LIVE_HOST} ({err.strerror})')


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
                        help='stop after this much sim time (the sim steps no further than '
                             'the first tick at or after it: sim.stop_time)')
    parser.add_argument('--no-respawn', action='store_true',
                        help='if a node dies, stop the others and exit non-zero')
    parser.add_argument('--run-dir', type=Path, help='folder for logs (default runs/<time>)')
    parser.add_argument('--config-dir', type=Path,
                        default=Path(os.environ.get('REPLAN_CONFIG', 'config')))
    parser.add_argument('--quiet', action='store_true',
                        help='no progress line (sim time, real-time factor, distance, '
                             're-plans) while the graph runs')
    add_live_option(parser)
    args = parser.parse_args(live_argv(argv))
    for path in args.params:
        if not path.is_file():
            parser.error(f'parameter file {path} does not exist')
    check_live_port(parser, args.live)
    root = Path(os.environ.get('REPLAN_ROOT', '.'))
    run_dir = args.run_dir or default_run_dir(root)
    try:
        profile_file(args.config_dir, args.profile)
    except ValueError as err:
        parser.error(str(err))
    try:
        graph = Graph(run_dir, config_dir=args.config_dir, param_files=args.params,
                      profile=args.profile, record_dir=args.record, gui=args.gui,
                      respawn=not args.no_respawn, live_port=args.live,
                      stop_time=args.duration)
    except ConfigError as err:
        print(f'config error: {err}', file=sys.stderr)
        return EXIT_CONFIG
    print(f'[launch] run folder {run_dir} (domain {os.environ.get("ROS_DOMAIN_ID", "0")}), '
          f'profile {args.profile}')
    if args.live is not None:
        print(f'[launch] live view: open ws://localhost:{args.live} in Foxglove or Lichtblick '
              '(layout config/foxglove/replan.json)')
    return run_graph(graph, args.duration,
                     progress=None if args.quiet else ProgressLine())


if __name__ == '__main__':
    sys.exit(main())
