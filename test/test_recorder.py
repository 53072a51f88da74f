"""Recorder node and replay tool, as real processes.

The bags are read back with the ``mcap`` library's reader and ``mcap_ros2``'s CDR decoder, which
parses the schema text the recorder wrote: a message that decodes to the published values proves
the schema right.
"""

from __future__ import annotations

import re
import signal
import subprocess
import time

import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Transform, Twist
from harness import CONFIG_DIR, REPO_ROOT, graph_env
from mcap.reader import make_reader
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2, PointField
from test_launch import LaunchProcess
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from replan_ros.messages.stamps import stamp_to_ns
from replan_ros.recording.bag_io import iter_decoded, qos_profiles_yaml
from replan_ros.recording.bag_writer import BagWriter, recover
from replan_ros.transport.on_demand import helper_name
from replan_ros.transport.qos import CONTACTS, LATCHED, SENSOR

RELIABLE = CONTACTS      # reliable, volatile, depth 50
TICK = 0.004   # s, the graph's control period (250 Hz)


def _stamp(k: int) -> Time:
    ns = (k + 1) * 4_000_000
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _joint_state(k: int) -> JointState:
    msg = JointState(name=['lf_haa_joint', 'lf_hfe_joint'], position=[0.001 * k, -0.5],
                     velocity=[float(k), 0.25], effort=[-float(k), 12.5])
    msg.header.stamp = _stamp(k)
    return msg


def _odometry(k: int) -> Odometry:
    msg = Odometry(child_frame_id='base_link')
    msg.header.stamp, msg.header.frame_id = _stamp(k), 'odom'
    msg.pose.pose.position.x = 0.01 * k
    msg.pose.pose.orientation.w = 1.0
    msg.twist.twist.linear.x = 0.2
    msg.pose.covariance[0] = float(k)
    return msg


def _cloud(k: int) -> PointCloud2:
    msg = PointCloud2(height=1, width=4, point_step=8, row_step=32, is_dense=True,
                      fields=[PointField(name='z', offset=0, datatype=PointField.FLOAT64,
                                         count=1)],
                      data=bytes((k + i) % 256 for i in range(32)))
    msg.header.stamp, msg.header.frame_id = _stamp(k), 'odom'
    return msg


def _trajectory(k: int) -> MultiDOFJointTrajectory:
    point = MultiDOFJointTrajectoryPoint(transforms=[Transform()], velocities=[Twist()],
                                         accelerations=[Twist()])
    point.transforms[0].translation.z = 0.5 + 0.001 * k
    point.velocities[0].linear.x = 0.1 * k
    msg = MultiDOFJointTrajectory(joint_names=['com'], points=[point, point])
    msg.header.stamp, msg.header.frame_id = _stamp(k), 'odom'
    return msg


RECORDER_READER = helper_name('recorder')     # the node that holds the recorder's readers


def _wait_subscribed(probe, topics, node_name=RECORDER_READER, timeout=20.0) -> bool:
    def subscribed():
        return all(any(info.node_name == node_name
                       for info in probe.node.get_subscriptions_info_by_topic(topic))
                   for topic in topics)
    return probe.spin_until(subscribed, timeout)


def _publish_ticks(probe, publishers, first: int, count: int) -> None:
    """Publish ``count`` ticks at 250 Hz: /clock, then the tick's messages, stamped alike."""
    start = time.monotonic()
    for i in range(count):
        k = first + i
        publishers['/clock'].publish(Clock(clock=_stamp(k)))
        publishers['/rec/joint_states'].publish(_joint_state(k))
        publishers['/rec/odom'].publish(_odometry(k))
        publishers['/rec/contacts'].publish(_cloud(k))
        if k % 25 == 0:
            publishers['/rec/com_plan'].publish(_trajectory(k))
        delay = start + (i + 1) * TICK - time.monotonic()
        if delay > 0:
            time.sleep(delay)


def _latest_counts(diagnostics: list) -> dict[str, str]:
    for array in reversed(diagnostics):
        for status in array.status:
            if status.name.startswith('recorder'):
                return {kv.key: kv.value for kv in status.values}
    return {}


def _received_all(diagnostics: list, topics) -> bool:
    """True if the recorder's latest diagnostics count a message received on every topic."""
    counts = _latest_counts(diagnostics)
    return all(int(counts.get(f'{topic} received', 0)) > 0 for topic in topics)


def _make_publishers(probe):
    node = probe.node
    return {
        '/clock': node.create_publisher(Clock, '/clock', RELIABLE),
        '/rec/joint_states': node.create_publisher(JointState, '/rec/joint_states', SENSOR),
        '/rec/odom': node.create_publisher(Odometry, '/rec/odom', SENSOR),
        '/rec/contacts': node.create_publisher(PointCloud2, '/rec/contacts', RELIABLE),
        '/rec/com_plan': node.create_publisher(MultiDOFJointTrajectory, '/rec/com_plan',
                                               LATCHED),
    }


def test_recorded_bag_decodes_to_the_published_messages(launcher, probe, tmp_path):
    publishers = _make_publishers(probe)
    # A latched plan published before the recorder exists must still be recorded.
    publishers['/rec/com_plan'].publish(_trajectory(-1))
    extra = tmp_path / 'extra.yaml'
    extra.write_text('recorder:\n  ros__parameters:\n'
                     '    metadata_json: \'{"purpose": "test", "seed": 7}\'\n')
    bag = tmp_path / 'run.mcap'
    recorder = launcher.start(
        'recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
        params={'output': str(bag), 'topics_regex': '^/rec/|^/clock$',
                'publish_time': 'header', 'config_files': [str(CONFIG_DIR / 'recorder.yaml')]},
        ros_args=['--params-file', str(extra)])
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', RELIABLE)
    assert _wait_subscribed(probe, list(publishers)), launcher.logs()
    probe.spin_for(1.0)   # discovery of the subscriptions on the publishers' side

    ticks = 500
    _publish_ticks(probe, publishers, 0, ticks)
    expected = {'/clock': ticks, '/rec/joint_states': ticks, '/rec/odom': ticks,
                '/rec/contacts': ticks, '/rec/com_plan': ticks // 25 + 1}
    assert probe.spin_until(
        lambda: _latest_counts(diagnostics).get('/rec/contacts written') == str(ticks),
        timeout=10.0), (_latest_counts(diagnostics), launcher.logs())
    counts = _latest_counts(diagnostics)
    assert counts['queued'] == '0' and counts['write_errors'] == '0'
    assert recorder.stop() == 0, recorder.log()

    with open(bag, 'rb') as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    recorded = {summary.channels[c].topic: n
                for c, n in summary.statistics.channel_message_counts.items()}
    assert recorded == expected   # published == recorded, topic by topic
    by_topic = {c.topic: c for c in summary.channels.values()}
    assert 'best_effort' in by_topic['/rec/odom'].metadata['offered_qos_profiles']
    assert 'transient_local' in by_topic['/rec/com_plan'].metadata['offered_qos_profiles']
    assert by_topic['/rec/odom'].metadata['topic_type_hash'].startswith('RIHS01_')
    assert summary.schemas[by_topic['/rec/odom'].schema_id].name == 'nav_msgs/msg/Odometry'
    assert metadata['replan_user'] == {'purpose': 'test', 'seed': '7'}
    assert str(CONFIG_DIR / 'recorder.yaml') in metadata['replan_config']
    assert metadata['replan_run']['git_revision']
    # Counted against the publishers' sequence numbers: nothing lost.
    assert metadata['replan_completeness']['complete'] == 'true', metadata['replan_completeness']

    seen = dict.fromkeys(expected, 0)
    plans = []
    for topic, log_time, publish_time, msg in iter_decoded(bag):
        k = seen[topic]
        seen[topic] += 1
        if topic == '/clock':
            assert (msg.clock.sec, msg.clock.nanosec) == (_stamp(k).sec, _stamp(k).nanosec)
            continue
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        assert publish_time == stamp_ns          # publish_time: header
        assert abs(log_time - stamp_ns) < 1e9    # log_time: sim time (wall would be ~1.7e18)
        if topic == '/rec/joint_states':
            ref = _joint_state(k)
            assert list(msg.name) == ref.name
            assert list(msg.position) == list(ref.position)
            assert list(msg.velocity) == list(ref.velocity)
            assert list(msg.effort) == list(ref.effort)
        elif topic == '/rec/odom':
            ref = _odometry(k)
            assert msg.child_frame_id == 'base_link' and msg.header.frame_id == 'odom'
            assert msg.pose.pose.position.x == ref.pose.pose.position.x
            assert msg.pose.covariance[0] == float(k) and msg.twist.twist.linear.x == 0.2
        elif topic == '/rec/contacts':
            assert bytes(msg.data) == bytes(_cloud(k).data) and msg.fields[0].name == 'z'
        else:
            plans.append(msg)
    assert seen == expected
    ref_plans = [_trajectory(k) for k in [-1, *range(0, ticks, 25)]]
    assert [p.points[0].transforms[0].translation.z for p in plans] == \
        [p.points[0].transforms[0].translation.z for p in ref_plans]
    assert [p.points[1].velocities[0].linear.x for p in plans] == \
        [p.points[1].velocities[0].linear.x for p in ref_plans]


@pytest.mark.parametrize('log_time_clock', ['sim', 'wall'])
def test_log_time_follows_the_clock_asked_for_even_with_clock_not_recorded(
        launcher, probe, tmp_path, log_time_clock):
    """/clock left out of the bag: ``sim`` log times still follow it (the recorder reads it
    on demand for its time alone), within a take period of each message's stamp and never
    decreasing; ``wall`` log times are the system clock while the messages came."""
    publishers = _make_publishers(probe)
    bag = tmp_path / 'clock.mcap'
    recorder = launcher.start(
        'recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
        params={'output': str(bag), 'topics_regex': '^/rec/(odom|contacts)$',
                'log_time_clock': log_time_clock})
    assert _wait_subscribed(probe, ['/rec/odom', '/rec/contacts']), launcher.logs()
    if log_time_clock == 'sim':
        assert _wait_subscribed(probe, ['/clock']), launcher.logs()
    probe.spin_for(1.0)
    wall_start = time.time_ns()
    _publish_ticks(probe, publishers, 0, 300)
    probe.spin_for(0.5)
    wall_end = time.time_ns()
    assert recorder.stop() == 0, recorder.log()
    log_times, offsets, topics = [], [], set()
    for topic, log_time, _, msg in iter_decoded(bag):
        topics.add(topic)
        log_times.append(log_time)
        offsets.append(log_time - (msg.header.stamp.sec * 1_000_000_000
                                   + msg.header.stamp.nanosec))
    assert topics == {'/rec/odom', '/rec/contacts'}
    assert len(log_times) == 600
    assert log_times == sorted(log_times)
    if log_time_clock == 'sim':
        # The recorder's sim clock is the newest /clock taken: behind a message's own tick by
        # at most about a take period (0.1 s wall, here 0.1 s of sim).
        assert max(abs(o) for o in offsets) < 0.25e9, (min(offsets), max(offsets))
    else:
        assert wall_start <= log_times[0] and log_times[-1] <= wall_end


def test_sigkill_leaves_a_file_whose_finished_chunks_are_recovered(launcher, probe, tmp_path):
    publishers = _make_publishers(probe)
    bag = tmp_path / 'killed.mcap'
    recorder = launcher.start(
        'recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
        params={'output': str(bag), 'topics': ['/rec/joint_states', '/clock'],
                'chunk_interval': 0.2})
    assert _wait_subscribed(probe, ['/rec/joint_states', '/clock']), launcher.logs()
    probe.spin_for(1.0)
    _publish_ticks(probe, publishers, 0, 250)
    probe.spin_for(1.5)   # > chunk_interval: every message of phase 1 is in a finished chunk
    # Phase 2: killed while messages keep coming.
    _publish_ticks(probe, publishers, 250, 100)
    recorder.signal(signal.SIGKILL)
    recorder.process.wait(10)
    assert recorder.process.returncode == -signal.SIGKILL

    out = tmp_path / 'recovered.mcap'
    report = recover(bag, out)
    assert not report.had_footer and report.chunks >= 1
    positions = [msg.position[0] for topic, _, _, msg in iter_decoded(out)
                 if topic == '/rec/joint_states']
    # Everything before the last finished chunk, in order, and nothing invented.
    assert len(positions) >= 250
    assert positions == [_joint_state(k).position[0] for k in range(len(positions))]


def test_sigterm_finishes_the_bag_with_its_summary(launcher, probe, tmp_path):
    publishers = _make_publishers(probe)
    bag = tmp_path / 'terminated.mcap'
    recorder = launcher.start('recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
                              params={'output': str(bag), 'topics': ['/rec/odom', '/clock']})
    assert _wait_subscribed(probe, ['/rec/odom', '/clock']), launcher.logs()
    probe.spin_for(1.0)
    _publish_ticks(probe, publishers, 0, 100)
    probe.spin_for(0.5)
    recorder.signal(signal.SIGTERM)
    recorder.process.wait(15)
    assert recorder.process.returncode == 0, recorder.log()
    with open(bag, 'rb') as stream:
        summary = make_reader(stream).get_summary()   # footer and summary are there
    counts = {summary.channels[c].topic: n
              for c, n in summary.statistics.channel_message_counts.items()}
    assert counts == {'/rec/odom': 100, '/clock': 100}
    # The bag's directory opens as a rosbag2 bag (its metadata.yaml).
    with AnyReader([tmp_path]) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == counts
        assert reader.message_count == sum(1 for _ in reader.messages()) == 200


def test_replay_publishes_the_bag_with_its_timing_and_clock(launcher, probe, tmp_path):
    bag = tmp_path / 'replay.mcap'
    writer = BagWriter(bag)
    clock_id = writer.add_channel('/clock', 'rosgraph_msgs/msg/Clock',
                                  qos_profiles_yaml([RELIABLE]))
    js_id = writer.add_channel('/rep/joint_states', 'sensor_msgs/msg/JointState',
                               qos_profiles_yaml([RELIABLE]))
    plan_id = writer.add_channel('/rep/com_plan', 'trajectory_msgs/msg/MultiDOFJointTrajectory',
                                 qos_profiles_yaml([LATCHED]))
    ticks = 100
    for k in range(ticks):
        t = (k + 1) * 10_000_000   # 100 Hz sim time, 1 s
        writer.write(clock_id, serialize_message(Clock(clock=Time(nanosec=t))), t, t)
        writer.write(js_id, serialize_message(_joint_state(k)), t, t)
        if k == 0:
            writer.write(plan_id, serialize_message(_trajectory(3)), t, t)
    writer.close()

    clocks = probe.subscribe(Clock, '/clock', RELIABLE)
    states: list = []
    arrivals: list = []

    def on_state(msg):
        states.append(msg)
        arrivals.append(time.monotonic())
    probe.node.create_subscription(JointState, '/rep/joint_states', on_state, RELIABLE)
    plans = probe.subscribe(MultiDOFJointTrajectory, '/rep/com_plan', LATCHED)
    player = launcher.start('replay', args=[str(bag), '--rate', '2.0', '--delay', '0.5',
                                            '--wait-subscribers', '20'])
    assert probe.spin_until(lambda: len(states) >= ticks and len(clocks) >= ticks, 20.0), \
        (len(states), len(clocks), launcher.logs())
    assert probe.spin_until(lambda: not player.alive, 10.0)
    assert player.process.returncode == 0, player.log()

    assert [m.position[0] for m in states] == [_joint_state(k).position[0] for k in range(ticks)]
    assert [m.clock.nanosec for m in clocks] == [(k + 1) * 10_000_000 for k in range(ticks)]
    assert [p.points[0].transforms[0].translation.z for p in plans] == \
        [_trajectory(3).points[0].transforms[0].translation.z]
    # Original timing at x2: 0.99 s of bag -> ~0.5 s; published all at once would be ~0.
    assert arrivals[-1] - arrivals[0] > 0.3


WALK = """name: rerun_walk
duration: 10.0
events:
  - {t: 0.5, cmd_vel: [0.15, 0.0, 0.0]}
  - {t: 6.0, push: {force: [0.0, 100.0, 0.0], duration: 0.2}}
"""


def test_rerun_of_a_recorded_walk_is_bit_identical(ros_domain, tmp_path):
    """A bag re-run gives the same run: 0 m, every message of the run's state and decisions
    the same bytes, the same last tick."""
    env = graph_env(ros_domain)
    scenario = tmp_path / 'walk.yaml'
    scenario.write_text(WALK)
    recorded = subprocess.run(
        [str(REPO_ROOT / 'scripts' / 'scenario.sh'), str(scenario), '--out', str(tmp_path / 'a')],
        env=env, capture_output=True, text=True, timeout=900)
    bags = sorted((tmp_path / 'a' / 'bag').glob('*.mcap'))
    assert bags, recorded.stdout + recorded.stderr
    rerun = subprocess.run(
        [str(REPO_ROOT / 'scripts' / 'rerun.sh'), str(bags[0]), '--out', str(tmp_path / 'b')],
        env=env, capture_output=True, text=True, timeout=900)
    match = re.search(r'largest base position deviation: ([0-9.e+-]+|inf) m', rerun.stdout)
    assert match, rerun.stdout + rerun.stderr
    assert float(match.group(1)) == 0.0, rerun.stdout
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    assert '[rerun] messages: bit-identical' in rerun.stdout, rerun.stdout
    assert 'both end at t = 10.000 s' in rerun.stdout, rerun.stdout


# HyQ with an unactuated revolute joint: a model whose /tf the recorder cannot derive.
HEAD = """  <link name="head"/>
  <joint name="head_pan" type="revolute">
    <parent link="base_link"/><child link="head"/>
    <origin xyz="0.5 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/>
  </joint>
</robot>"""


def test_a_robot_the_bag_cannot_show_stops_the_run_before_the_robot_moves(ros_domain, tmp_path):
    """The recorder stops the start with one line (exit code 2) and leaves no bag; the launcher
    stops the graph without respawning it and without starting the controller, so the sim
    never steps (every ANYmal C bag once lacked /robot_description and /tf, and the runs
    passed)."""
    urdf = tmp_path / 'hyq_head.urdf'
    urdf.write_text((REPO_ROOT / 'urdf' / 'hyq.urdf').read_text().replace('</robot>', HEAD))
    robot = tmp_path / 'hyq_head.yaml'
    robot.write_text((CONFIG_DIR / 'robots' / 'hyq.yaml').read_text()
                     .replace('name: hyq', 'name: hyq_head')
                     .replace('urdf: urdf/hyq.urdf', f'urdf: {urdf}'))
    launch = LaunchProcess(['--robot', str(robot), '--profile', 'ideal', '--record',
                            str(tmp_path / 'bag'), '--run-dir', str(tmp_path / 'run'),
                            '--duration', '5', '--quiet'], ros_domain)
    try:
        assert launch.process.wait(120) == 2, launch.output
    finally:
        launch.stop()
    output = launch.output
    reason = (f'config error: cannot derive /robot_description and /tf of hyq_head: {urdf}: '
              'joint head_pan is not actuated; a bag without them cannot show the robot')
    assert f'recorder refused its configuration, stopping the graph: {reason}' in output, output
    assert output.count('died') == 1 and 'respawn' not in output, output
    assert 'started wbc' not in output and 'all nodes stopped' in output, output
    log = (tmp_path / 'run' / 'logs' / 'recorder.log').read_text()
    errors = [line for line in log.splitlines() if 'error' in line.lower()]
    assert len(errors) == 1 and errors[0].startswith('[FATAL]') and reason in errors[0], log
    assert not list(tmp_path.glob('bag/*.mcap'))


def test_an_unwritable_output_stops_the_recording_with_one_line_and_the_recorder_stays_up(
        launcher, probe, tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    recorder = launcher.start('recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
                              params={'output_dir': str(blocker / 'bag')})
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', RELIABLE)
    assert probe.spin_until(lambda: 'recording stopped' in recorder.log(), timeout=20.0), \
        recorder.log()
    lines = [ln for ln in recorder.log().splitlines() if 'recording stopped' in ln]
    assert len(lines) == 1 and str(blocker) in lines[0] and 'Not a directory' in lines[0]
    assert probe.spin_until(lambda: any(
        s.name.startswith('recorder') and s.level == DiagnosticStatus.ERROR
        and 'recording stopped' in s.message for a in diagnostics for s in a.status),
        timeout=10.0)
    assert recorder.alive                  # no crash, so no respawn loop that stops a graph
    assert recorder.stop() == 0, recorder.log()
    assert 'Traceback' not in recorder.log()


def test_a_respawned_recorder_continues_the_bag_as_a_split(launcher, probe, tmp_path):
    from replan_ros.recording.bag_files import bag_files
    from replan_ros.recording.bag_read import read_messages
    from replan_ros.recording.completeness import bag_completeness

    publishers = _make_publishers(probe)
    folder = tmp_path / 'bag'
    params = {'output_dir': str(folder), 'topics': ['/rec/joint_states', '/clock'],
              'chunk_interval': 0.2}
    first = launcher.start('recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
                           params=params)
    assert _wait_subscribed(probe, ['/rec/joint_states', '/clock']), launcher.logs()
    probe.spin_for(1.0)
    _publish_ticks(probe, publishers, 0, 250)
    probe.spin_for(1.5)                    # > chunk_interval: phase 1 is in finished chunks
    first.signal(signal.SIGKILL)
    first.process.wait(10)
    _publish_ticks(probe, publishers, 250, 50)      # while no recorder runs: lost, counted
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', RELIABLE)
    second = launcher.start('recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
                            params=params)
    assert probe.spin_until(lambda: 'recording to' in second.log(), timeout=20.0), second.log()
    assert 'recovered' in second.log()             # the killed file, said in one line
    assert _wait_subscribed(probe, ['/rec/joint_states', '/clock']), launcher.logs()
    # A reader that replaces a killed process's is seen in the graph before samples reach it
    # (DDS): ticks published until the new recorder has received both topics are the
    # respawn's loss, counted below; every tick after that must be in the bag.
    k = 300
    while not _received_all(diagnostics, ('/rec/joint_states', '/clock')) and k < 300 + 2500:
        _publish_ticks(probe, publishers, k, 25)
        probe.spin_for(0.05)
        k += 25
    assert _received_all(diagnostics, ('/rec/joint_states', '/clock')), second.log()
    _publish_ticks(probe, publishers, k, 250)
    probe.spin_for(0.5)
    assert second.stop() == 0, second.log()
    files = bag_files(folder)
    assert len(files) == 2 and files[0].name.endswith('.recovered.mcap'), files
    with AnyReader([folder]) as reader:            # metadata.yaml lists both files
        assert reader.message_count == sum(1 for _ in reader.messages())
        total = reader.message_count
    positions = [m.position[0] for _, m in
                 read_messages(folder, topics=['/rec/joint_states'])['/rec/joint_states']]
    assert positions == sorted(positions)
    ticks = {round(p * 1000) for p in positions}
    assert ticks >= set(range(250)) | set(range(k, k + 250)), sorted(ticks)
    assert total >= len(positions)
    counted = bag_completeness(folder)
    assert not counted.complete and counted.topics['/rec/joint_states'].missing >= 50, \
        counted.gaps_text()


def test_a_stopped_recorder_gets_every_tick_and_plan_again_from_the_writers(
        launcher, probe, tmp_path):
    """A recorder whose process does not run for a second (SIGSTOP: as when a loaded machine
    does not schedule its receive thread) while the per-tick topics fill its socket misses
    samples in transport; the writers' histories (``SENSOR_PUB``, ``LATCHED_PUB``) send them
    again, so the bag holds every tick and every plan (docs/recording.md, "No loss"). With
    plan writers of depth 1 the plans published while it stopped were lost."""
    from replan_ros.recording.completeness import bag_completeness
    from replan_ros.transport.qos import LATCHED_PUB, SENSOR_PUB

    node = probe.node
    ticks = node.create_publisher(JointState, '/rec/joint_states', SENSOR_PUB)
    plans = node.create_publisher(MultiDOFJointTrajectory, '/rec/com_plan', LATCHED_PUB)
    joints = [f'joint_{i}' for i in range(60)]     # about 2.5 kB a tick: 0.6 MB/s at 250 Hz
    folder = tmp_path / 'bag'
    recorder = launcher.start('recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
                              params={'output_dir': str(folder),
                                      'topics': ['/rec/joint_states', '/rec/com_plan']})
    assert _wait_subscribed(probe, ['/rec/joint_states', '/rec/com_plan']), launcher.logs()
    probe.spin_for(1.0)
    count, plan_every, stop_at, resume_at = 1000, 25, 250, 500     # ticks; 1 s stopped
    start = time.monotonic()
    try:
        for k in range(count):
            if k == stop_at:
                recorder.signal(signal.SIGSTOP)
            elif k == resume_at:
                recorder.signal(signal.SIGCONT)
            msg = JointState(name=joints, position=[0.001 * k] * 60, velocity=[0.0] * 60)
            msg.header.stamp = _stamp(k)
            ticks.publish(msg)
            if k % plan_every == 0:
                plans.publish(_trajectory(k))
            delay = start + (k + 1) * TICK - time.monotonic()
            if delay > 0:
                time.sleep(delay)
    finally:
        recorder.signal(signal.SIGCONT)
    probe.spin_for(1.0)
    assert recorder.stop() == 0, recorder.log()
    written = {'/rec/joint_states': [], '/rec/com_plan': []}
    for topic, _, _, msg in iter_decoded(next(folder.glob('*.mcap'))):
        written[topic].append(stamp_to_ns(msg.header.stamp))
    # No /clock here: every log time is 0, so the order within the bag is not checked.
    assert sorted(written['/rec/joint_states']) == [stamp_to_ns(_stamp(k)) for k in range(count)]
    assert sorted(written['/rec/com_plan']) == [stamp_to_ns(_stamp(k))
                                                for k in range(0, count, plan_every)]
    counted = bag_completeness(folder)
    assert counted.topics['/rec/com_plan'].missing == 0, counted.gaps_text()


def test_a_late_plan_reader_ends_on_the_newest_plan_and_a_recorder_gets_the_history(probe):
    """The plan writers' history (``LATCHED_PUB``, 20) reaches a reader that joins late whole
    only if it keeps all (a respawned recorder: ``recorder_qos``). A graph reader (``LATCHED``,
    depth 1) may take some of the older plans too: its depth drops only the samples it has not
    taken yet, and the executor takes each one as it comes. What it gets is in publication
    order and ends on the newest, which is what the controller needs: it keeps plans by stamp
    and adopts the newest pair (``tick_protocol``; docs/recording.md, "No loss")."""
    from replan_ros.transport.qos import LATCHED_PUB, PLAN_HISTORY, recorder_qos

    plans = probe.node.create_publisher(MultiDOFJointTrajectory, '/rec/late_plan', LATCHED_PUB)
    published = [_trajectory(k) for k in range(10)]
    for msg in published:
        plans.publish(msg)
    assert len(published) < PLAN_HISTORY
    newest = probe.subscribe(MultiDOFJointTrajectory, '/rec/late_plan', LATCHED)
    every = probe.subscribe(MultiDOFJointTrajectory, '/rec/late_plan',
                            recorder_qos([LATCHED_PUB])[0])
    assert probe.spin_until(lambda: len(every) == len(published), timeout=10.0), len(every)
    probe.spin_for(0.5)                  # nothing more comes to either
    order = [stamp_to_ns(m.header.stamp) for m in published]
    assert [stamp_to_ns(m.header.stamp) for m in every] == order
    taken = [order.index(stamp_to_ns(m.header.stamp)) for m in newest]
    assert taken and taken[-1] == len(published) - 1, taken
    assert taken == sorted(set(taken)), taken
