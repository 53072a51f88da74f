"""Faults while walking: a killed node, a killed recorder, bad messages, bad files.

One graph walks for the whole module (the realistic profile, 0.1 m/s from a stamped set-point;
sim, gait, mpc, wbc and the recorder as real processes started like the launcher does, without
respawn, so that a killed node stays dead until the test starts it again "by hand"). The tests
run in file order on that graph, each leaving it walking:

- SIGKILL of mpc, then of gait: the wbc notices at the next due re-plans (``plan_timeout`` wall s
  each) and, after ``missed_replans_to_stand`` of them, stands with the feet in place; its
  /diagnostics says ERROR and which plan (and node) is missing; the node started again, the
  robot walks on without a restart of the others;
- SIGKILL of wbc: the sim notices (``command_timeout``) and goes to damping mode (the robot sits
  down), ERROR on /diagnostics; the wbc started again, the robot stands up and walks on;
- malformed messages (non-finite, wrong-sized) on internal topics: one line from the receiver,
  no crash, the robot keeps walking;
- SIGKILL of the recorder: its bag, recovered, holds everything up to its last finished chunk;
  replay and rerun refuse the killed bag (and a corrupt one) with one line.

Each test writes what happened to ``runs/robustness/<test>.json`` ($REPLAN_ROBUSTNESS_DIR), from
which ``replan_experiments.robustness_page`` writes docs/robustness.md. Bounds are in sim time
(generous) or wall-clock timeouts on waiting; nothing asserts how fast anything ran.
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from harness import CONFIG_DIR, REPO_ROOT, Launcher, Probe, executable, graph_env
from mcap.reader import make_reader
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState, PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from replan_ros.launch.graph import wbc_listeners
from replan_ros.messages.stamps import ns_to_stamp, stamp_to_sec
from replan_ros.recording.bag_io import check_bag, iter_decoded
from replan_ros.recording.bag_writer import recover
from replan_ros.telemetry.diagnostics import values_of
from replan_ros.transport.qos import COMMAND, CONTACTS, LATCHED, SCHEDULE, SENSOR

PROFILE = CONFIG_DIR / 'profiles' / 'realistic.yaml'
SPEED = 0.1                 # m/s, commanded from t = 1 s
STANDING_Z = 0.5            # m: the base above this is standing (0.61 walking, ~0.34 sat down)
SAT_DOWN_Z = 0.45
WAIT = 120.0                # wall s: generous timeouts for waits (a loaded 2-core machine)
ERROR = DiagnosticStatus.ERROR[0] if isinstance(DiagnosticStatus.ERROR, bytes) else 2
OK = 0


def results_dir() -> Path:
    return Path(os.environ.get('REPLAN_ROBUSTNESS_DIR', REPO_ROOT / 'runs' / 'robustness'))


def record(test: str, **fields) -> None:
    """What happened, for docs/robustness.md (replan_experiments/robustness_page.py)."""
    folder = results_dir()
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f'{test}.json').write_text(json.dumps(fields, indent=1, sort_keys=True) + '\n')


def _level(status: DiagnosticStatus) -> int:
    return status.level[0] if isinstance(status.level, bytes) else int(status.level)


@pytest.mark.parametrize('node', ['sim', 'mpc', 'wbc'])
def test_a_missing_or_malformed_urdf_stops_the_node_with_one_line(node, tmp_path, ros_domain):
    bad = tmp_path / 'bad.urdf'
    bad.write_text("<robot name='x'><link")
    messages = []
    for urdf in (bad, tmp_path / 'missing.urdf'):
        run = subprocess.run(
            [executable(f'{node}_node'), '--ros-args',
             '--params-file', str(CONFIG_DIR / f'{node}.yaml'), '-p', f'urdf_path:={urdf}'],
            env=graph_env(ros_domain), capture_output=True, text=True, timeout=120)
        out = run.stdout + run.stderr
        assert run.returncode == 1, out
        assert 'Traceback' not in out and f'cannot load the URDF {str(urdf)!r}' in out, out
        messages.append(next(ln for ln in out.splitlines() if 'cannot load the URDF' in ln)
                        .replace(str(urdf), 'URDF'))
    record(f'urdf_{node}', fault=f'a missing or malformed URDF given to {node}',
           noticed_by=f'{node} at start', diagnostics=messages[0].split(']: ', 1)[-1],
           safe_state='exit code 1 before anything is published (the launcher reports it)',
           time_to_safe_s=0.0, recovery='fix urdf_path', time_to_walk_s=None,
           lowest_base_m='', data_lost='nothing (nothing started)')


class Walk:
    """The walking graph, the probe that watches it (truth odom, /diagnostics) and steers it."""

    NODES = ('sim', 'gait', 'mpc', 'wbc')

    def __init__(self, domain: int, folder: Path) -> None:
        self.folder = folder
        self.launcher = Launcher(domain, folder)
        self.probe = Probe(domain, 'fault_probe')
        node = self.probe.node
        self.odom: list[tuple[float, float, float]] = []        # (t, x, z) of the truth
        self.diags: list[tuple[float, DiagnosticStatus]] = []  # (probe's sim t, status)
        node.create_subscription(Odometry, 'ground_truth/odom', self._on_odom, SENSOR)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, COMMAND)
        self.cmd = node.create_publisher(TwistStamped, 'cmd_vel_stamped', SCHEDULE)
        setpoint = TwistStamped()
        setpoint.header.stamp = ns_to_stamp(1_000_000_000)
        setpoint.twist.linear.x = SPEED
        self.cmd.publish(setpoint)
        self.procs = {}
        self.bag = folder / 'walk.mcap'
        self.procs['recorder'] = self.launcher.start(
            'recorder_node', name='recorder', params_file=CONFIG_DIR / 'recorder.yaml',
            params={'output': str(self.bag), 'chunk_interval': 0.5})
        for name in self.NODES:
            self.start(name)

    def start(self, name: str) -> None:
        # As the launcher starts a recorded graph: the wbc's first command waits until the
        # planners and the recorder listen (graph.wbc_listeners).
        params = ({'first_command_waits_for': wbc_listeners(recording=True)} if name == 'wbc'
                  else None)
        self.procs[name] = self.launcher.start(
            f'{name}_node', name=name, params_file=CONFIG_DIR / f'{name}.yaml',
            ros_args=['--params-file', str(PROFILE)], params=params)

    def kill(self, name: str) -> float:
        """SIGKILL; returns the sim time it happened at (the truth's latest stamp)."""
        proc = self.procs[name]
        proc.signal(signal.SIGKILL)
        proc.process.wait(10)
        assert proc.process.returncode == -signal.SIGKILL
        return self.t

    def _on_odom(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        self.odom.append((stamp_to_sec(msg.header.stamp), p.x, p.z))

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            self.diags.append((self.t, status))

    @property
    def t(self) -> float:
        return self.odom[-1][0] if self.odom else 0.0

    @property
    def x(self) -> float:
        return self.odom[-1][1] if self.odom else 0.0

    @property
    def z(self) -> float:
        return self.odom[-1][2] if self.odom else 0.0

    def spin_sim(self, seconds: float) -> bool:
        """Spin until the sim time has advanced by ``seconds``."""
        end = self.t + seconds
        return self.probe.spin_until(lambda: self.t >= end, WAIT)

    def wait_status(self, name: str, predicate, since: int = 0) -> DiagnosticStatus | None:
        """The first status of ``name`` (from index ``since`` of ``diags``) that matches."""
        def found():
            return next((s for _, s in self.diags[since:]
                         if s.name == name and predicate(s)), None)
        self.probe.spin_until(lambda: found() is not None, WAIT)
        return found()

    def min_z(self, t0: float) -> float:
        return min(z for t, _, z in self.odom if t >= t0)

    def walks(self, seconds: float = 3.0) -> float:
        """Distance walked over the next ``seconds`` of sim time."""
        x0 = self.x
        assert self.spin_sim(seconds), self.logs()
        return self.x - x0

    def logs(self) -> str:
        """The processes' logs, after what the probe saw last: the truth's time and each
        node's latest /diagnostics status (which side stopped, when a wait fails)."""
        latest = {}
        for t, status in self.diags:
            latest[status.name] = (t, status)
        seen = '; '.join(f'{name} at t={t:.3f}: level {_level(s)} {s.message!r}'
                         for name, (t, s) in sorted(latest.items()))
        return (f'probe: truth t={self.t:.3f} s, {len(self.odom)} truth samples; latest '
                f'diagnostics: {seen or "none"}\n{self.launcher.logs(tail=60)}')

    def log_of(self, name: str) -> str:
        return '\n'.join(p.log() for p in self.launcher.processes if p.name == name)

    def close(self) -> None:
        self.launcher.stop_all()
        self.probe.close()


@pytest.fixture(scope='module')
def walk(ros_domain, tmp_path_factory):
    graph = Walk(ros_domain, tmp_path_factory.mktemp('faults'))
    try:
        # Walking, not only t >= 4 s: on a loaded machine the gait node may discover the
        # probe's set-point late, while the sim runs faster than real time.
        ok = graph.probe.spin_until(
            lambda: graph.t >= 4.0 and graph.x - graph.odom[0][1] > 0.05, 180)
        assert ok, graph.logs()
        yield graph
    finally:
        graph.close()


def _planner_killed(walk: Walk, name: str, topic: str) -> None:
    assert walk.walks() > 0.4 * SPEED * 3.0, walk.logs()
    mark = len(walk.diags)
    t_kill = walk.kill(name)
    missing = f'{topic} ({name})'
    status = walk.wait_status('wbc', lambda s: _level(s) == ERROR and missing in s.message,
                              mark)
    assert status is not None, walk.logs()
    t_stand = float(values_of(status)['stand_since_s'])
    # Noticed at the due re-plans after the kill: two steps (0.75 s each) and the plan latency.
    assert 0.0 <= t_stand - t_kill < 3.0, (t_kill, t_stand)
    # Standing: no step, no sitting, while the node is away.
    x0, t0 = walk.x, walk.t
    assert walk.spin_sim(2.0), walk.logs()
    assert abs(walk.x - x0) < 0.03 and walk.min_z(t0) > STANDING_Z, walk.odom[-1]
    assert walk.procs[name].alive is False and all(
        walk.procs[n].alive for n in Walk.NODES if n != name), walk.logs()
    # Started again by hand: the robot walks on, nothing else restarted.
    t_start = walk.t
    mark = len(walk.diags)
    walk.start(name)
    back = walk.wait_status('wbc', lambda s: _level(s) == OK and s.message == 'tracking the plan',
                            mark)
    assert back is not None, walk.logs()
    t_back = walk.t
    # A restarted gait node plans from the latched set-point once DDS discovery brings it
    # (1-3 wall s for a new process); until then it steps in place (setpoint_source 'none').
    steered = walk.wait_status('gait', lambda s: values_of(s).get('setpoint_source')
                               == 'cmd_vel_stamped', mark)
    assert steered is not None, walk.logs()
    walked = walk.walks()
    assert walked > 0.4 * SPEED * 3.0, f'walked {walked:.3f} m\n{walk.logs()}'
    assert walk.min_z(t_kill) > STANDING_Z
    record(f'kill_{name}', fault=f'SIGKILL of {name} while walking {SPEED} m/s',
           noticed_by='wbc (its due re-plans get no ' + topic + f' from {name})',
           diagnostics=status.message, safe_state='stands with the feet in place',
           time_to_safe_s=round(t_stand - t_kill, 3),
           recovery=f'{name} started again: walks on ({walked:.2f} m in 3 s)',
           time_to_walk_s=round(t_back - t_start, 3), lowest_base_m=round(walk.min_z(t_kill), 3),
           data_lost=f'no plans while {name} was away; nothing recorded is lost')


def test_mpc_killed_the_robot_stands_then_walks_on_when_mpc_is_back(walk):
    _planner_killed(walk, 'mpc', 'com_plan')


def test_gait_killed_the_robot_stands_then_walks_on_when_gait_is_back(walk):
    _planner_killed(walk, 'gait', 'footholds')


def test_wbc_killed_the_sim_damps_the_robot_down_then_it_stands_up_and_walks(walk):
    assert walk.walks() > 0.4 * SPEED * 3.0, walk.logs()
    mark = len(walk.diags)
    t_kill = walk.kill('wbc')
    status = walk.wait_status('sim', lambda s: _level(s) == ERROR and 'wbc' in s.message, mark)
    assert status is not None, walk.logs()
    t_damp = float(values_of(status)['damping_since_s'])
    # Lock-step: the sim does not advance without the controller, so it damps from the tick the
    # controller last answered (within a tick or two of the kill).
    assert abs(t_damp - t_kill) < 0.1, (t_kill, t_damp)
    assert walk.probe.spin_until(lambda: walk.z < SAT_DOWN_Z, WAIT), walk.odom[-1]
    t_sat = walk.t
    assert walk.spin_sim(1.0)
    z_sat = walk.z
    mark = len(walk.diags)
    t_start = walk.t
    walk.start('wbc')
    back = walk.wait_status('sim', lambda s: _level(s) == OK, mark)
    assert back is not None, walk.logs()
    assert walk.probe.spin_until(lambda: walk.z > STANDING_Z + 0.05, WAIT), walk.odom[-1]
    # Up, it tracks plans again (after the stand-up's hold, with plans made after it), and
    # walks on from there.
    tracking = walk.wait_status('wbc', lambda s: values_of(s).get('mode') == 'plan', mark)
    assert tracking is not None, walk.logs()
    t_walk = walk.t
    # Sim time from the wbc's first answer (lock-step again) to the plan it left the stand
    # with: the stand-up, then the next re-plan. Before that answer the sim damps in real
    # time while the process starts, which no sim-time bound can hold. Both from the new
    # process's log lines: its diagnostics come every wall second, so the plan they name is
    # the one in force then, a re-plan or more after the first (56.456 s against the 54.408 s
    # the log names, in a run where the sim went faster than real time).
    restarted = walk.procs['wbc'].log()
    t_answered = float(re.findall(r'standing up at t = ([0-9.]+) s', restarted)[0])
    t_adopted = float(re.findall(r'plans stamped ([0-9.]+) s: leaving the stand', restarted)[0])
    wbc = yaml.safe_load((CONFIG_DIR / 'wbc.yaml').read_text())['wbc']['ros__parameters']
    stand_up = wbc['stand_up_time'] + wbc['stand_up_hold']
    assert t_adopted - t_answered < stand_up + 2.0, (t_answered, t_adopted)
    walked = walk.walks()
    assert walked > 0.4 * SPEED * 3.0, f'walked {walked:.3f} m\n{walk.logs()}'
    record('kill_wbc', fault=f'SIGKILL of wbc while walking {SPEED} m/s',
           noticed_by='sim (no joint_torque_cmd for command_timeout = 3 wall s; the sim time '
                      'does not advance meanwhile)',
           diagnostics=status.message, safe_state=f'damping mode: sits down (base {z_sat:.2f} m)',
           time_to_safe_s=round(t_sat - t_kill, 3),
           recovery=f'wbc started again: stands up, walks on ({walked:.2f} m in 3 s)',
           time_to_walk_s=round(t_walk - t_start, 3),
           lowest_base_m=round(walk.min_z(t_kill), 3),
           data_lost='nothing recorded is lost; the estimator starts over')


def _cloud_like(template: PointCloud2, data: bytes, rows: int) -> PointCloud2:
    msg = PointCloud2(header=template.header, height=1, width=rows, fields=template.fields,
                      is_bigendian=False, point_step=template.point_step,
                      row_step=template.point_step * rows, data=data, is_dense=True)
    return msg


def test_malformed_messages_are_rejected_with_one_line_and_the_robot_walks_on(walk):
    """Non-finite and wrong-sized messages on the internal topics from a second publisher:
    each receiver logs a line, keeps its last good input, and nothing crashes. They are sent
    once a second of sim time, four times: a plan reader keeps one sample (depth 1), so a
    malformed plan that the controller has not taken yet is replaced, untaken, by the
    planners' next real one, and on a loaded machine the controller can take its plans late
    enough for a single one to be lost so (docs/recording.md, "No loss")."""
    node = walk.probe.node
    footholds = walk.probe.collect(PointCloud2, 'footholds', LATCHED, timeout=30)
    assert footholds, walk.logs()
    good = footholds[-1]
    stamp = ns_to_stamp(int((walk.t + 100.0) * 1e9))        # far ahead: never a real stamp
    nan_table = bytearray(good.data)
    nan_table[0:8] = np.float64(math.nan).tobytes()         # x of the first row
    publishers = {
        'footholds': (node.create_publisher(PointCloud2, 'footholds', LATCHED), [
            _cloud_like(good, bytes(nan_table), good.width),
            _cloud_like(good, bytes(good.data[:len(good.data) // 2]), good.width)]),
        'com_plan': (node.create_publisher(MultiDOFJointTrajectory, 'com_plan', LATCHED), [
            MultiDOFJointTrajectory(joint_names=['com'], points=[
                MultiDOFJointTrajectoryPoint()])]),
        'joint_torque_cmd': (node.create_publisher(JointState, 'joint_torque_cmd', COMMAND), [
            JointState(name=['lf_haa_joint'], effort=[math.nan])]),
        'contacts': (node.create_publisher(PointCloud2, 'contacts', CONTACTS), [
            _cloud_like(good, b'\x00' * 7, 4)]),
    }
    for _pub, messages in publishers.values():
        for msg in messages:
            if hasattr(msg, 'header'):
                msg.header.stamp = stamp
    walk.probe.spin_for(1.0)                                 # discovery of the publishers
    t0 = walk.t
    walked = 0.0
    for _ in range(4):
        for pub, messages in publishers.values():
            for msg in messages:
                pub.publish(msg)
        walked += walk.walks(1.0)
    for pub, _ in publishers.values():
        node.destroy_publisher(pub)                          # latched: never for a late joiner
    assert all(walk.procs[n].alive for n in Walk.NODES), walk.logs()
    assert walked > 0.4 * SPEED * 4.0 and walk.min_z(t0) > STANDING_Z, (
        f'walked {walked:.3f} m\n{walk.logs()}')
    lines = {
        'mpc (footholds)': [ln for ln in walk.log_of('mpc').splitlines()
                            if 'footholds rejected' in ln],
        'wbc (footholds, com_plan)': [ln for ln in walk.log_of('wbc').splitlines()
                                      if 'rejected footholds' in ln or 'rejected com_plan' in ln],
        'sim (joint_torque_cmd)': [ln for ln in walk.log_of('sim').splitlines()
                                   if 'rejected joint_torque_cmd' in ln],
        'gait (contacts)': [ln for ln in walk.log_of('gait').splitlines()
                            if 'contacts rejected' in ln],
    }
    for receiver, found in lines.items():
        assert found, f'{receiver}\n{walk.logs()}'
    for found in lines.values():
        assert not any('Traceback' in ln for ln in found)
    record('malformed_messages',
           fault='non-finite and wrong-sized footholds, com_plan, joint_torque_cmd, contacts',
           noticed_by='each receiver, at the message',
           diagnostics='; '.join(f'{k}: {v[0].split("]: ", 1)[-1]}' for k, v in lines.items()),
           safe_state='the message is dropped, the last good input kept',
           time_to_safe_s=0.0, recovery=f'none needed: walked {walked:.2f} m in 4 s',
           time_to_walk_s=None, lowest_base_m=round(walk.min_z(t0), 3), data_lost='the message')


def test_recorder_killed_its_bag_is_recovered_up_to_the_last_chunk(walk, tmp_path,
                                                                   reserve_domain):
    assert walk.spin_sim(2.0)
    t_kill = walk.kill('recorder')
    # replay and rerun read the killed bag, recovering it on the way with one line; on a
    # domain of their own: a replay must never reach the graph. --info and --against read
    # it without publishing or running anything.
    env = graph_env(reserve_domain())
    for tool, extra in (('replay', ['--info']), ('rerun', ['--against', str(walk.bag)])):
        run = subprocess.run([str(REPO_ROOT / 'scripts' / f'{tool}.sh'), str(walk.bag), *extra],
                             env=env, capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stdout + run.stderr
        assert 'Traceback' not in run.stderr and 'recovered' in run.stderr, run.stderr
    out = tmp_path / 'recovered.mcap'
    report = recover(walk.bag, out)
    assert not report.had_footer and report.chunks >= 1
    count = check_bag(out)
    stamps = [stamp_to_sec(msg.header.stamp)
              for _, _, _, msg in iter_decoded(out, ['/ground_truth/odom'])]
    assert count > 0 and stamps
    lost = t_kill - max(stamps)
    # The recorder closes a chunk every 0.5 wall s (chunk_interval): what it held then is lost.
    assert 0.0 <= lost < 3.0, lost
    record('kill_recorder', fault='SIGKILL of the recorder while walking',
           noticed_by='launch.sh reports the death and respawns it (this test has no '
                      'launcher); replay/rerun recover the bag on the way, one line',
           diagnostics=run.stderr.strip().splitlines()[0].replace(str(walk.bag), 'BAG'),
           safe_state='the robot walks on (the recorder is not in the loop)',
           time_to_safe_s=0.0, recovery=f'bag_recover: {report.messages} messages in '
                                        f'{report.chunks} chunks, readable',
           time_to_walk_s=None, lowest_base_m=round(walk.min_z(t_kill), 3),
           data_lost=f'{lost:.2f} s of sim time (the open chunk)')


@pytest.mark.parametrize('damage', ['truncated', 'corrupt'])
def test_a_damaged_bag_gets_one_line_from_replay_and_rerun(walk, tmp_path, reserve_domain,
                                                           damage):
    """Runs after the recorder test: its recovered bag is damaged here."""
    source = tmp_path / 'source.mcap'
    recover(walk.bag, source)
    data = bytearray(source.read_bytes())
    if damage == 'truncated':
        data = data[:len(data) // 2]
    else:
        with open(source, 'rb') as stream:          # inside the data of a chunk in the middle
            chunks = make_reader(stream).get_summary().chunk_indexes
        chunk = chunks[len(chunks) // 2]
        middle = chunk.chunk_start_offset + chunk.chunk_length // 2
        for i in range(middle, middle + 200):
            data[i] ^= 0x5A
    bag = tmp_path / f'{damage}.mcap'
    bag.write_bytes(bytes(data))
    env = graph_env(reserve_domain())               # never the graph's, should it replay
    lines = []
    # A truncated file has lost its summary, as a killed recorder's: the tools recover it on
    # the way (one line) and read it; a corrupt chunk under an intact summary is refused.
    expected = 0 if damage == 'truncated' else 2
    for tool, extra in (('replay', ['--info']), ('rerun', ['--against', str(bag)])):
        run = subprocess.run([str(REPO_ROOT / 'scripts' / f'{tool}.sh'), str(bag), *extra],
                             env=env, capture_output=True, text=True, timeout=120)
        assert run.returncode == expected, run.stdout + run.stderr
        assert 'Traceback' not in run.stderr and str(bag) in run.stderr, run.stderr
        lines.append(run.stderr.strip().splitlines()[0].replace(str(bag), 'BAG'))
    record(f'{damage}_bag', fault=f'a {damage} bag given to replay.sh and rerun.sh',
           noticed_by='replay, rerun (every chunk read and its CRC checked first)',
           diagnostics=lines[1],
           safe_state=('recovered on the way, read' if damage == 'truncated'
                       else 'exit code 2, nothing published or started'),
           time_to_safe_s=0.0, recovery='bag_recover keeps the intact chunks',
           time_to_walk_s=None, lowest_base_m='', data_lost='the damaged chunks')
