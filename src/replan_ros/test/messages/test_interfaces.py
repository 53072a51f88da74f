"""Round trips of every message encoding of docs/ARCHITECTURE.md."""

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2

from replan_core.rotations import yaw_of
from replan_core.types import (
    JOINT_NAMES,
    BaseState,
    ComPlan,
    ContactState,
    FootholdPlan,
    ImuReading,
    JointState,
    Step,
)
from replan_ros.messages import interfaces as itf
from replan_ros.messages.tick_cdr import encode_imu, imu_from_cdr


def _through_wire(msg):
    return deserialize_message(serialize_message(msg), type(msg))


def test_stamp_round_trip_is_exact_in_ns():
    for t in (0.0, 0.004, 12.348, 1234.5678):
        assert itf.stamp_to_ns(itf.sec_to_stamp(t)) == round(t * 1e9)


def test_ns_to_sec_is_the_float_the_decoders_give():
    """The wbc prepares the estimator's next step for ns_to_sec(next stamp) and the estimator
    uses it only for an equal float: the decoders must give exactly that float."""
    for tick in (0, 1, 3, 250, 5517, 123_457, 10_000_001):
        ns = tick * 4_000_000
        t = itf.ns_to_sec(ns)
        assert t == itf.stamp_to_sec(itf.ns_to_stamp(ns))
        reading = ImuReading(tick * 0.004, np.zeros(3), np.array([0.0, 0.0, 9.81]))
        decoded_ns, decoded = imu_from_cdr(encode_imu(reading))
        assert decoded_ns == ns and decoded.stamp == t


def test_joint_state_reorders_by_name_and_rejects_unknown():
    rng = np.random.default_rng(0)
    js = JointState(1.5, rng.normal(size=12), rng.normal(size=12), rng.normal(size=12))
    msg = itf.joint_state_to_msg(js)
    order = rng.permutation(12)
    msg.name = [msg.name[i] for i in order]
    msg.position = [msg.position[i] for i in order]
    msg.velocity = [msg.velocity[i] for i in order]
    msg.effort = [msg.effort[i] for i in order]
    back = itf.joint_state_from_msg(_through_wire(msg))
    np.testing.assert_allclose(back.position, js.position)
    np.testing.assert_allclose(back.effort, js.effort)
    msg.name[0] = 'elbow_joint'
    with pytest.raises(ValueError, match='unknown joints'):
        itf.joint_state_from_msg(msg)


def test_torque_command_rejects_nan_and_wrong_count():
    msg = itf.torque_cmd_to_msg(0.004, np.arange(12.0))
    stamp_ns, tau = itf.torque_cmd_from_msg(_through_wire(msg))
    assert stamp_ns == 4_000_000
    np.testing.assert_array_equal(tau, np.arange(12.0))
    msg.effort[3] = float('nan')
    with pytest.raises(ValueError, match=JOINT_NAMES[3]):
        itf.torque_cmd_from_msg(msg)
    short = itf.torque_cmd_to_msg(0.0, np.zeros(11))
    short.name = short.name[:11]
    with pytest.raises(ValueError, match='11 joints'):
        itf.torque_cmd_from_msg(short)


def test_odom_twist_is_in_base_frame_and_round_trips():
    yaw = 0.7
    q = np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
    bs = BaseState(2.0, np.array([1.0, 2.0, 0.55]), q, np.array([0.3, 0.0, 0.0]),
                   np.array([0.0, 0.0, 0.2]))
    msg = itf.odom_from_base_state(bs)
    assert msg.child_frame_id == 'base_link' and msg.header.frame_id == 'odom'
    # World velocity along +x seen from a base yawed by 0.7 rad.
    assert msg.twist.twist.linear.x == pytest.approx(0.3 * np.cos(yaw))
    assert msg.twist.twist.linear.y == pytest.approx(-0.3 * np.sin(yaw))
    back = itf.base_state_from_odom(_through_wire(msg))
    np.testing.assert_allclose(back.linear_velocity, bs.linear_velocity, atol=1e-12)
    np.testing.assert_allclose(back.angular_velocity, bs.angular_velocity, atol=1e-12)
    assert yaw_of(back.quaternion) == pytest.approx(yaw)


def _contacts():
    rng = np.random.default_rng(1)
    return ContactState(0.5, rng.normal(size=(4, 3)), rng.normal(size=(4, 3)),
                        np.array([True, True, False, True]),
                        np.array([False, True, False, False]),
                        np.array([False, False, True, False]))


def test_contacts_table_round_trip_and_events():
    cs = _contacts()
    msg = _through_wire(itf.contacts_to_msg(cs))
    assert isinstance(msg, PointCloud2) and msg.width == 4
    assert [f.name for f in msg.fields][:3] == ['x', 'y', 'z']
    back = itf.contacts_from_msg(msg)
    np.testing.assert_array_equal(back.foot_position, cs.foot_position)
    np.testing.assert_array_equal(back.force, cs.force)
    np.testing.assert_array_equal(back.contact, cs.contact)
    events = itf.contact_events_from_msg(itf.contact_events_to_msg(cs))
    assert [(leg, kind) for leg, kind, _, _ in events] == [(1, 'touchdown'), (2, 'liftoff')]
    cs.touchdown[:] = False
    cs.liftoff[:] = False
    assert itf.contact_events_to_msg(cs) is None


def test_footholds_round_trip():
    feet = np.array([[0.37, 0.3, 0.0], [0.37, -0.3, 0.0], [-0.37, 0.3, 0.0], [-0.37, -0.3, 0.0]])
    steps = [Step(leg, 10.2 + i, 10.7 + i, feet[leg] + [0.1, 0, 0], 0.1, i % 2 == 0, i == 0,
                  0.05 * i) for i, leg in enumerate([2, 0, 3, 1])]
    plan = FootholdPlan(10.0, feet, 0.0, steps, min_swing_fraction=0.4, max_extension=0.25)
    back = itf.footholds_from_msg(_through_wire(itf.footholds_to_msg(plan)))
    assert (back.min_swing_fraction, back.max_extension) == (0.4, 0.25)
    assert back.start_time == pytest.approx(10.0)
    np.testing.assert_array_equal(back.initial_feet, feet)
    assert [s.leg for s in back.steps] == [2, 0, 3, 1]
    for a, b in zip(back.steps, steps, strict=True):
        assert a.liftoff_time == pytest.approx(b.liftoff_time, abs=1e-12)
        assert a.touchdown_time == pytest.approx(b.touchdown_time, abs=1e-12)
        assert (a.haptic, a.replan) == (b.haptic, b.replan)
        np.testing.assert_array_equal(a.target, b.target)


def test_com_plan_round_trip_and_exact_sampling():
    dt, n = 0.04, 50
    rng = np.random.default_rng(2)
    jerk = rng.normal(size=(n, 3))
    pos, vel, acc = np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros((n + 1, 3))
    for k in range(n):  # eq. (2)
        acc[k + 1] = acc[k] + jerk[k] * dt
        vel[k + 1] = vel[k] + acc[k] * dt + jerk[k] * dt**2 / 2
        pos[k + 1] = pos[k] + vel[k] * dt + acc[k] * dt**2 / 2 + jerk[k] * dt**3 / 6
    plan = ComPlan(3.0, dt, pos, vel, acc)
    back = itf.com_plan_from_msg(_through_wire(itf.com_plan_to_msg(plan)))
    np.testing.assert_allclose(back.position, pos)
    # Half-way through interval 7, integrated analytically from sample 7.
    s = dt / 2
    p, _, a = back.sample(3.0 + 7 * dt + s)
    np.testing.assert_allclose(a, acc[7] + jerk[7] * s, atol=1e-9)
    np.testing.assert_allclose(p, pos[7] + vel[7] * s + acc[7] * s**2 / 2 + jerk[7] * s**3 / 6,
                               atol=1e-9)
    np.testing.assert_allclose(back.sample(3.0 + 8 * dt)[0], pos[8], atol=1e-9)


def test_non_finite_states_are_rejected_by_the_conversions():
    bs = BaseState(1.0, np.array([0.0, 0.0, 0.6]), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3),
                   np.zeros(3))
    msg = itf.odom_from_base_state(bs)
    msg.twist.twist.linear.x = float('nan')
    with pytest.raises(ValueError, match='non-finite'):
        itf.base_state_from_odom(msg)
    msg = itf.odom_from_base_state(bs)
    msg.pose.pose.orientation.w = 0.0                 # all-zero quaternion
    with pytest.raises(ValueError, match='quaternion'):
        itf.base_state_from_odom(msg)
    js = itf.joint_state_to_msg(JointState(1.0, np.zeros(12), np.zeros(12), np.zeros(12)))
    js.velocity[5] = float('inf')
    with pytest.raises(ValueError, match='non-finite'):
        itf.joint_state_from_msg(js)
