"""nav_msgs/Odometry: a BaseState (twist in the child frame, REP-105), as an rclpy message and
as the lock-step's hand-written CDR.

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import math
import struct

import numpy as np
from nav_msgs.msg import Odometry

from replan_core.common import rotations
from replan_core.common.types import BASE_FRAME, WORLD_FRAME, BaseState
from replan_ros.messages.cdr import (
    ENCAPSULATION,
    NS,
    STAMP,
    CdrStrings,
    deserialize_or_raise,
    pad_to,
    stamp_pair,
)
from replan_ros.messages.stamps import header, stamp_to_sec


def odom_values(bs: BaseState) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(pose: x y z qx qy qz qw, twist in ``base_link``: vx vy vz wx wy wz) of the
    odometry of ``bs`` (REP-105); shared by ``odom_from_base_state`` and ``encode_odom``."""
    p, q = bs.position, bs.quaternion
    to_base = rotations.conjugate(rotations.normalized(q))     # twist in base_link (REP-105)
    linear = rotations.rotate(to_base, bs.linear_velocity)
    angular = rotations.rotate(to_base, bs.angular_velocity)
    pose = (float(p[0]), float(p[1]), float(p[2]),
            float(q[0]), float(q[1]), float(q[2]), float(q[3]))
    return pose, tuple(float(v) for v in (*linear, *angular))


def odom_from_base_state(bs: BaseState) -> Odometry:
    msg = Odometry()
    msg.header = header(bs.stamp, WORLD_FRAME)
    msg.child_frame_id = BASE_FRAME
    pose, twist = odom_values(bs)
    position, orientation = msg.pose.pose.position, msg.pose.pose.orientation
    position.x, position.y, position.z = pose[:3]
    orientation.x, orientation.y, orientation.z, orientation.w = pose[3:]
    linear, angular = msg.twist.twist.linear, msg.twist.twist.angular
    linear.x, linear.y, linear.z = twist[:3]
    angular.x, angular.y, angular.z = twist[3:]
    return msg


def base_state_from_odom(msg: Odometry) -> BaseState:
    """Base state with the twist in the world frame; ValueError on a non-finite pose or twist
    or a quaternion that is not one."""
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
    return base_state_from_values(stamp_to_sec(msg.header.stamp),
                                  (p.x, p.y, p.z, o.x, o.y, o.z, o.w),
                                  (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))


def base_state_from_values(stamp: float, pose, twist) -> BaseState:
    """``base_state_from_odom`` of an odometry's pose (x y z qx qy qz qw) and twist in the
    child frame (vx vy vz wx wy wz); shared with the hand-written codec."""
    q = tuple(pose[3:7])
    values = (*pose[:3], *twist, *q)
    if not (all(math.isfinite(v) for v in values)
            and abs(math.sqrt(sum(c * c for c in q)) - 1.0) < 0.1):
        raise ValueError('odom: non-finite pose or twist, or not a unit quaternion')
    unit = rotations.normalized(q)
    return BaseState(stamp=stamp, position=np.array(pose[:3]), quaternion=np.array(q),
                     linear_velocity=np.array(rotations.rotate(unit, tuple(twist[:3]))),
                     angular_velocity=np.array(rotations.rotate(unit, tuple(twist[3:6]))))


_ODOM_FRAMES = CdrStrings(8, WORLD_FRAME, BASE_FRAME)


_ODOM = struct.Struct(f'<4siI{_ODOM_FRAMES.fmt}{pad_to(_ODOM_FRAMES.end, 8)}x7d288x6d288x')


_ODOM_VALUES = struct.Struct('<7d288x6d')


def base_state_from_cdr(data: bytes) -> tuple[int, BaseState]:
    """(stamp ns, base state, twist in the world frame) of a serialized ``Odometry``, any
    frames; ``ValueError`` as ``base_state_from_odom`` gives it."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError
        sec, nanosec = STAMP.unpack_from(data, 4)
        pos = 8
        for _ in range(2):                   # frame_id, child_frame_id
            pos += pad_to(pos, 4)
            (size,) = struct.unpack_from('<I', data, 4 + pos)
            pos += 4 + size
        pos += pad_to(pos, 8)
        if len(data) - 4 - pos < _ODOM_VALUES.size + 288:
            raise ValueError
        values = _ODOM_VALUES.unpack_from(data, 4 + pos)
    except (ValueError, struct.error):
        msg = deserialize_or_raise(data, Odometry)
        stamp = msg.header.stamp
        return stamp.sec * NS + stamp.nanosec, base_state_from_odom(msg)
    return sec * NS + nanosec, base_state_from_values(sec + nanosec * 1e-9, values[:7],
                                                        values[7:])


def odom_fields_from_cdr(data: bytes) -> tuple[int, str, str, tuple[float, ...],
                                               tuple[float, ...]]:
    """(stamp ns, frame_id, child_frame_id, pose: x y z qx qy qz qw, twist in the child
    frame: vx vy vz wx wy wz) of a serialized ``Odometry``, unchecked (what a viewer draws);
    ``ValueError`` if rclpy's decoder cannot read it either."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError
        sec, nanosec = STAMP.unpack_from(data, 4)
        pos = 8
        frames = []
        for _ in range(2):                   # frame_id, child_frame_id
            pos += pad_to(pos, 4)
            (size,) = struct.unpack_from('<I', data, 4 + pos)
            if size < 1:
                raise ValueError
            frames.append(bytes(data[8 + pos:8 + pos + size - 1]).decode())
            pos += 4 + size
        pos += pad_to(pos, 8)
        if len(data) - 4 - pos < _ODOM_VALUES.size + 288:
            raise ValueError
        values = _ODOM_VALUES.unpack_from(data, 4 + pos)
    except (ValueError, struct.error, UnicodeDecodeError):
        msg = deserialize_or_raise(data, Odometry)
        p, o = msg.pose.pose.position, msg.pose.pose.orientation
        v, w = msg.twist.twist.linear, msg.twist.twist.angular
        return (msg.header.stamp.sec * NS + msg.header.stamp.nanosec, msg.header.frame_id,
                msg.child_frame_id, (p.x, p.y, p.z, o.x, o.y, o.z, o.w),
                (v.x, v.y, v.z, w.x, w.y, w.z))
    return sec * NS + nanosec, frames[0], frames[1], values[:7], values[7:]


def encode_odom(base: BaseState, stamp_ns: int | None = None) -> bytes:
    """``odom_from_base_state(base)`` serialized, stamped ``stamp_ns`` if given."""
    if stamp_ns is None:
        stamp_ns = round(base.stamp * 1e9)
    pose, twist = odom_values(base)
    return _ODOM.pack(ENCAPSULATION, *stamp_pair(stamp_ns), *_ODOM_FRAMES.values, *pose, *twist)
