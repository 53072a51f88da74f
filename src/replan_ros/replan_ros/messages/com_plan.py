"""com_plan: a ComPlan as trajectory_msgs/MultiDOFJointTrajectory, as an rclpy message and as hand-
written CDR (the re-plan path).

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import struct

import numpy as np
from geometry_msgs.msg import Quaternion, Transform, Twist, Vector3
from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from replan_core.common.types import ComPlan
from replan_ros.messages.cdr import NS, CdrReader, CdrWriter
from replan_ros.messages.stamps import (
    duration_to_sec,
    header,
    sec_to_duration,
    stamp_to_ns,
    stamp_to_sec,
)


def _vec(v: np.ndarray) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def com_plan_to_msg(plan: ComPlan) -> MultiDOFJointTrajectory:
    msg = MultiDOFJointTrajectory()
    msg.header = header(plan.start_time)
    msg.joint_names = ['com']
    for k in range(len(plan.position)):
        p = plan.position[k]
        point = MultiDOFJointTrajectoryPoint()
        point.transforms = [Transform(translation=_vec(p),
                                      rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))]
        point.velocities = [Twist(linear=_vec(plan.velocity[k]))]
        point.accelerations = [Twist(linear=_vec(plan.acceleration[k]))]
        point.time_from_start = sec_to_duration(k * plan.dt)
        msg.points.append(point)
    return msg


def com_plan_from_msg(msg: MultiDOFJointTrajectory) -> ComPlan:
    if list(msg.joint_names) != ['com'] or len(msg.points) < 2:
        raise ValueError('com_plan must have joint_names ["com"] and at least two points')
    def xyz(v):
        return (v.x, v.y, v.z)
    pos = np.array([xyz(pt.transforms[0].translation) for pt in msg.points])
    vel = np.array([xyz(pt.velocities[0].linear) for pt in msg.points])
    acc = np.array([xyz(pt.accelerations[0].linear) for pt in msg.points])
    times = np.array([duration_to_sec(pt.time_from_start) for pt in msg.points])
    return com_plan_from_arrays(stamp_to_sec(msg.header.stamp), times, pos, vel, acc)


def com_plan_from_arrays(start_time: float, times: np.ndarray, position: np.ndarray,
                         velocity: np.ndarray, acceleration: np.ndarray) -> ComPlan:
    """A ``com_plan``'s samples (``times`` from its start, s) checked: evenly spaced and
    finite (``ValueError`` otherwise). Shared by both decoders (rclpy's and the hand-written
    one)."""
    dt = float(times[1] - times[0])
    if dt <= 0 or not np.allclose(np.diff(times), dt, atol=1e-6):
        raise ValueError('com_plan samples must be evenly spaced')
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(velocity))
            and np.all(np.isfinite(acceleration))):
        raise ValueError('com_plan holds non-finite values')
    return ComPlan(start_time=start_time, dt=dt, position=position, velocity=velocity,
                   acceleration=acceleration)


# One MultiDOFJointTrajectoryPoint with one transform, one velocity, one acceleration: its
# doubles are 8-aligned, so its layout depends on its start offset modulo 8 (4 or 0).
_POINT_AT_4 = struct.Struct('<I7dI4x6dI4x6diI')


_POINT_AT_0 = struct.Struct('<I4x7dI4x6dI4x6diI')


def encode_com_plan(plan: ComPlan, stamp_ns: int, frame_id: str) -> bytes:
    """``com_plan`` as ``com_plan_to_msg`` builds it (joint ``com``, identity
    rotations, sample ``k`` at ``k * dt``), with ``header.stamp = stamp_ns``, serialized."""
    w = CdrWriter()
    w.header(stamp_ns, frame_id)
    w.u32(1)
    w.string('com')
    n = len(plan.position)
    w.u32(n)
    pos = np.asarray(plan.position, dtype=float).tolist()
    vel = np.asarray(plan.velocity, dtype=float).tolist()
    acc = np.asarray(plan.acceleration, dtype=float).tolist()
    buf = w.buf
    for k in range(n):
        fmt = _POINT_AT_0 if (len(buf) - 4) % 8 == 0 else _POINT_AT_4
        sec, nanosec = divmod(round(k * plan.dt * 1e9), NS)      # as sec_to_duration
        buf.extend(fmt.pack(1, *pos[k], 0.0, 0.0, 0.0, 1.0, 1, *vel[k], 0.0, 0.0, 0.0,
                            1, *acc[k], 0.0, 0.0, 0.0, sec, nanosec))
    return w.bytes()


def decode_com_plan(data: bytes) -> tuple[int, ComPlan] | None:
    """(``header.stamp`` ns, plan) of a serialized ``com_plan`` with one joint and one
    transform, velocity and acceleration per point; ``None`` for anything else (the caller
    then uses the generic decoder, which also gives the precise error)."""
    try:
        r = CdrReader(data)
        sec, nanosec = r.time()
        r.string()                                           # frame_id
        if r.u32() != 1 or r.string() != 'com':
            return None
        n = r.u32()
        if n < 2 or r.pos + n * _POINT_AT_4.size > len(r.data):
            return None
        rows = np.empty((n, 24))
        for k in range(n):
            fmt = _POINT_AT_0 if (r.pos - 4) % 8 == 0 else _POINT_AT_4
            rows[k] = r.unpack(fmt, 1)
    except (ValueError, UnicodeDecodeError, struct.error):
        return None
    # Columns: count, 7 transform, count, 6 twist, count, 6 twist, sec, nanosec.
    if not (np.all(rows[:, 0] == 1) and np.all(rows[:, 8] == 1) and np.all(rows[:, 15] == 1)):
        return None
    # The same float arithmetic as com_plan_from_msg, so both decoders give identical plans.
    times = rows[:, 22] + rows[:, 23] * 1e-9
    return sec * NS + nanosec, com_plan_from_arrays(
        sec + nanosec * 1e-9, times, rows[:, 1:4].copy(), rows[:, 9:12].copy(),
        rows[:, 16:19].copy())


def com_plan_from_cdr(data: bytes) -> tuple[int, ComPlan]:
    """(``header.stamp`` ns, plan) of a serialized ``com_plan``: ``decode_com_plan``, or
    rclpy's generic decoder for a layout that one declines. ``ValueError`` for a bad plan."""
    decoded = decode_com_plan(data)
    if decoded is not None:
        return decoded
    try:
        msg = deserialize_message(data, MultiDOFJointTrajectory)
    except Exception as err:       # rclpy raises its own error types on bad CDR
        raise ValueError(f'cannot deserialize: {err}') from err
    return stamp_to_ns(msg.header.stamp), com_plan_from_msg(msg)
