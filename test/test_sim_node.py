"""The sim node as a process: state topics and /clock, lock-step, bad commands, controller death,
pushes."""

from __future__ import annotations

import math

import numpy as np
from conftest import CONFIG_DIR
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, PointCloud2

from replan_core.common.types import JOINT_NAMES
from replan_ros.messages.contacts import contacts_from_msg
from replan_ros.messages.imu import imu_from_msg
from replan_ros.messages.joint_state import joint_state_from_msg, torque_cmd_to_msg
from replan_ros.messages.stamps import ns_to_stamp, stamp_to_ns
from replan_ros.telemetry.diagnostics import values_of
from replan_ros.transport import qos

TICK_NS = 4_000_000
SIM_YAML = CONFIG_DIR / 'sim.yaml'


class Driver:
    """Test-side controller: subscribes the sim's outputs, sends torque commands."""

    def __init__(self, probe) -> None:
        self.probe = probe
        self.joints = probe.subscribe(JointState, 'joint_states', qos.SENSOR)
        self.odom = probe.subscribe(Odometry, 'ground_truth/odom', qos.SENSOR)
        self.contacts = probe.subscribe(PointCloud2, 'ground_truth/contacts', qos.CONTACTS)
        self.imu = probe.subscribe(Imu, 'imu', qos.SENSOR)
        self.clock = probe.subscribe(Clock, '/clock', qos.CLOCK)
        self.diag = probe.subscribe(DiagnosticArray, '/diagnostics', qos.COMMAND)
        self.applied = probe.subscribe(WrenchStamped, 'applied_wrench', qos.SCHEDULE)
        self.cmd_pub = probe.node.create_publisher(JointState, 'joint_torque_cmd', qos.COMMAND)

    def wait_ready(self, timeout: float = 30.0) -> bool:
        return self.probe.spin_until(
            lambda: self.cmd_pub.get_subscription_count() > 0 and self.joints and self.odom
            and self.contacts and self.imu, timeout)

    def latest_ns(self) -> int:
        return max(stamp_to_ns(m.header.stamp) for m in self.joints)

    def stamps(self, msgs) -> set[int]:
        return {stamp_to_ns(m.header.stamp) for m in msgs}

    def send(self, stamp_ns: int, torques) -> None:
        msg = torque_cmd_to_msg(0.0, np.asarray(torques, dtype=float))
        msg.header.stamp = ns_to_stamp(stamp_ns)
        self.cmd_pub.publish(msg)

    def send_raw(self, msg: JointState) -> None:
        self.cmd_pub.publish(msg)

    def wait_state(self, stamp_ns: int, timeout: float = 5.0) -> bool:
        return self.probe.spin_until(
            lambda: stamp_ns in self.stamps(self.joints) and stamp_ns in self.stamps(self.odom)
            and stamp_ns in self.stamps(self.contacts), timeout)

    def step(self, torques) -> int:
        """Answer the latest state; return the new state stamp."""
        now = self.latest_ns()
        self.send(now, torques)
        assert self.wait_state(now + TICK_NS), f'no state at {(now + TICK_NS) * 1e-9} s'
        return now + TICK_NS

    def joint_msg(self, stamp_ns: int) -> JointState:
        return next(m for m in reversed(self.joints) if stamp_to_ns(m.header.stamp) == stamp_ns)

    def sim_status(self) -> DiagnosticStatus | None:
        for arr in reversed(self.diag):
            for st in arr.status:
                if st.name == 'sim':
                    return st
        return None


def start_sim(launcher, **params):
    return launcher.start('sim_node', params_file=SIM_YAML, params=params)


def test_publishes_state_and_waits_for_first_command(launcher, probe):
    sim = start_sim(launcher)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    probe.spin_for(1.0)                              # ~10 republish periods, no command
    assert driver.clock, 'no /clock'
    for msgs in (driver.joints, driver.odom, driver.contacts):
        assert driver.stamps(msgs) == {0}            # the sim did not advance
    assert {stamp_to_ns(c.clock) for c in driver.clock} == {0}
    assert len(driver.joints) >= 5                   # republished while waiting
    js = driver.joints[-1]
    assert list(js.name) == list(JOINT_NAMES)
    odom = driver.odom[-1]
    assert odom.header.frame_id == 'odom' and odom.child_frame_id == 'base_link'
    assert 0.55 < odom.pose.pose.position.z < 0.62   # standing on flat ground
    contacts = contacts_from_msg(driver.contacts[-1])
    assert contacts.contact.all()
    assert driver.imu, 'no imu'
    imu = imu_from_msg(driver.imu[-1])
    assert driver.imu[-1].header.frame_id == 'base_link'
    np.testing.assert_allclose(imu.linear_acceleration, [0.0, 0.0, 9.81], atol=1e-3)  # ideal
    np.testing.assert_allclose(imu.angular_velocity, 0.0, atol=1e-6)
    assert probe.spin_until(lambda: driver.sim_status() is not None, 5.0)
    status = driver.sim_status()
    assert status.level == DiagnosticStatus.OK
    assert values_of(status)['mode'] == 'waiting_first_command'
    assert sim.alive


def test_lock_step_one_tick_per_command(launcher, probe):
    start_sim(launcher)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    torques = np.linspace(-5.0, 5.0, 12)
    stamps = [driver.step(torques) for _ in range(10)]
    assert stamps == [TICK_NS * (k + 1) for k in range(10)]
    # /clock is keep-last depth 1: a slow reader may miss ticks, never sees a time not stepped.
    assert {stamp_to_ns(c.clock) for c in driver.clock} <= {0, *stamps}
    assert probe.spin_until(lambda: stamp_to_ns(driver.clock[-1].clock) == stamps[-1], 2.0)
    np.testing.assert_allclose(driver.joint_msg(stamps[-1]).effort, torques)
    # A command for a stale stamp is ignored: the sim stays at its tick.
    driver.send(stamps[-2], torques)
    probe.spin_for(0.5)
    assert driver.latest_ns() == stamps[-1]
    assert max(driver.stamps(driver.contacts)) == stamps[-1]
    # Several commands for the current stamp advance it once.
    driver.send(stamps[-1], torques)
    driver.send(stamps[-1], torques)
    assert driver.wait_state(stamps[-1] + TICK_NS)
    probe.spin_for(0.5)
    assert driver.latest_ns() == stamps[-1] + TICK_NS


def test_stop_time_holds_at_its_tick(launcher, probe):
    """With stop_time the sim steps to the first tick at or after it and no further: that tick
    goes out with /clock (off the clock grid too), is republished until its command comes and
    not after, commands for it are not stepped, the robot is not damped."""
    start_sim(launcher, stop_time=0.01, command_timeout=0.5)   # on no tick: holds at 0.012
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    torques = np.linspace(-5.0, 5.0, 12)
    stamps = [driver.step(torques) for _ in range(3)]
    assert stamps[-1] == 3 * TICK_NS

    def held_copies() -> int:
        return len([m for m in driver.joints if stamp_to_ns(m.header.stamp) == stamps[-1]])

    # Tick 3 is off the 5-tick clock grid: the held tick's own /clock says where it stopped.
    assert probe.spin_until(lambda: stamps[-1] in {stamp_to_ns(c.clock) for c in driver.clock},
                            2.0), launcher.logs()
    assert probe.spin_until(lambda: held_copies() >= 3, 5.0), launcher.logs()  # not answered
    driver.send(stamps[-1], torques)
    probe.spin_for(0.3)                           # a republish in flight may still come
    answered = held_copies()
    for _ in range(10):                           # past command_timeout (0.5 wall s)
        driver.send(stamps[-1], torques)
        probe.spin_for(0.1)
    assert driver.latest_ns() == stamps[-1], launcher.logs()
    assert held_copies() == answered, launcher.logs()      # answered: no more republishes
    assert probe.spin_until(lambda: driver.sim_status() is not None and values_of(
        driver.sim_status())['holding_at_stop_time'] == 'True', 5.0), launcher.logs()
    status = driver.sim_status()
    assert status.level == DiagnosticStatus.OK and values_of(status)['mode'] == 'lock_step'
    assert 'reached stop_time: holding at t = 0.012 s' in launcher.logs()


def test_bad_commands_rejected_previous_kept(launcher, probe):
    sim = start_sim(launcher)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    good = np.full(12, 3.0)
    now = driver.step(good)

    short = torque_cmd_to_msg(0.0, np.zeros(11))
    short.name = list(JOINT_NAMES[:11])
    unknown = torque_cmd_to_msg(0.0, np.zeros(12))
    unknown.name = [*JOINT_NAMES[:11], 'lf_tail_joint']
    nan = torque_cmd_to_msg(0.0, np.zeros(12))
    nan.effort[4] = math.nan
    for msg in (short, unknown, nan):
        msg.header.stamp = ns_to_stamp(now)
        driver.send_raw(msg)
    probe.spin_for(1.0)
    assert driver.latest_ns() == now                  # not advanced by any bad command
    np.testing.assert_allclose(driver.joint_msg(now).effort, good)   # previous command kept
    log = sim.log()
    assert 'rejected joint_torque_cmd' in log
    assert 'with 11 joints, expected 12' in log
    assert "unknown joints ['lf_tail_joint']" in log
    assert "non-finite effort for ['rf_hfe_joint']" in log
    assert driver.step(good) == now + TICK_NS         # a good command still works
    assert probe.spin_until(lambda: driver.sim_status() is not None
                            and int(values_of(driver.sim_status())['commands_rejected']) == 3,
                            5.0)


def test_controller_silence_damping_then_resume(launcher, probe):
    # The watchdog is wall time: the test's own answers must come within command_timeout,
    # under any load of the machine (0.5 s was missed beside two node graphs on 2 cores).
    sim = start_sim(launcher, command_timeout=2.0, diagnostics_period=0.25)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    now = driver.step(np.zeros(12))

    def damping():
        st = driver.sim_status()
        return st is not None and st.level == DiagnosticStatus.ERROR

    assert probe.spin_until(damping, 10.0), launcher.logs()
    status = driver.sim_status()
    assert values_of(status)['mode'] == 'damping'
    assert 'controller dead' in status.message
    assert 'controller dead' in sim.log()
    probe.spin_for(1.0)
    # Free-running: it advances without commands, paced by the wall clock (never ahead of it;
    # how far behind depends on the machine's load, so no lower bound on the rate).
    assert driver.latest_ns() > now + 50 * TICK_NS
    assert float(values_of(driver.sim_status())['real_time_factor']) < 1.2
    # The controller answers again: lock-step resumes at the stamp it answers.
    driver.diag.clear()
    current = driver.latest_ns()
    driver.send(current, np.zeros(12))               # may be stale by now: the sim then waits

    def lock_step():
        st = driver.sim_status()
        return st is not None and st.level == DiagnosticStatus.OK \
            and values_of(st)['mode'] == 'lock_step'

    assert probe.spin_until(lock_step, 5.0), launcher.logs()
    probe.spin_for(0.3)                              # the held state's republish: latest_ns
    held = driver.latest_ns()
    for k in range(1, 6):                            # each tick only when answered
        assert driver.step(np.zeros(12)) == held + k * TICK_NS, launcher.logs()
    assert 'controller back: lock_step' in sim.log()
    assert lock_step()


def test_push_tool_wrench_applied_at_its_stamp(launcher, probe):
    start_sim(launcher)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    push = launcher.start('push', args=['30', '-20', '10', '--duration', '0.02'])
    push.process.wait(20)
    assert push.process.returncode == 0, push.log()
    assert 'push: F = (30, -20, 10) N' in push.log()
    for _ in range(8):                               # t = 0 .. 0.032 s
        driver.step(np.zeros(12))
    assert probe.spin_until(lambda: len(driver.applied) >= 2, 5.0), launcher.logs()
    start, end = driver.applied[:2]
    assert stamp_to_ns(start.header.stamp) == 0
    assert (start.wrench.force.x, start.wrench.force.y, start.wrench.force.z) == (30, -20, 10)
    assert stamp_to_ns(end.header.stamp) == 5 * TICK_NS   # 0.02 s later, exactly
    assert (end.wrench.force.x, end.wrench.force.y, end.wrench.force.z) == (0, 0, 0)


def test_free_run_mode_real_time(launcher, probe):
    start_sim(launcher, lock_step=False, diagnostics_period=0.5)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    probe.spin_for(0.3)
    assert driver.latest_ns() == 0                   # no command yet: does not advance
    driver.send(0, np.zeros(12))                     # any stamp drives the free run
    probe.spin_for(1.5)
    for _ in range(3):
        driver.send(driver.latest_ns(), np.zeros(12))
        probe.spin_for(0.2)
    # ~2 s of real time: it advanced, paced by the wall clock (never ahead of it; how far
    # behind depends on the machine's load, so only a loose lower bound).
    assert driver.latest_ns() > 50 * TICK_NS
    status = driver.sim_status()
    assert values_of(status)['mode'] == 'free_run'
    assert float(values_of(status)['real_time_factor']) < 1.2


def test_noisy_sensors_are_seeded_and_drawn_once_per_tick(launcher, probe):
    """The realistic profile's sensors: noise on imu and joint_states, the truth untouched, a
    republished tick identical (noise is drawn once per tick), and the seed decides the draw."""
    noise = {'imu_gyro_noise_density': 1e-3, 'imu_accel_noise_density': 1e-3,
             'imu_gyro_initial_bias': 1e-3, 'joint_position_noise': 1e-3,
             'joint_velocity_noise': 1e-2, 'joint_torque_noise': 0.5}
    start_sim(launcher, noise_seed=7, **noise)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    assert probe.spin_until(lambda: len(driver.joints) >= 3 and len(driver.imu) >= 3, 5.0)
    first, again = driver.joints[0], driver.joints[-1]
    assert stamp_to_ns(first.header.stamp) == stamp_to_ns(again.header.stamp) == 0
    assert list(first.position) == list(again.position)          # a republish: the same draw
    imu = imu_from_msg(driver.imu[-1])
    assert 0.0 < abs(imu.linear_acceleration[2] - 9.81) < 0.1      # noisy, but an accelerometer
    truth_height = driver.odom[-1].pose.pose.position.z
    joints = joint_state_from_msg(first)
    launcher.stop_all()
    # The same seed again: the same samples at t = 0.
    start_sim(launcher, noise_seed=7, **noise)
    driver2 = Driver(probe)
    assert driver2.wait_ready(), launcher.logs()
    np.testing.assert_array_equal(joint_state_from_msg(driver2.joints[-1]).position,
                                  joints.position)
    assert driver2.odom[-1].pose.pose.position.z == truth_height
    assert driver2.imu[-1].angular_velocity_covariance[0] > 0.0


def test_default_qos_subscriber_receives_sensor_topics(launcher, probe):
    """REP-2003: sensor topics are published reliable, so a subscriber with the default QoS
    (depth 10, reliable: `ros2 topic echo`, RViz) is compatible and receives them."""
    start_sim(launcher)
    joints = probe.subscribe(JointState, 'joint_states', 10)
    imu = probe.subscribe(Imu, 'imu', 10)
    odom = probe.subscribe(Odometry, 'ground_truth/odom', 10)
    assert probe.spin_until(lambda: joints and imu and odom, 30.0), launcher.logs()
    for topic in ('/joint_states', '/imu', '/ground_truth/odom'):
        infos = probe.node.get_publishers_info_by_topic(topic)
        assert infos and all(i.qos_profile.reliability == qos.SENSOR_PUB.reliability
                             for i in infos), topic


def test_topic_without_reader_is_served_to_a_late_reader(launcher, probe):
    """The sim builds a tick's truth and imu messages only for topics someone reads; a reader
    that comes while the sim waits gets the samples of the current tick, stamped with it."""
    start_sim(launcher)
    joints = probe.subscribe(JointState, 'joint_states', qos.SENSOR)
    cmd_pub = probe.node.create_publisher(JointState, 'joint_torque_cmd', qos.COMMAND)
    assert probe.spin_until(lambda: joints and cmd_pub.get_subscription_count() > 0, 30.0), \
        launcher.logs()
    torques = np.zeros(12)
    for k in range(5):                       # ticks stepped with nobody on the other topics
        msg = torque_cmd_to_msg(0.0, torques)
        msg.header.stamp = ns_to_stamp(TICK_NS * k)
        cmd_pub.publish(msg)
        assert probe.spin_until(
            lambda k=k: TICK_NS * (k + 1) in {stamp_to_ns(m.header.stamp) for m in joints},
            5.0), launcher.logs()
    odom = probe.subscribe(Odometry, 'ground_truth/odom', qos.SENSOR)
    contacts = probe.subscribe(PointCloud2, 'ground_truth/contacts', qos.CONTACTS)
    imu = probe.subscribe(Imu, 'imu', qos.SENSOR)
    assert probe.spin_until(lambda: odom and contacts and imu, 5.0), launcher.logs()
    for msgs in (odom, contacts, imu):       # the republish of the tick the sim waits at
        assert {stamp_to_ns(m.header.stamp) for m in msgs} == {TICK_NS * 5}
    assert 0.55 < odom[-1].pose.pose.position.z < 0.62
    assert contacts_from_msg(contacts[-1]).foot_position.shape == (4, 3)


def test_a_second_graph_on_the_domain_stops_the_sim_with_one_line(launcher, probe):
    """Two graphs on one ROS domain mix their topics (two scenario runs started without their
    own ROS_DOMAIN_ID read each other's clocks and torques): a second /clock publisher stops
    the sim with one line naming the domain, instead of a run on mixed inputs."""
    sim = start_sim(launcher)
    driver = Driver(probe)
    assert driver.wait_ready(), launcher.logs()
    probe.spin_for(1.5)
    assert sim.alive, launcher.logs()            # its own /clock alone: no complaint
    probe.node.create_publisher(Clock, '/clock', qos.CLOCK)
    assert probe.spin_until(lambda: not sim.alive, 10.0), launcher.logs()
    assert sim.process.returncode == 3
    assert (f'another graph publishes /clock on ROS_DOMAIN_ID {launcher.domain_id} (1 other '
            'publisher(s))') in sim.log()
