"""joint_states and joint_torque_cmd: the rclpy conversion (order by name, checks) and the
hand-written CDR against rclpy's serializer and decoder."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState as JointStateMsg
from wire_checks import STAMPS, same_bytes_as_rclpy, through_wire

from replan_core.common.types import JOINT_NAMES, JointState
from replan_ros.messages.joint_state import (
    JOINT_STATES,
    TORQUE_COMMAND,
    encode_joint_state,
    encode_torque_command,
    joint_state_from_cdr,
    joint_state_from_msg,
    joint_state_to_msg,
    torque_cmd_from_msg,
    torque_cmd_to_msg,
    torque_command_from_cdr,
)
from replan_ros.messages.stamps import ns_to_stamp


def test_joint_state_reorders_by_name_and_rejects_unknown():
    rng = np.random.default_rng(0)
    js = JointState(1.5, rng.normal(size=12), rng.normal(size=12), rng.normal(size=12))
    msg = joint_state_to_msg(js)
    order = rng.permutation(12)
    msg.name = [msg.name[i] for i in order]
    msg.position = [msg.position[i] for i in order]
    msg.velocity = [msg.velocity[i] for i in order]
    msg.effort = [msg.effort[i] for i in order]
    back = joint_state_from_msg(through_wire(msg))
    np.testing.assert_allclose(back.position, js.position)
    np.testing.assert_allclose(back.effort, js.effort)
    msg.name[0] = 'elbow_joint'
    with pytest.raises(ValueError, match='unknown joints'):
        joint_state_from_msg(msg)


def test_torque_command_rejects_nan_and_wrong_count():
    msg = torque_cmd_to_msg(0.004, np.arange(12.0))
    stamp_ns, tau = torque_cmd_from_msg(through_wire(msg))
    assert stamp_ns == 4_000_000
    np.testing.assert_array_equal(tau, np.arange(12.0))
    msg.effort[3] = float('nan')
    with pytest.raises(ValueError, match=JOINT_NAMES[3]):
        torque_cmd_from_msg(msg)
    short = torque_cmd_to_msg(0.0, np.zeros(11))
    short.name = short.name[:11]
    with pytest.raises(ValueError, match='11 joints'):
        torque_cmd_from_msg(short)


@pytest.mark.parametrize('t', STAMPS)
def test_joint_states_bytes_are_rclpys(t):
    rng = np.random.default_rng(1)
    js = JointState(t, rng.normal(size=12), rng.normal(size=12), rng.normal(size=12))
    same_bytes_as_rclpy(encode_joint_state(js), joint_state_to_msg(js),
                         JointStateMsg)


@pytest.mark.parametrize('t', STAMPS)
def test_joint_states_decode_as_the_generic_decoder(t):
    rng = np.random.default_rng(2)
    msg = joint_state_to_msg(JointState(t, rng.normal(size=12), rng.normal(size=12),
                                        rng.normal(size=12)))
    data = bytes(serialize_message(msg))
    assert JOINT_STATES.decode(data) is not None          # the fast path
    stamp_ns, fast = joint_state_from_cdr(data)
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
        assert JOINT_STATES.decode(data) is None
        _, decoded = joint_state_from_cdr(data)
        expected = joint_state_from_msg(msg)
        np.testing.assert_array_equal(decoded.position, expected.position)
        np.testing.assert_array_equal(decoded.effort, expected.effort)
    np.testing.assert_array_equal(joint_state_from_cdr(
        bytes(serialize_message(reordered)))[1].position, js.position)


def test_bad_joint_states_give_the_generic_errors():
    js = JointState(1.0, np.zeros(12), np.zeros(12), np.zeros(12))
    js.velocity[3] = math.nan
    data = encode_joint_state(js)
    with pytest.raises(ValueError, match='non-finite joint positions or velocities'):
        joint_state_from_cdr(data)
    short = joint_state_to_msg(js)
    short.name = short.name[:11]
    with pytest.raises(ValueError, match='11 joints, expected 12'):
        joint_state_from_cdr(bytes(serialize_message(short)))
    with pytest.raises(ValueError, match='cannot deserialize'):
        joint_state_from_cdr(data[:40])


@pytest.mark.parametrize('stamp_ns', [0, 4_000_000, 12_348_000_000, 1_234_567_891_234])
def test_torque_command_round_trip(stamp_ns):
    torques = np.random.default_rng(stamp_ns % 97).normal(scale=20, size=12)
    msg = torque_cmd_to_msg(stamp_ns * 1e-9, torques)
    msg.header.stamp = ns_to_stamp(stamp_ns)
    data = encode_torque_command(stamp_ns, torques)
    same_bytes_as_rclpy(data, msg, JointStateMsg)
    decoded_stamp, decoded = torque_command_from_cdr(data)
    assert decoded_stamp == stamp_ns
    np.testing.assert_array_equal(decoded, torque_cmd_from_msg(msg)[1])


def test_torque_commands_of_another_layout_or_bad_values():
    torques = np.arange(12.0)
    msg = torque_cmd_to_msg(2.0, torques)
    msg.name = list(reversed(msg.name))                 # reordered: the generic decoder
    data = bytes(serialize_message(msg))
    assert TORQUE_COMMAND.decode(data) is None
    np.testing.assert_array_equal(torque_command_from_cdr(data)[1], torques[::-1])
    bad = torques.copy()
    bad[5] = math.inf
    with pytest.raises(ValueError, match=f"non-finite effort for \\['{JOINT_NAMES[5]}'\\]"):
        torque_command_from_cdr(encode_torque_command(2_000_000_000, bad))
    few = torque_cmd_to_msg(2.0, torques)
    few.effort = few.effort[:6]
    with pytest.raises(ValueError, match='6 values for 12 names'):
        torque_command_from_cdr(bytes(serialize_message(few)))


def test_huge_but_finite_values_are_accepted():
    # Their sum overflows; the check must not call them non-finite.
    js = JointState(1.0, np.full(12, 1e308), np.full(12, 1e308), np.zeros(12))
    _, decoded = joint_state_from_cdr(encode_joint_state(js))
    np.testing.assert_array_equal(decoded.position, js.position)
    _, torques = torque_command_from_cdr(
        encode_torque_command(0, np.full(12, -1e308)))
    np.testing.assert_array_equal(torques, np.full(12, -1e308))
