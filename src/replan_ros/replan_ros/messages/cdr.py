"""Hand-written CDR for the plan messages, byte for byte what rclpy's ``serialize_message``
writes (XCDR1, little endian; unit tests compare the bytes).

A re-plan's ``com_plan`` (``trajectory_msgs/MultiDOFJointTrajectory``, 201 points over 8 s) is
about 1800 Python message objects: building and serializing it took the mpc node 4.6 ms and
deserializing it took the controller 4.4 ms, against a 2 ms solve; both are on the re-plan's
path (docs/ARCHITECTURE.md, "Re-plan path"). The plan's arrays go straight to bytes and back
here. Anything this decoder does not expect (another byte order, several transforms per point,
a truncated payload) returns ``None``: the caller then falls back to rclpy's generic
deserialization, so a plan published by another tool is still read.
"""

from __future__ import annotations

import struct

import numpy as np
from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_core.types import ComPlan
from replan_ros.messages.interfaces import com_plan_from_arrays, com_plan_from_msg, stamp_to_ns

ENCAPSULATION = b'\x00\x01\x00\x00'        # CDR, little endian, no options
_U32 = struct.Struct('<I')
_TIME = struct.Struct('<iI')                 # builtin_interfaces Time / Duration: sec, nanosec
_NS = 1_000_000_000
# One MultiDOFJointTrajectoryPoint with one transform, one velocity, one acceleration: its
# doubles are 8-aligned, so its layout depends on its start offset modulo 8 (4 or 0).
_POINT_AT_4 = struct.Struct('<I7dI4x6dI4x6diI')
_POINT_AT_0 = struct.Struct('<I4x7dI4x6dI4x6diI')


class CdrWriter:
    """Appends CDR fields; alignment is relative to the end of the encapsulation header."""

    def __init__(self) -> None:
        self.buf = bytearray(ENCAPSULATION)

    def align(self, n: int) -> None:
        self.buf.extend(b'\x00' * (-(len(self.buf) - 4) % n))

    def u32(self, value: int) -> None:
        self.align(4)
        self.buf.extend(_U32.pack(value))

    def time(self, ns: int) -> None:
        """A builtin_interfaces Time or Duration of ``ns`` nanoseconds."""
        self.align(4)
        self.buf.extend(_TIME.pack(*divmod(int(ns), _NS)))

    def string(self, text: str) -> None:
        data = text.encode() + b'\x00'
        self.u32(len(data))
        self.buf.extend(data)

    def header(self, stamp_ns: int, frame_id: str) -> None:
        self.time(stamp_ns)
        self.string(frame_id)

    def packed(self, fmt: struct.Struct, alignment: int, *values) -> None:
        self.align(alignment)
        self.buf.extend(fmt.pack(*values))

    def bytes(self) -> bytes:
        return bytes(self.buf)


class CdrReader:
    """Reads what ``CdrWriter`` writes; raises ``ValueError`` past the end."""

    def __init__(self, data: bytes) -> None:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError('not little-endian CDR')
        self.data = memoryview(data)
        self.pos = 4

    def align(self, n: int) -> None:
        self.pos += -(self.pos - 4) % n

    def unpack(self, fmt: struct.Struct, alignment: int = 4) -> tuple:
        self.align(alignment)
        if self.pos + fmt.size > len(self.data):
            raise ValueError('truncated CDR')
        values = fmt.unpack_from(self.data, self.pos)
        self.pos += fmt.size
        return values

    def u32(self) -> int:
        return self.unpack(_U32)[0]

    def time(self) -> tuple[int, int]:
        """(sec, nanosec) of a builtin_interfaces Time or Duration."""
        return self.unpack(_TIME)

    def string(self) -> str:
        size = self.u32()
        if size < 1 or self.pos + size > len(self.data):
            raise ValueError('bad CDR string')
        text = bytes(self.data[self.pos:self.pos + size - 1]).decode()
        self.pos += size
        return text


def encode_com_plan(plan: ComPlan, stamp_ns: int, frame_id: str) -> bytes:
    """``com_plan`` as ``interfaces.com_plan_to_msg`` builds it (joint ``com``, identity
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
        sec, nanosec = divmod(round(k * plan.dt * 1e9), _NS)      # as sec_to_duration
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
    return sec * _NS + nanosec, com_plan_from_arrays(
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


POSE = struct.Struct('<7d')      # geometry_msgs Pose / Transform: x y z, qx qy qz qw


def encode_path(stamp_ns: int, start_time: float, dt: float, points: np.ndarray,
                frame_id: str) -> bytes:
    """``nav_msgs/Path`` stamped ``stamp_ns`` as ``interfaces.path_msg`` builds it: one pose
    per row of ``points`` (n, 2 or 3; z 0 if absent), pose ``k`` stamped
    ``start_time + k * dt`` (s), identity orientation."""
    w = CdrWriter()
    w.header(stamp_ns, frame_id)
    xyz = np.zeros((len(points), 3))
    points = np.asarray(points, dtype=float)
    xyz[:, :points.shape[1]] = points[:, :3]
    w.u32(len(xyz))
    for k, (x, y, z) in enumerate(xyz.tolist()):
        w.header(round((start_time + k * dt) * 1e9), frame_id)     # as interfaces.header
        w.packed(POSE, 8, x, y, z, 0.0, 0.0, 0.0, 1.0)
    return w.bytes()
