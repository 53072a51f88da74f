"""The hand-written plan CDR against rclpy's serializer: the same layout (rclpy deserializes our
bytes into the very message it serialized; its padding bytes are not zeroed, so the bytes are
compared by size), the same plans."""

from __future__ import annotations

import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.serialization import deserialize_message, serialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_core.types import ComPlan
from replan_ros.messages import cdr
from replan_ros.messages.interfaces import (
    com_plan_from_msg,
    com_plan_to_msg,
    path_msg,
    sec_to_stamp,
    stamp_to_ns,
)


def _plan(rng, n: int, start: float, dt: float) -> ComPlan:
    return ComPlan(start, dt, rng.normal(size=(n + 1, 3)), rng.normal(size=(n + 1, 3)),
                   rng.normal(size=(n + 1, 3)))


@pytest.mark.parametrize('frame_id', ['odom', 'map', 'a_longer_frame', ''])
@pytest.mark.parametrize('n', [1, 2, 200])
def test_com_plan_bytes_are_rclpys(frame_id, n):
    rng = np.random.default_rng(n)
    plan = _plan(rng, n, 12.348, 0.04)
    stamp = sec_to_stamp(12.348)
    msg = com_plan_to_msg(plan)
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    data = cdr.encode_com_plan(plan, stamp_to_ns(stamp), frame_id)
    assert len(data) == len(serialize_message(msg))
    assert deserialize_message(data, MultiDOFJointTrajectory) == msg


@pytest.mark.parametrize('frame_id', ['odom', 'abc', ''])
def test_com_plan_decodes_as_the_generic_decoder(frame_id):
    rng = np.random.default_rng(3)
    plan = _plan(rng, 200, 7.123456789, 0.04)
    msg = com_plan_to_msg(plan)
    msg.header.frame_id = frame_id
    data = bytes(serialize_message(msg))
    stamp_ns, fast = cdr.decode_com_plan(data)
    generic = com_plan_from_msg(deserialize_message(data, MultiDOFJointTrajectory))
    assert stamp_ns == stamp_to_ns(msg.header.stamp)
    assert fast.start_time == generic.start_time and fast.dt == generic.dt
    for name in ('position', 'velocity', 'acceleration'):
        np.testing.assert_array_equal(getattr(fast, name), getattr(generic, name))


def test_com_plan_decoder_declines_what_it_does_not_expect():
    rng = np.random.default_rng(4)
    msg = com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))
    msg.points[3].velocities = []                   # a point without a velocity
    assert cdr.decode_com_plan(bytes(serialize_message(msg))) is None
    msg = com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))
    msg.joint_names = ['base']
    assert cdr.decode_com_plan(bytes(serialize_message(msg))) is None
    data = bytes(serialize_message(com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))))
    assert cdr.decode_com_plan(data[:-30]) is None                 # truncated
    assert cdr.decode_com_plan(b'\x00\x00' + data[2:]) is None     # big endian
    assert cdr.decode_com_plan(b'') is None


def test_com_plan_decoder_rejects_bad_values_as_the_generic_one():
    rng = np.random.default_rng(5)
    plan = _plan(rng, 10, 1.0, 0.04)
    plan.position[4, 1] = np.nan
    data = cdr.encode_com_plan(plan, 1_000_000_000, 'odom')
    with pytest.raises(ValueError, match='non-finite'):
        cdr.decode_com_plan(data)
    with pytest.raises(ValueError, match='non-finite'):
        com_plan_from_msg(deserialize_message(data, MultiDOFJointTrajectory))
    msg = com_plan_to_msg(_plan(rng, 10, 1.0, 0.04))
    msg.points[5].time_from_start.nanosec += 1_000_000                # uneven samples
    with pytest.raises(ValueError, match='evenly spaced'):
        cdr.decode_com_plan(bytes(serialize_message(msg)))


@pytest.mark.parametrize('frame_id', ['odom', 'abcdefg', ''])
@pytest.mark.parametrize('width', [2, 3])
def test_path_bytes_are_rclpys(frame_id, width):
    rng = np.random.default_rng(width)
    points = rng.normal(size=(201, width))
    start = 3.3300000001
    msg = path_msg(start, 0.04, points, frame_id)
    msg.header.stamp = sec_to_stamp(start)
    data = cdr.encode_path(stamp_to_ns(msg.header.stamp), start, 0.04, points, frame_id)
    assert len(data) == len(serialize_message(msg))
    assert deserialize_message(data, Path) == msg


def test_bench_msgs_times_every_operation(capsys):
    from replan_ros.benchmarks import bench_msgs

    results = bench_msgs.measure(repeats=3)
    assert len(results) == 6 + 20 + 2      # plans; ticks: 10 operations, two ways each; view
    assert all(0.0 < median <= p90 for median, p90 in results.values())
    assert bench_msgs.main(['--repeats', '2', '--json']) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith('operation') and len(out) == 2 + len(results)
