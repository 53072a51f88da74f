"""The node graph of one run as processes: which nodes run with which command and parameter
files (``Graph``), each in its own process group with its log (``ManagedNode``); started,
respawned after a back-off (up to a limit), stopped; ``run_graph`` supervises it to the end."""

from __future__ import annotations

import contextlib
import datetime
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ament_index_python.packages import get_package_prefix
from rclpy.duration import Duration as RclpyDuration

from replan_ros.launch.domain import loopback_dds
from replan_ros.launch.param_files import (
    DEFAULT_GAIT,
    DEFAULT_PROFILE,
    check_run_files,
    gait_library,
    gait_parameters,
    profile_file,
    robot_parameters,
    write_source,
)
from replan_ros.launch.progress import ProgressLine, RunProgress
from replan_ros.launch.watch import ClockWatch
from replan_ros.params.robot import project_root
from replan_ros.transport.on_demand import helper_name

NODES = ('sim', 'gait', 'mpc', 'wbc')


def wbc_listeners(recording: bool) -> list[str]:
    """Whom the wbc's first command waits for (its ``first_command_waits_for``): the planners
    on the estimate they read and, in a recorded graph, the recorder on all of it. A wbc started
    again on a running graph is unknown to the other processes until DDS discovery has matched
    its writers with their readers: stepping meanwhile, the planners would plan nothing and the
    bag would lose its first ticks. The estimate comes from the wbc, which starts last, so at
    the graph's start the wait is the same as for its first plans."""
    planners = [f'{helper_name("gait")}=contacts+odom', f'{helper_name("mpc")}=odom']
    return planners + ([helper_name('recorder')] if recording else [])


# Published by sim, gait and mpc as soon as they are up; with a recorder in the graph the wbc,
# whose first command lets the sim advance, starts only once the recorder listens to all of them.
RECORDED_BEFORE_START = ('/clock', '/joint_states', '/imu', '/ground_truth/odom',
                         '/ground_truth/contacts', '/applied_wrench', '/footholds',
                         '/velocity_setpoint', '/com_plan', '/zmp_plan')
RECORDER_WAIT = 20.0    # s, wall
DELIVERY_WAIT = 30.0    # s, wall: scheduled inputs acknowledged by the nodes that use them
STOP_TIMEOUT = 10.0     # s, SIGINT -> SIGKILL
# wall s the launcher waits, at the end of a recorded run, for the controller's command of the
# stop tick: without it the bag's last command and estimate were there or not by a race (the
# controller stopped before or after it answered), and the metrics of the last tick with them.
END_COMMAND_WAIT = 2.0
RESPAWN_DELAY = 1.0     # s, wall: first back-off, doubled at each further death
RESPAWN_LIMIT = 3       # deaths of one node within RESPAWN_WINDOW that stop the graph
RESPAWN_WINDOW = 30.0   # s, wall
LOG_TAIL = 20           # lines of a node's log printed when it keeps dying
# s of sim from the first tick: a shorter run's real-time factor and CPU time per sim s would
# be mostly its first ticks' (plans, discovery), not the graph's rate, so none is given.
MIN_MEASURED_SIM_S = 1.0
EXIT_DONE, EXIT_DIED, EXIT_CONFIG, EXIT_WALL_TIME, EXIT_RESPAWN_LIMIT = 0, 1, 2, 3, 4


def _executable(name: str) -> str:
    return str(Path(get_package_prefix('replan_ros')) / 'lib' / 'replan_ros' / name)


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

    @property
    def refused(self) -> bool:
        """It exited refusing its configuration (``EXIT_CONFIG``, nodes.node_main)."""
        return self.process is not None and self.process.poll() == EXIT_CONFIG

    def reason(self) -> str:
        """Its last ``config error:`` line (the one a node that refuses logs), else its
        last line."""
        tail = self.log_tail()
        line = next((t for t in reversed(tail) if 'config error:' in t), tail[-1] if tail else '')
        return line[line.find('config error:'):] if 'config error:' in line else line

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
                 live_port: int | None = None, stop_time: float | None = None,
                 robot: str | None = None, gait: str | None = DEFAULT_GAIT) -> None:
        """ConfigError (nothing started, nothing written) when a parameter file of the run
        does not pass ``params.check_run``, or the ``robot`` (a name of config/robots/ or a
        robot file; None: the files hold one already, or the nodes' HyQ defaults) cannot be
        used, or the ``gait`` (a name of config/gaits/; None: the files hold one already, as in
        a re-run) is unknown. The gait's parameters (``run_dir/gait.yaml``) come first, then
        the profile, the robot's parameters (``run_dir/robot.yaml``) and the user's files.
        With ``live_port`` the live view (``replan_ros.view.live_view``, a Foxglove WebSocket
        on that port) runs with the graph.
        ``stop_time`` (sim s, a run's duration): the sim steps no further than the first tick
        at or after it, so the run ends at the same tick every time."""
        extra_params = extra_params or {}
        if stop_time is not None:
            sim = {**extra_params.get('sim', {}), 'stop_time': repr(float(stop_time))}
            extra_params = {**extra_params, 'sim': sim}
        profile_path = profile_file(config_dir, profile) if profile is not None else None
        gait_source = gait_parameters(config_dir, gait) if gait is not None else None
        layer = (robot_parameters(config_dir, robot, profile_path, gait_source)
                 if robot is not None else None)
        self.robot = layer.name if layer is not None else None
        self.robot_layer = layer
        if gait_source is not None:
            gait_source.sections['gait']['gait_library'] = gait_library(config_dir, profile_path,
                                                                        layer)
        first = [profile_path] if profile_path is not None else []
        gait_sources = [gait_source] if gait_source is not None else []
        robot_sources = [layer.derived, layer.overrides] if layer is not None else []
        self.resolved = check_run_files(
            config_dir, [*gait_sources, *first, *robot_sources, *param_files], extra_params)
        self.gait = self.resolved.values['gait']['gait']
        self.run_dir = run_dir
        self.log_dir = run_dir / 'logs'
        self.log_dir.mkdir(parents=True, exist_ok=True)
        if gait_source is not None:
            first.insert(0, write_source(gait_source, run_dir / 'gait.yaml', (
                f'# The gait of this run: {gait} (config/gaits/{gait}.yaml) in the reference '
                'robot\'s units, written by the launcher; the profile and the robot\'s '
                'parameters come after it.\n')))
        if layer is not None:
            first.append(layer.write(run_dir / 'robot.yaml'))
        param_files = [*first, *param_files]
        # DDS on the loopback as scripts/env.sh sets it, for a graph started from Python too;
        # the project's profile, not the run's configuration (a re-run's has none).
        self.env = loopback_dds(dict(env or os.environ), project_root() / 'config')
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
            if name == 'wbc':
                listeners = ', '.join(wbc_listeners(record_dir is not None))
                cmd += ['-p', f'first_command_waits_for:=[{listeners}]']
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
                if any(n.refused for n in self.nodes):
                    return          # the sim never moves; poll() stops the graph
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
        recorder = next(n for n in self.nodes if n.name == 'recorder')
        while time.monotonic() < deadline and recorder.alive:
            missing = [t for t in RECORDED_BEFORE_START
                       if not any(info.node_name == helper_name('recorder') for info in
                                  watch.node.get_subscriptions_info_by_topic(t))]
            if not missing:
                return
            watch.spin(0.1)
        if not recorder.alive:
            return          # poll() reports it (a refusal stops the graph, else a respawn)
        self.log(f'[launch {_stamp()}] recorder not subscribed to {missing} after '
                 f'{RECORDER_WAIT} s; starting anyway (the bag may miss the first messages)')

    def poll(self) -> int | None:
        """Check the nodes once; respawn the dead ones after their back-off. None while the
        graph runs on, else the exit code it must stop with (EXIT_DIED without respawn,
        EXIT_RESPAWN_LIMIT when a node died RESPAWN_LIMIT times within RESPAWN_WINDOW,
        EXIT_CONFIG when a node refused its configuration: it would refuse it again)."""
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
            if code == EXIT_CONFIG:
                # A bad parameter, a robot it cannot load, a bag that could not show the
                # robot: the same again at every start, so no respawn.
                self.log(f'[launch {_stamp()}] {node.name} refused its configuration, '
                         f'stopping the graph: {node.reason()}')
                return EXIT_CONFIG
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
        used = {}
        for node in self.nodes:
            if node.process is None or node.process.poll() is not None:
                continue
            seconds = process_cpu_seconds(node.process.pid)
            if seconds is not None:
                used[f'{node.name}:{node.process.pid}'] = seconds
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


def run_graph(graph: Graph, duration: float | None, wall_timeout: float | None = None,
              on_start=None, on_tick=None, progress: ProgressLine | None = None,
              event_times=()) -> int:
    """Start, supervise until the sim-time duration, Ctrl-C, a death (no respawn) or a wall
    timeout; stop. ``on_start(node)`` gets the launcher's own rclpy node before the graph
    starts, to publish inputs; it may return (publisher, topic, consumer node) entries that
    must be delivered before the sim may advance. ``on_tick(sim_time)`` is called about every
    0.1 s. With ``progress``, a progress line (``RunProgress``) is printed on it; the sim times
    of the timed inputs (``event_times``) count as events there. Returns an
    exit code: 0 done, 1 a node died without respawn, 2 a node refused its configuration,
    3 wall-time limit, 4 respawn limit."""
    stop_requested = []

    def request_stop(signum, _frame):
        stop_requested.append(signum)

    old_int = signal.signal(signal.SIGINT, request_stop)
    old_term = signal.signal(signal.SIGTERM, request_stop)
    # The truth only when the run records it anyway: a plain launch has no reader of the
    # simulator's truth at all (test/test_launch.py checks it), so it shows the estimate.
    recording = any(n.name == 'recorder' for n in graph.nodes)
    controlled = any(n.name == 'wbc' for n in graph.nodes)
    watch = ClockWatch(graph.env, follow_run=progress is not None, truth=recording,
                       commands=recording and controlled)
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
                # The sim holds at its stop tick; the run ends with the controller's answer
                # to it, so every recorded run ends with the same messages.
                if not watch.wait_for_command(watch.clock_ns, END_COMMAND_WAIT):
                    graph.log(f'[launch {_stamp()}] no controller command stamped '
                              f'{watch.sim_time:.3f} s within {END_COMMAND_WAIT} s: the '
                              'recording ends without it')
                break
            if wall_timeout is not None and time.monotonic() - start_wall > wall_timeout:
                graph.log(f'[launch {_stamp()}] wall-time limit {wall_timeout} s reached at '
                          f'sim time {watch.sim_time:.2f} s')
                code = 3
                break
        if stop_requested:
            graph.log(f'[launch {_stamp()}] signal {stop_requested[0]}: stopping')
        graph.peak_memory_mb = graph.memory_peaks_mb()
        sim = watch.sim_time - first_tick[1] if first_tick is not None else 0.0
        if sim > 0.0:
            graph.real_time_factor, graph.cpu_ms_per_sim_s = closing_figures(
                sim, time.monotonic() - first_tick[0], cpu_at_first_tick, graph.cpu_seconds())
        if sim > 0.0 and graph.real_time_factor is None:
            graph.log(f'[launch {_stamp()}] {watch.sim_time:.1f} s of sim time: too short to '
                      f'measure the real-time factor and the CPU time per sim s (under '
                      f'{MIN_MEASURED_SIM_S:g} s from the first tick)')
        elif sim > 0.0:
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


def closing_figures(sim_seconds: float, wall_seconds: float, cpu_before: dict[str, float],
                    cpu_after: dict[str, float]) -> tuple[float | None, dict[str, float]]:
    """A run's real-time factor (sim s per wall s) and CPU ms per sim s of each node
    (``cpu_per_sim_s``) over the span from its first tick; (None, {}) for a span under
    ``MIN_MEASURED_SIM_S``."""
    if sim_seconds < MIN_MEASURED_SIM_S:
        return None, {}
    return sim_seconds / wall_seconds, cpu_per_sim_s(cpu_before, cpu_after, sim_seconds)


def process_cpu_seconds(pid: int) -> float | None:
    """User + system CPU time (s) process ``pid`` has used so far (``/proc/<pid>/stat``);
    None if it is gone."""
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return None
    # Fields after the command name (which may hold spaces): utime, stime are 14, 15.
    fields = stat.rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


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
