"""sensor_msgs/Imu: an ImuReading (base_link axes; no orientation: REP-145's covariance[0] = -1), as
an rclpy message and as the lock-step's hand-written CDR.

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import math
import struct

import numpy as np
from sensor_msgs.msg import Imu

from replan_core.common.types import BASE_FRAME, ImuReading
from replan_ros.messages.cdr import (
    ENCAPSULATION,
    NS,
    STAMP,
    CdrStrings,
    all_finite,
    deserialize_or_raise,
    pad_to,
    stamp_pair,
)
from replan_ros.messages.stamps import header, stamp_to_sec


def imu_values(reading: ImuReading, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> tuple[float, ...]:
    """The 37 numbers of ``imu_to_msg`` in field order: orientation (x y z w, not provided),
    its covariance (``[0] = -1``), angular velocity, its covariance, linear acceleration, its
    covariance (the variances of one sample on the diagonals); shared with the hand-written
    codec."""
    w, a = reading.angular_velocity, reading.linear_acceleration
    gyro_cov = (gyro_variance, 0.0, 0.0, 0.0, gyro_variance, 0.0, 0.0, 0.0, gyro_variance)
    accel_cov = (accel_variance, 0.0, 0.0, 0.0, accel_variance, 0.0, 0.0, 0.0, accel_variance)
    return ((0.0, 0.0, 0.0, 1.0, -1.0) + (0.0,) * 8
            + (float(w[0]), float(w[1]), float(w[2])) + tuple(float(v) for v in gyro_cov)
            + (float(a[0]), float(a[1]), float(a[2])) + tuple(float(v) for v in accel_cov))


def imu_to_msg(reading: ImuReading, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> Imu:
    """The IMU sample in ``base_link``; the variances (per axis, of one sample) fill the
    diagonal covariances; the orientation is marked as not provided."""
    values = imu_values(reading, gyro_variance, accel_variance)
    msg = Imu()
    msg.header = header(reading.stamp, BASE_FRAME)
    o = msg.orientation
    o.x, o.y, o.z, o.w = values[:4]
    msg.orientation_covariance = values[4:13]
    v = msg.angular_velocity
    v.x, v.y, v.z = values[13:16]
    msg.angular_velocity_covariance = values[16:25]
    v = msg.linear_acceleration
    v.x, v.y, v.z = values[25:28]
    msg.linear_acceleration_covariance = values[28:37]
    return msg


def imu_from_msg(msg: Imu) -> ImuReading:
    """ImuReading in the frame of the message (base_link); ValueError on a non-finite value."""
    w, a = msg.angular_velocity, msg.linear_acceleration
    values = (w.x, w.y, w.z, a.x, a.y, a.z)
    if not all(math.isfinite(v) for v in values):
        raise ValueError('imu: non-finite angular velocity or acceleration')
    return ImuReading(stamp=stamp_to_sec(msg.header.stamp),
                      angular_velocity=np.array(values[:3]),
                      linear_acceleration=np.array(values[3:]))


_IMU_FRAME = CdrStrings(8, BASE_FRAME)


_IMU = struct.Struct(f'<4siI{_IMU_FRAME.fmt}{pad_to(_IMU_FRAME.end, 8)}x37d')


_IMU_VALUES = struct.Struct('<37d')


def encode_imu(reading: ImuReading, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> bytes:
    """``imu_to_msg`` serialized."""
    return _IMU.pack(ENCAPSULATION, *stamp_pair(round(reading.stamp * 1e9)), *_IMU_FRAME.values,
                     *imu_values(reading, gyro_variance, accel_variance))


def imu_from_cdr(data: bytes) -> tuple[int, ImuReading]:
    """(stamp ns, reading) of a serialized ``Imu``, any frame; ``ValueError`` as
    ``imu_from_msg`` gives it."""
    try:
        if bytes(data[:2]) != ENCAPSULATION[:2]:
            raise ValueError
        sec, nanosec = STAMP.unpack_from(data, 4)
        (frame_size,) = struct.unpack_from('<I', data, 12)
        pos = 12 + frame_size               # body offset after the frame's bytes
        pos += pad_to(pos, 8)
        if not _IMU_VALUES.size <= len(data) - 4 - pos < _IMU_VALUES.size + 4:
            raise ValueError
        values = _IMU_VALUES.unpack_from(data, 4 + pos)
    except (ValueError, struct.error):
        msg = deserialize_or_raise(data, Imu)
        return msg.header.stamp.sec * NS + msg.header.stamp.nanosec, imu_from_msg(msg)
    measured = values[13:16] + values[25:28]      # angular velocity, linear acceleration
    if not all_finite(measured):
        raise ValueError('imu: non-finite angular velocity or acceleration')
    return sec * NS + nanosec, ImuReading(stamp=sec + nanosec * 1e-9,
                                           angular_velocity=np.array(measured[:3]),
                                           linear_acceleration=np.array(measured[3:]))
