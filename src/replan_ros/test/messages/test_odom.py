"""odom: the rclpy conversion (twist in the base frame, checks) and the hand-written CDR
against rclpy's serializer and decoder."""

from __future__ import annotations

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from wire_checks import STAMPS, same_bytes_as_rclpy, through_wire

from replan_core.common import rotations
from replan_core.common.rotations import yaw_of
from replan_core.common.types import BaseState, JointState
from replan_ros.messages.joint_state import joint_state_from_msg, joint_state_to_msg
from replan_ros.messages.odom import (
    base_state_from_cdr,
    base_state_from_odom,
    encode_odom,
    odom_from_base_state,
)
from replan_ros.messages.stamps import ns_to_stamp


def test_odom_twist_is_in_base_frame_and_round_trips():
    yaw = 0.7
    q = np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
    bs = BaseState(2.0, np.array([1.0, 2.0, 0.55]), q, np.array([0.3, 0.0, 0.0]),
                   np.array([0.0, 0.0, 0.2]))
    msg = odom_from_base_state(bs)
    assert msg.child_frame_id == 'base_link' and msg.header.frame_id == 'odom'
    # World velocity along +x seen from a base yawed by 0.7 rad.
    assert msg.twist.twist.linear.x == pytest.approx(0.3 * np.cos(yaw))
    assert msg.twist.twist.linear.y == pytest.approx(-0.3 * np.sin(yaw))
    back = base_state_from_odom(through_wire(msg))
    np.testing.assert_allclose(back.linear_velocity, bs.linear_velocity, atol=1e-12)
    np.testing.assert_allclose(back.angular_velocity, bs.angular_velocity, atol=1e-12)
    assert yaw_of(back.quaternion) == pytest.approx(yaw)


@pytest.mark.parametrize('t', STAMPS)
def test_odom_bytes_are_rclpys(t):
    rng = np.random.default_rng(6)
    base = BaseState(t, rng.normal(size=3), np.asarray(rotations.normalized(rng.normal(size=4))),
                     rng.normal(size=3), rng.normal(size=3))
    msg = odom_from_base_state(base)
    same_bytes_as_rclpy(encode_odom(base), msg, Odometry)
    msg.header.stamp = ns_to_stamp(777)
    same_bytes_as_rclpy(encode_odom(base, 777), msg, Odometry)


@pytest.mark.parametrize('t', STAMPS)
def test_odom_decodes_as_the_generic_decoder(t):
    rng = np.random.default_rng(8)
    base = BaseState(t, rng.normal(size=3), np.asarray(rotations.normalized(rng.normal(size=4))),
                     rng.normal(size=3), rng.normal(size=3))
    for data in (encode_odom(base), bytes(serialize_message(odom_from_base_state(base)))):
        stamp_ns, fast = base_state_from_cdr(data)
        msg = deserialize_message(data, Odometry)
        generic = base_state_from_odom(msg)
        assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert fast.stamp == generic.stamp
        for name in ('position', 'quaternion', 'linear_velocity', 'angular_velocity'):
            np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))
    framed = odom_from_base_state(base)
    framed.header.frame_id, framed.child_frame_id = 'map', 'trunk_of_the_robot'
    _, decoded = base_state_from_cdr(bytes(serialize_message(framed)))
    np.testing.assert_array_equal(decoded.position, base.position)
    bad = odom_from_base_state(base)
    bad.pose.pose.orientation.w = 5.0
    with pytest.raises(ValueError, match='not a unit quaternion'):
        base_state_from_cdr(bytes(serialize_message(bad)))
    with pytest.raises(ValueError, match='cannot deserialize'):
        base_state_from_cdr(encode_odom(base)[:60])


def test_non_finite_states_are_rejected_by_the_conversions():
    bs = BaseState(1.0, np.array([0.0, 0.0, 0.6]), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3),
                   np.zeros(3))
    msg = odom_from_base_state(bs)
    msg.twist.twist.linear.x = float('nan')
    with pytest.raises(ValueError, match='non-finite'):
        base_state_from_odom(msg)
    msg = odom_from_base_state(bs)
    msg.pose.pose.orientation.w = 0.0                 # all-zero quaternion
    with pytest.raises(ValueError, match='quaternion'):
        base_state_from_odom(msg)
    js = joint_state_to_msg(JointState(1.0, np.zeros(12), np.zeros(12), np.zeros(12)))
    js.velocity[5] = float('inf')
    with pytest.raises(ValueError, match='non-finite'):
        joint_state_from_msg(js)
