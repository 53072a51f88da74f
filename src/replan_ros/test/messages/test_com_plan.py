"""com_plan: round trip, exact sampling, and the hand-written CDR against rclpy's serializer
and decoder (and what it declines)."""

from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory
from wire_checks import through_wire

from replan_core.common.types import ComPlan
from replan_ros.messages.com_plan import (
    com_plan_from_msg,
    com_plan_to_msg,
    decode_com_plan,
    encode_com_plan,
)
from replan_ros.messages.stamps import sec_to_stamp, stamp_to_ns


def _plan(rng, n: int, start: float, dt: float) -> ComPlan:
    return ComPlan(start, dt, rng.normal(size=(n + 1, 3)), rng.normal(size=(n + 1, 3)),
                   rng.normal(size=(n + 1, 3)))


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
    back = com_plan_from_msg(through_wire(com_plan_to_msg(plan)))
    np.testing.assert_allclose(back.position, pos)
    # Half-way through interval 7, integrated analytically from sample 7.
    s = dt / 2
    p, _, a = back.sample(3.0 + 7 * dt + s)
    np.testing.assert_allclose(a, acc[7] + jerk[7] * s, atol=1e-9)
    np.testing.assert_allclose(p, pos[7] + vel[7] * s + acc[7] * s**2 / 2 + jerk[7] * s**3 / 6,
                               atol=1e-9)
    np.testing.assert_allclose(back.sample(3.0 + 8 * dt)[0], pos[8], atol=1e-9)


@pytest.mark.parametrize('frame_id', ['odom', 'map', 'a_longer_frame', ''])
@pytest.mark.parametrize('n', [1, 2, 200])
def test_com_plan_bytes_are_rclpys(frame_id, n):
    rng = np.random.default_rng(n)
    plan = _plan(rng, n, 12.348, 0.04)
    stamp = sec_to_stamp(12.348)
    msg = com_plan_to_msg(plan)
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    data = encode_com_plan(plan, stamp_to_ns(stamp), frame_id)
    assert len(data) == len(serialize_message(msg))
    assert deserialize_message(data, MultiDOFJointTrajectory) == msg


@pytest.mark.parametrize('frame_id', ['odom', 'abc', ''])
def test_com_plan_decodes_as_the_generic_decoder(frame_id):
    rng = np.random.default_rng(3)
    plan = _plan(rng, 200, 7.123456789, 0.04)
    msg = com_plan_to_msg(plan)
    msg.header.frame_id = frame_id
    data = bytes(serialize_message(msg))
    stamp_ns, fast = decode_com_plan(data)
    generic = com_plan_from_msg(deserialize_message(data, MultiDOFJointTrajectory))
    assert stamp_ns == stamp_to_ns(msg.header.stamp)
    assert fast.start_time == generic.start_time and fast.dt == generic.dt
    for name in ('position', 'velocity', 'acceleration'):
        np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))


def test_com_plan_decoder_declines_what_it_does_not_expect():
    rng = np.random.default_rng(4)
    msg = com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))
    msg.points[3].velocities = []                   # a point without a velocity
    assert decode_com_plan(bytes(serialize_message(msg))) is None
    msg = com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))
    msg.joint_names = ['base']
    assert decode_com_plan(bytes(serialize_message(msg))) is None
    data = bytes(serialize_message(com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))))
    assert decode_com_plan(data[:-30]) is None                 # truncated
    assert decode_com_plan(b'\x00\x00' + data[2:]) is None     # big endian
    assert decode_com_plan(b'') is None


def test_com_plan_decoder_rejects_bad_values_as_the_generic_one():
    rng = np.random.default_rng(5)
    plan = _plan(rng, 10, 1.0, 0.04)
    plan.position[4, 1] = np.nan
    data = encode_com_plan(plan, 1_000_000_000, 'odom')
    with pytest.raises(ValueError, match='non-finite'):
        decode_com_plan(data)
    with pytest.raises(ValueError, match='non-finite'):
        com_plan_from_msg(deserialize_message(data, MultiDOFJointTrajectory))
    msg = com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))
    msg.points[5].time_from_start.nanosec += 1_000_000                # uneven samples
    with pytest.raises(ValueError, match='evenly spaced'):
        decode_com_plan(bytes(serialize_message(msg)))
