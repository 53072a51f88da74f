"""The per-tick messages' hand-written CDR against rclpy's serializer: rclpy decodes our bytes
into the very message ``interfaces`` builds, and they are rclpy's bytes but for the padding
(rclpy does not zero it; ours is zero) and some bytes rclpy leaves after empty sequences; our
decoders give what the generic ones give, or defer to them for any other layout."""

from __future__ import annotations

import math

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, PointCloud2
from sensor_msgs.msg import JointState as JointStateMsg

from replan_core import rotations
from replan_core.types import JOINT_NAMES, BaseState, ContactState, ImuReading, JointState
from replan_ros.messages import tick_cdr
from replan_ros.messages.interfaces import (
    base_state_from_odom,
    contact_events_to_msg,
    contact_rows,
    contacts_from_msg,
    contacts_to_msg,
    imu_from_msg,
    imu_to_msg,
    joint_state_from_msg,
    joint_state_to_msg,
    ns_to_stamp,
    odom_from_base_state,
    torque_cmd_from_msg,
    torque_cmd_to_msg,
)

STAMPS = [0.0, 0.004, 12.348, 1234.567891234]


def _same_bytes_as_rclpy(data: bytes, msg, msg_type) -> None:
    theirs = bytes(serialize_message(msg))
    assert len(theirs) - 8 <= len(data) <= len(theirs)
    assert all(ours in (their, 0) for ours, their in zip(data, theirs, strict=False))
    assert deserialize_message(data, msg_type) == msg


@pytest.mark.parametrize('t', STAMPS)
def test_joint_states_bytes_are_rclpys(t):
    rng = np.random.default_rng(1)
    js = JointState(t, rng.normal(size=12), rng.normal(size=12), rng.normal(size=12))
    _same_bytes_as_rclpy(tick_cdr.encode_joint_state(js), joint_state_to_msg(js),
                         JointStateMsg)


@pytest.mark.parametrize('t', STAMPS)
def test_joint_states_decode_as_the_generic_decoder(t):
    rng = np.random.default_rng(2)
    msg = joint_state_to_msg(JointState(t, rng.normal(size=12), rng.normal(size=12),
                                        rng.normal(size=12)))
    data = bytes(serialize_message(msg))
    assert tick_cdr.JOINT_STATES.decode(data) is not None          # the fast path
    stamp_ns, fast = tick_cdr.joint_state_from_cdr(data)
    generic = joint_state_from_msg(msg)
    assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    assert fast.stamp == generic.stamp
    for name in ('position', 'velocity', 'effort'):
        np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))


def test_joint_states_of_another_layout_go_to_the_generic_decoder():
    rng = np.random.default_rng(3)
    js = JointState(1.0, rng.normal(size=12), rng.normal(size=12), rng.normal(size=12))
    reordered = joint_state_to_msg(js)
    order = list(reversed(range(12)))
    reordered.name = [JOINT_NAMES[i] for i in order]
    reordered.position = [js.position[i] for i in order]
    reordered.velocity = [js.velocity[i] for i in order]
    reordered.effort = [js.effort[i] for i in order]
    no_effort = joint_state_to_msg(js)
    no_effort.effort = []
    framed = joint_state_to_msg(js)
    framed.header.frame_id = 'base_link'
    for msg in (reordered, no_effort, framed):
        data = bytes(serialize_message(msg))
        assert tick_cdr.JOINT_STATES.decode(data) is None
        _, decoded = tick_cdr.joint_state_from_cdr(data)
        expected = joint_state_from_msg(msg)
        np.testing.assert_array_equal(decoded.position, expected.position)
        np.testing.assert_array_equal(decoded.effort, expected.effort)
    np.testing.assert_array_equal(tick_cdr.joint_state_from_cdr(
        bytes(serialize_message(reordered)))[1].position, js.position)


def test_bad_joint_states_give_the_generic_errors():
    js = JointState(1.0, np.zeros(12), np.zeros(12), np.zeros(12))
    js.velocity[3] = math.nan
    data = tick_cdr.encode_joint_state(js)
    with pytest.raises(ValueError, match='non-finite joint positions or velocities'):
        tick_cdr.joint_state_from_cdr(data)
    short = joint_state_to_msg(js)
    short.name = short.name[:11]
    with pytest.raises(ValueError, match='11 joints, expected 12'):
        tick_cdr.joint_state_from_cdr(bytes(serialize_message(short)))
    with pytest.raises(ValueError, match='cannot deserialize'):
        tick_cdr.joint_state_from_cdr(data[:40])


@pytest.mark.parametrize('stamp_ns', [0, 4_000_000, 12_348_000_000, 1_234_567_891_234])
def test_torque_command_round_trip(stamp_ns):
    torques = np.random.default_rng(stamp_ns % 97).normal(scale=20, size=12)
    msg = torque_cmd_to_msg(stamp_ns * 1e-9, torques)
    msg.header.stamp = ns_to_stamp(stamp_ns)
    data = tick_cdr.encode_torque_command(stamp_ns, torques)
    _same_bytes_as_rclpy(data, msg, JointStateMsg)
    decoded_stamp, decoded = tick_cdr.torque_command_from_cdr(data)
    assert decoded_stamp == stamp_ns
    np.testing.assert_array_equal(decoded, torque_cmd_from_msg(msg)[1])


def test_torque_commands_of_another_layout_or_bad_values():
    torques = np.arange(12.0)
    msg = torque_cmd_to_msg(2.0, torques)
    msg.name = list(reversed(msg.name))                 # reordered: the generic decoder
    data = bytes(serialize_message(msg))
    assert tick_cdr.TORQUE_COMMAND.decode(data) is None
    np.testing.assert_array_equal(tick_cdr.torque_command_from_cdr(data)[1], torques[::-1])
    bad = torques.copy()
    bad[5] = math.inf
    with pytest.raises(ValueError, match=f"non-finite effort for \\['{JOINT_NAMES[5]}'\\]"):
        tick_cdr.torque_command_from_cdr(tick_cdr.encode_torque_command(2_000_000_000, bad))
    few = torque_cmd_to_msg(2.0, torques)
    few.effort = few.effort[:6]
    with pytest.raises(ValueError, match='6 values for 12 names'):
        tick_cdr.torque_command_from_cdr(bytes(serialize_message(few)))


@pytest.mark.parametrize('t', STAMPS)
def test_imu_round_trip(t):
    rng = np.random.default_rng(5)
    reading = ImuReading(t, rng.normal(size=3), rng.normal(size=3) + np.array([0, 0, 9.81]))
    msg = imu_to_msg(reading, 1e-4, 2e-3)
    data = tick_cdr.encode_imu(reading, 1e-4, 2e-3)
    _same_bytes_as_rclpy(data, msg, Imu)
    assert msg.orientation_covariance[0] == -1.0 and msg.orientation.w == 1.0
    stamp_ns, decoded = tick_cdr.imu_from_cdr(data)
    expected = imu_from_msg(msg)
    assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    assert decoded.stamp == expected.stamp
    np.testing.assert_array_equal(decoded.angular_velocity, expected.angular_velocity)
    np.testing.assert_array_equal(decoded.linear_acceleration, expected.linear_acceleration)


@pytest.mark.parametrize('frame_id', ['', 'imu_link', 'a_much_longer_imu_frame'])
def test_imu_of_any_frame_decodes(frame_id):
    reading = ImuReading(3.0, np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 9.0]))
    msg = imu_to_msg(reading)
    msg.header.frame_id = frame_id
    _, decoded = tick_cdr.imu_from_cdr(bytes(serialize_message(msg)))
    np.testing.assert_array_equal(decoded.angular_velocity, reading.angular_velocity)
    np.testing.assert_array_equal(decoded.linear_acceleration, reading.linear_acceleration)


def test_bad_imu():
    reading = ImuReading(3.0, np.array([0.1, math.nan, 0.3]), np.array([1.0, 2.0, 9.0]))
    with pytest.raises(ValueError, match='imu: non-finite'):
        tick_cdr.imu_from_cdr(tick_cdr.encode_imu(reading))
    with pytest.raises(ValueError, match='cannot deserialize'):
        tick_cdr.imu_from_cdr(tick_cdr.encode_imu(
            ImuReading(3.0, np.zeros(3), np.zeros(3)))[:100])


@pytest.mark.parametrize('t', STAMPS)
def test_odom_bytes_are_rclpys(t):
    rng = np.random.default_rng(6)
    base = BaseState(t, rng.normal(size=3), np.asarray(rotations.normalized(rng.normal(size=4))),
                     rng.normal(size=3), rng.normal(size=3))
    msg = odom_from_base_state(base)
    _same_bytes_as_rclpy(tick_cdr.encode_odom(base), msg, Odometry)
    msg.header.stamp = ns_to_stamp(777)
    _same_bytes_as_rclpy(tick_cdr.encode_odom(base, 777), msg, Odometry)


def _contacts(t: float, touchdown, liftoff) -> ContactState:
    rng = np.random.default_rng(7)
    return ContactState(t, rng.normal(size=(4, 3)), rng.normal(size=(4, 3)),
                        np.array([True, False, True, True]), np.array(touchdown),
                        np.array(liftoff))


@pytest.mark.parametrize('t', STAMPS)
def test_contact_tables_are_rclpys(t):
    cs = _contacts(t, [False, True, False, False], [False, False, False, True])
    _same_bytes_as_rclpy(tick_cdr.encode_contacts(cs), contacts_to_msg(cs), PointCloud2)
    _same_bytes_as_rclpy(tick_cdr.encode_contact_events(cs), contact_events_to_msg(cs),
                         PointCloud2)
    msg = contacts_to_msg(cs)
    msg.header.stamp = ns_to_stamp(123)
    _same_bytes_as_rclpy(tick_cdr.encode_contacts(cs, 123), msg, PointCloud2)
    quiet = _contacts(t, [False] * 4, [False] * 4)
    assert tick_cdr.encode_contact_events(quiet) is None
    one = _contacts(t, [True, False, False, False], [False] * 4)
    _same_bytes_as_rclpy(tick_cdr.encode_contact_events(one), contact_events_to_msg(one),
                         PointCloud2)


def test_huge_but_finite_values_are_accepted():
    # Their sum overflows; the check must not call them non-finite.
    js = JointState(1.0, np.full(12, 1e308), np.full(12, 1e308), np.zeros(12))
    _, decoded = tick_cdr.joint_state_from_cdr(tick_cdr.encode_joint_state(js))
    np.testing.assert_array_equal(decoded.position, js.position)
    _, torques = tick_cdr.torque_command_from_cdr(
        tick_cdr.encode_torque_command(0, np.full(12, -1e308)))
    np.testing.assert_array_equal(torques, np.full(12, -1e308))


@pytest.mark.parametrize('t', STAMPS)
def test_odom_decodes_as_the_generic_decoder(t):
    rng = np.random.default_rng(8)
    base = BaseState(t, rng.normal(size=3), np.asarray(rotations.normalized(rng.normal(size=4))),
                     rng.normal(size=3), rng.normal(size=3))
    for data in (tick_cdr.encode_odom(base), bytes(serialize_message(odom_from_base_state(base)))):
        stamp_ns, fast = tick_cdr.base_state_from_cdr(data)
        msg = deserialize_message(data, Odometry)
        generic = base_state_from_odom(msg)
        assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert fast.stamp == generic.stamp
        for name in ('position', 'quaternion', 'linear_velocity', 'angular_velocity'):
            np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))
    framed = odom_from_base_state(base)
    framed.header.frame_id, framed.child_frame_id = 'map', 'trunk_of_the_robot'
    _, decoded = tick_cdr.base_state_from_cdr(bytes(serialize_message(framed)))
    np.testing.assert_array_equal(decoded.position, base.position)
    bad = odom_from_base_state(base)
    bad.pose.pose.orientation.w = 5.0
    with pytest.raises(ValueError, match='not a unit quaternion'):
        tick_cdr.base_state_from_cdr(bytes(serialize_message(bad)))
    with pytest.raises(ValueError, match='cannot deserialize'):
        tick_cdr.base_state_from_cdr(tick_cdr.encode_odom(base)[:60])


@pytest.mark.parametrize('t', STAMPS)
def test_contacts_decode_as_the_generic_decoder(t):
    cs = _contacts(t, [False, True, False, False], [False, False, False, True])
    for data in (tick_cdr.encode_contacts(cs), bytes(serialize_message(contacts_to_msg(cs)))):
        stamp_ns, fast = tick_cdr.contacts_from_cdr(data)
        msg = deserialize_message(data, PointCloud2)
        generic = contacts_from_msg(msg)
        assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert fast.stamp == generic.stamp
        for name in ('foot_position', 'force', 'contact', 'touchdown', 'liftoff'):
            np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))
            assert getattr(fast, name).dtype == getattr(generic, name).dtype
    # Rows out of leg order (not ours, still a valid table): sorted as the generic decoder.
    shuffled = tick_cdr._encode_table(round(t * 1e9), contact_rows(cs, np.array([2, 0, 3, 1])))
    _, fast = tick_cdr.contacts_from_cdr(shuffled)
    generic = contacts_from_msg(deserialize_message(shuffled, PointCloud2))
    for name in ('foot_position', 'force', 'contact', 'touchdown', 'liftoff'):
        np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))
    np.testing.assert_array_equal(fast.foot_position, cs.foot_position)
    events = tick_cdr.encode_contact_events(cs)       # two rows: not a contacts table
    with pytest.raises(ValueError, match='one row per leg'):
        tick_cdr.contacts_from_cdr(events)
    bad = _contacts(t, [False] * 4, [False] * 4)
    bad.force[2, 1] = math.nan
    with pytest.raises(ValueError, match='non-finite fy'):
        tick_cdr.contacts_from_cdr(tick_cdr.encode_contacts(bad))
    with pytest.raises(ValueError, match='cannot deserialize'):
        tick_cdr.contacts_from_cdr(tick_cdr.encode_contacts(cs)[:50])
