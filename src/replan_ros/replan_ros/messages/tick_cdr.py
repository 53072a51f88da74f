"""Hand-written CDR for the lock-step's per-tick messages, byte for byte what rclpy writes
(XCDR1, little endian; unit tests compare with rclpy's serializer and decoder).

Every tick the sim publishes ``imu``, ``joint_states`` (and, to a reader, the truth), the
controller decodes them, publishes ``joint_torque_cmd`` and its estimate (``odom``,
``contacts``), and the sim decodes the command: all on the lock-step chain or beside it. Each
message through rclpy's Python classes costs a Python object per field both ways: 12-27 us
per message to build and serialize or to decode, against 1-7 us here, on an idle core
(``python -m replan_ros.benchmarks.bench_msgs``); in the running graph the difference was worth
about a fifth of the real-time factor (docs/ARCHITECTURE.md, "Per-tick budget"). The
layouts here are fixed (our joint names in ``JOINT_NAMES`` order, our frames), so each
message is one ``struct`` pack or unpack. A decoder returns ``None`` for any other layout
(another joint order, a frame it does not know, another byte order, a truncated payload); the
``*_from_cdr`` functions then use rclpy's generic decoder, so a message from another tool is
still read, with the same checks and error messages as before (``interfaces``).
"""

from __future__ import annotations

import math
import struct

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, PointCloud2
from sensor_msgs.msg import JointState as JointStateMsg

from replan_core.types import (
    BASE_FRAME,
    JOINT_NAMES,
    WORLD_FRAME,
    BaseState,
    ContactState,
    ImuReading,
    JointState,
)
from replan_ros.messages.cdr import ENCAPSULATION, CdrWriter
from replan_ros.messages.interfaces import (
    CONTACT_DTYPE,
    base_state_from_odom,
    base_state_from_values,
    contact_rows,
    contacts_from_msg,
    contacts_from_table,
    imu_from_msg,
    imu_values,
    joint_state_from_msg,
    odom_values,
    point_fields,
    torque_cmd_from_msg,
)

_NS = 1_000_000_000
_STAMP = struct.Struct('<iI')


def _pad(pos: int, n: int) -> int:
    return -pos % n


class _Strings:
    """Constant strings and string sequences (a str, or a tuple of str) from body offset
    ``pos``: their struct format, with ``x`` for CDR's padding (zero when written, skipped
    when read: rclpy does not zero it), the values it packs, and the offset after them."""

    def __init__(self, pos: int, *parts) -> None:
        fmt, values = [], []

        def align4() -> None:
            nonlocal pos
            if _pad(pos, 4):
                fmt.append(f'{_pad(pos, 4)}x')
                pos += _pad(pos, 4)

        for part in parts:
            texts = (part,) if isinstance(part, str) else part
            if not isinstance(part, str):
                align4()
                fmt.append('I')
                values.append(len(texts))
                pos += 4
            for text in texts:
                data = text.encode() + b'\x00'
                align4()
                fmt.append(f'I{len(data)}s')
                values += [len(data), data]
                pos += 4 + len(data)
        self.fmt = ''.join(fmt)
        self.values = tuple(values)
        self.end = pos


def _double_sequences(pos: int, counts: tuple[int, ...]) -> tuple[str, int]:
    """The struct format of sequences of ``counts`` doubles from body offset ``pos``."""
    fmt = ''
    for count in counts:
        if _pad(pos, 4):
            fmt += f'{_pad(pos, 4)}x'
            pos += _pad(pos, 4)
        fmt += 'I'
        pos += 4
        if count:
            if _pad(pos, 8):
                fmt += f'{_pad(pos, 8)}x'
                pos += _pad(pos, 8)
            fmt += f'{count}d'
            pos += 8 * count
    return fmt, pos


def _stamp(ns: int) -> tuple[int, int]:
    sec, nanosec = divmod(int(ns), _NS)
    return sec, nanosec


class JointStateCodec:
    """``sensor_msgs/JointState`` with ``frame_id`` and ``names`` fixed and ``counts`` values
    of position, velocity and effort (0: an empty sequence)."""

    def __init__(self, counts: tuple[int, int, int], names: tuple[str, ...] = JOINT_NAMES,
                 frame_id: str = '') -> None:
        self.counts = counts
        strings = _Strings(8, frame_id, tuple(names))
        sequences, _ = _double_sequences(strings.end, counts)
        self._struct = struct.Struct(f'<4siI{strings.fmt}{sequences}')
        self._constant = strings.values
        # Where the constant strings, each value sequence's count and its values are in the
        # unpacked tuple.
        index = 3 + len(strings.values)
        self._strings = slice(3, index)
        self._slices = []
        for count in counts:
            self._slices.append((index, slice(index + 1, index + 1 + count)))
            index += 1 + count

    def encode(self, stamp_ns: int, *arrays) -> bytes:
        """The message stamped ``stamp_ns`` with the ``counts`` non-empty arrays in order
        (position, velocity, effort; one per non-zero count)."""
        values = [ENCAPSULATION, *_stamp(stamp_ns), *self._constant]
        given = iter(arrays)
        for count in self.counts:
            values.append(count)
            if count:
                values.extend(np.asarray(next(given), dtype=float).tolist())
        return self._struct.pack(*values)

    def decode(self, data: bytes) -> tuple[int, tuple[tuple[float, ...], ...]] | None:
        """(stamp ns, (position, velocity, effort)) as tuples, empty for an empty sequence;
        None for any other layout. Bytes after the message are ignored (rclpy's serializer
        leaves some after empty sequences)."""
        if len(data) < self._struct.size or bytes(data[:2]) != ENCAPSULATION[:2]:
            return None
        values = self._struct.unpack_from(data)
        if values[self._strings] != self._constant:
            return None
        sequences = []
        for (index, values_slice), count in zip(self._slices, self.counts, strict=True):
            if values[index] != count:
                return None
            sequences.append(values[values_slice])
        return values[1] * _NS + values[2], tuple(sequences)


def _all_finite(values: tuple[float, ...]) -> bool:
    # A sum is finite when every term is, short of an overflow (then numpy decides): one
    # call instead of numpy's per-array overhead, several us per tick.
    return math.isfinite(sum(values)) or bool(np.all(np.isfinite(values)))


_N = len(JOINT_NAMES)
JOINT_STATES = JointStateCodec((_N, _N, _N))      # the sim's joint_states
TORQUE_COMMAND = JointStateCodec((0, 0, _N))      # the controller's joint_torque_cmd


def encode_joint_state(js: JointState) -> bytes:
    """``interfaces.joint_state_to_msg(js)`` serialized."""
    return JOINT_STATES.encode(round(js.stamp * 1e9), js.position, js.velocity, js.effort)


def joint_state_from_cdr(data: bytes) -> tuple[int, JointState]:
    """(stamp ns, joint state) of a serialized ``JointState``; ``ValueError`` as
    ``interfaces.joint_state_from_msg`` gives it."""
    decoded = JOINT_STATES.decode(data)
    if decoded is None:
        msg = _deserialize(data, JointStateMsg)
        js = joint_state_from_msg(msg)
        return msg.header.stamp.sec * _NS + msg.header.stamp.nanosec, js
    stamp_ns, (position, velocity, effort) = decoded
    if not _all_finite(position + velocity):
        raise ValueError('joint_states: non-finite joint positions or velocities')
    sec, nanosec = divmod(stamp_ns, _NS)
    return stamp_ns, JointState(sec + nanosec * 1e-9, np.array(position), np.array(velocity),
                                np.array(effort))


def encode_torque_command(stamp_ns: int, torques: np.ndarray) -> bytes:
    """``interfaces.torque_cmd_to_msg`` stamped exactly ``stamp_ns``, serialized."""
    return TORQUE_COMMAND.encode(stamp_ns, torques)


def torque_command_from_cdr(data: bytes) -> tuple[int, np.ndarray]:
    """(stamp ns, torques in ``JOINT_NAMES`` order); ``ValueError`` as
    ``interfaces.torque_cmd_from_msg`` gives it."""
    decoded = TORQUE_COMMAND.decode(data)
    if decoded is None:
        return torque_cmd_from_msg(_deserialize(data, JointStateMsg))
    stamp_ns, (_, _, torques) = decoded
    if not _all_finite(torques):
        return torque_cmd_from_msg(_deserialize(data, JointStateMsg))   # its message
    return stamp_ns, np.array(torques)


# ---------------------------------------------------------------------------------------------
# sensor_msgs/Imu: a header, then 37 doubles (orientation, 3 x (vector), 3 covariances)

_IMU_FRAME = _Strings(8, BASE_FRAME)
_IMU = struct.Struct(f'<4siI{_IMU_FRAME.fmt}{_pad(_IMU_FRAME.end, 8)}x37d')
_IMU_VALUES = struct.Struct('<37d')


def encode_imu(reading: ImuReading, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> bytes:
    """``interfaces.imu_to_msg`` serialized."""
    return _IMU.pack(ENCAPSULATION, *_stamp(round(reading.stamp * 1e9)), *_IMU_FRAME.values,
                     *imu_values(reading, gyro_variance, accel_variance))


def imu_from_cdr(data: bytes) -> tuple[int, ImuReading]:
    """(stamp ns, reading) of a serialized ``Imu``, any frame; ``ValueError`` as
    ``interfaces.imu_from_msg`` gives it."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError
        sec, nanosec = _STAMP.unpack_from(data, 4)
        (frame_size,) = struct.unpack_from('<I', data, 12)
        pos = 12 + frame_size               # body offset after the frame's bytes
        pos += _pad(pos, 8)
        if not _IMU_VALUES.size <= len(data) - 4 - pos < _IMU_VALUES.size + 4:
            raise ValueError
        values = _IMU_VALUES.unpack_from(data, 4 + pos)
    except (ValueError, struct.error):
        msg = _deserialize(data, Imu)
        return msg.header.stamp.sec * _NS + msg.header.stamp.nanosec, imu_from_msg(msg)
    measured = values[13:16] + values[25:28]      # angular velocity, linear acceleration
    if not _all_finite(measured):
        raise ValueError('imu: non-finite angular velocity or acceleration')
    return sec * _NS + nanosec, ImuReading(stamp=sec + nanosec * 1e-9,
                                           angular_velocity=np.array(measured[:3]),
                                           linear_acceleration=np.array(measured[3:]))


# ---------------------------------------------------------------------------------------------
# nav_msgs/Odometry: a header, the child frame, then 85 doubles (pose, covariance, twist,
# covariance); the covariances are zero (interfaces.odom_from_base_state)

_ODOM_FRAMES = _Strings(8, WORLD_FRAME, BASE_FRAME)
_ODOM = struct.Struct(f'<4siI{_ODOM_FRAMES.fmt}{_pad(_ODOM_FRAMES.end, 8)}x7d288x6d288x')


_ODOM_VALUES = struct.Struct('<7d288x6d')


def base_state_from_cdr(data: bytes) -> tuple[int, BaseState]:
    """(stamp ns, base state, twist in the world frame) of a serialized ``Odometry``, any
    frames; ``ValueError`` as ``interfaces.base_state_from_odom`` gives it."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError
        sec, nanosec = _STAMP.unpack_from(data, 4)
        pos = 8
        for _ in range(2):                   # frame_id, child_frame_id
            pos += _pad(pos, 4)
            (size,) = struct.unpack_from('<I', data, 4 + pos)
            pos += 4 + size
        pos += _pad(pos, 8)
        if len(data) - 4 - pos < _ODOM_VALUES.size + 288:
            raise ValueError
        values = _ODOM_VALUES.unpack_from(data, 4 + pos)
    except (ValueError, struct.error):
        msg = _deserialize(data, Odometry)
        stamp = msg.header.stamp
        return stamp.sec * _NS + stamp.nanosec, base_state_from_odom(msg)
    return sec * _NS + nanosec, base_state_from_values(sec + nanosec * 1e-9, values[:7],
                                                        values[7:])


def odom_fields_from_cdr(data: bytes) -> tuple[int, str, str, tuple[float, ...],
                                               tuple[float, ...]]:
    """(stamp ns, frame_id, child_frame_id, pose: x y z qx qy qz qw, twist in the child
    frame: vx vy vz wx wy wz) of a serialized ``Odometry``, unchecked (what a viewer draws);
    ``ValueError`` if rclpy's decoder cannot read it either."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError
        sec, nanosec = _STAMP.unpack_from(data, 4)
        pos = 8
        frames = []
        for _ in range(2):                   # frame_id, child_frame_id
            pos += _pad(pos, 4)
            (size,) = struct.unpack_from('<I', data, 4 + pos)
            if size < 1:
                raise ValueError
            frames.append(bytes(data[8 + pos:8 + pos + size - 1]).decode())
            pos += 4 + size
        pos += _pad(pos, 8)
        if len(data) - 4 - pos < _ODOM_VALUES.size + 288:
            raise ValueError
        values = _ODOM_VALUES.unpack_from(data, 4 + pos)
    except (ValueError, struct.error, UnicodeDecodeError):
        msg = _deserialize(data, Odometry)
        p, o = msg.pose.pose.position, msg.pose.pose.orientation
        v, w = msg.twist.twist.linear, msg.twist.twist.angular
        return (msg.header.stamp.sec * _NS + msg.header.stamp.nanosec, msg.header.frame_id,
                msg.child_frame_id, (p.x, p.y, p.z, o.x, o.y, o.z, o.w),
                (v.x, v.y, v.z, w.x, w.y, w.z))
    return sec * _NS + nanosec, frames[0], frames[1], values[:7], values[7:]


def encode_odom(base: BaseState, stamp_ns: int | None = None) -> bytes:
    """``interfaces.odom_from_base_state(base)`` serialized, stamped ``stamp_ns`` if given."""
    if stamp_ns is None:
        stamp_ns = round(base.stamp * 1e9)
    pose, twist = odom_values(base)
    return _ODOM.pack(ENCAPSULATION, *_stamp(stamp_ns), *_ODOM_FRAMES.values, *pose, *twist)


# ---------------------------------------------------------------------------------------------
# sensor_msgs/PointCloud2 contact tables (interfaces.contacts_to_msg)

def _fields_bytes(dtype: np.dtype) -> bytes:
    """The ``fields`` sequence of a table from a 4-aligned offset (it ends 4-aligned)."""
    w = CdrWriter()
    fields = point_fields(dtype)
    w.u32(len(fields))
    for field in fields:
        w.string(field.name)
        w.u32(field.offset)
        w.buf.append(field.datatype)
        w.u32(field.count)
    return bytes(w.buf[4:])


_CONTACT_FRAME = _Strings(8, WORLD_FRAME)
_CONTACT_HEADER = struct.Struct(f'<iI{_CONTACT_FRAME.fmt}{_pad(_CONTACT_FRAME.end, 4)}xII')
_CONTACT_FIELDS = _fields_bytes(CONTACT_DTYPE)
_CLOUD_STEPS = struct.Struct('<3xIII')        # (is_bigendian before), point_step, row_step,
#                                               the data's length


def _encode_table(stamp_ns: int, table: np.ndarray) -> bytes:
    data = table.tobytes()
    step = table.dtype.itemsize
    out = bytearray(ENCAPSULATION)
    out += _CONTACT_HEADER.pack(*_stamp(stamp_ns), *_CONTACT_FRAME.values, 1, len(table))
    out += _CONTACT_FIELDS
    out.append(0)                                   # is_bigendian
    out += _CLOUD_STEPS.pack(step, step * len(table), len(data))
    out += data
    out.append(1)                                   # is_dense
    return bytes(out)


_CONTACT_TABLE_AT = struct.calcsize(_CONTACT_HEADER.format) + len(_CONTACT_FIELDS) + 16
_CONTACT_STEPS = struct.Struct('<BxxxIII')
# The four rows of our table, legs in order: x y z leg fx fy fz contact touchdown liftoff each.
_CONTACT_ROWS = struct.Struct('<' + '3dB3d3B' * 4)
_LEGS_IN_ORDER = (0, 1, 2, 3)


def contacts_from_cdr(data: bytes) -> tuple[int, ContactState]:
    """(stamp ns, contacts) of a serialized contacts table; ``ValueError`` as
    ``interfaces.contacts_from_msg`` gives it. Only our layout (frame, fields, little endian)
    is read here; any other goes to rclpy's decoder."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2] or len(data) < 4 + _CONTACT_TABLE_AT:
            raise ValueError
        header = _CONTACT_HEADER.unpack_from(data, 4)
        start = 4 + _CONTACT_HEADER.size
        if (header[2:-2] != _CONTACT_FRAME.values or header[-2] != 1
                or bytes(data[start:start + len(_CONTACT_FIELDS)]) != _CONTACT_FIELDS):
            raise ValueError
        big, step, _, size = _CONTACT_STEPS.unpack_from(data, start + len(_CONTACT_FIELDS))
        width = header[-1]
        if big or step != CONTACT_DTYPE.itemsize or size != width * step:
            raise ValueError
        sec, nanosec = header[0], header[1]
        if width == 4:
            # The table as the sim and controller send it: plain Python, a quarter of
            # contacts_from_table's numpy time; anything else (legs out of order, a
            # non-finite value: its error message) goes there.
            values = _CONTACT_ROWS.unpack_from(data, 4 + _CONTACT_TABLE_AT)
            rows = [values[k:k + 10] for k in range(0, 40, 10)]
            if (values[3::10] == _LEGS_IN_ORDER
                    and _all_finite(tuple(v for row in rows for v in (*row[:3], *row[4:7])))):
                return sec * _NS + nanosec, ContactState(
                    stamp=sec + nanosec * 1e-9,
                    foot_position=np.array([row[:3] for row in rows]),
                    force=np.array([row[4:7] for row in rows]),
                    contact=np.array([row[7] for row in rows], dtype=bool),
                    touchdown=np.array([row[8] for row in rows], dtype=bool),
                    liftoff=np.array([row[9] for row in rows], dtype=bool))
        table = np.frombuffer(data, dtype=CONTACT_DTYPE, count=width,
                              offset=4 + _CONTACT_TABLE_AT)
    except (ValueError, struct.error):
        msg = _deserialize(data, PointCloud2)
        stamp = msg.header.stamp
        return stamp.sec * _NS + stamp.nanosec, contacts_from_msg(msg)
    return sec * _NS + nanosec, contacts_from_table(sec + nanosec * 1e-9, table)


def encode_contacts(cs: ContactState, stamp_ns: int | None = None) -> bytes:
    """``interfaces.contacts_to_msg(cs)`` serialized, stamped ``stamp_ns`` if given."""
    if stamp_ns is None:
        stamp_ns = round(cs.stamp * 1e9)
    return _encode_table(stamp_ns, contact_rows(cs, np.arange(4)))


def encode_contact_events(cs: ContactState, stamp_ns: int | None = None) -> bytes | None:
    """``interfaces.contact_events_to_msg(cs)`` serialized; None if no flag changed."""
    rows = np.flatnonzero(np.asarray(cs.touchdown) | np.asarray(cs.liftoff))
    if len(rows) == 0:
        return None
    if stamp_ns is None:
        stamp_ns = round(cs.stamp * 1e9)
    return _encode_table(stamp_ns, contact_rows(cs, rows))


def _deserialize(data: bytes, msg_type: type):
    try:
        return deserialize_message(data, msg_type)
    except Exception as err:       # rclpy raises its own error types on bad CDR
        raise ValueError(f'cannot deserialize {msg_type.__name__}: {err}') from err

