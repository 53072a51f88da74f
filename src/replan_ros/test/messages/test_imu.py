"""imu: the hand-written CDR against rclpy's serializer and decoder, any frame, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu
from wire_checks import STAMPS, same_bytes_as_rclpy

from replan_core.common.types import ImuReading
from replan_ros.messages.imu import encode_imu, imu_from_cdr, imu_from_msg, imu_to_msg


@pytest.mark.parametrize('t', STAMPS)
def test_imu_round_trip(t):
    rng = np.random.default_rng(5)
    reading = ImuReading(t, rng.normal(size=3), rng.normal(size=3) + np.array([0, 0, 9.81]))
    msg = imu_to_msg(reading, 1e-4, 2e-3)
    data = encode_imu(reading, 1e-4, 2e-3)
    same_bytes_as_rclpy(data, msg, Imu)
    assert msg.orientation_covariance[0] == -1.0 and msg.orientation.w == 1.0
    stamp_ns, decoded = imu_from_cdr(data)
    expected = imu_from_msg(msg)
    assert stamp_ns == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    assert decoded.stamp == expected.stamp
    np.testing.assert_array_equal(decoded.angular_velocity, expected.angular_velocity)
    np.testing.assert_array_equal(decoded.linear_acceleration, expected.linear_acceleration)


@pytest.mark.parametrize('frame_id', ['', 'imu_link', 'a_much_longer_imu_frame'])
def test_imu_of_any_frame_decodes(frame_id):
    reading = ImuReading(3.0, np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 9.0]))
    msg = imu_to_msg(reading)
    msg.header.frame_id = frame_id
    _, decoded = imu_from_cdr(bytes(serialize_message(msg)))
    np.testing.assert_array_equal(decoded.angular_velocity, reading.angular_velocity)
    np.testing.assert_array_equal(decoded.linear_acceleration, reading.linear_acceleration)


def test_bad_imu():
    reading = ImuReading(3.0, np.array([0.1, math.nan, 0.3]), np.array([1.0, 2.0, 9.0]))
    with pytest.raises(ValueError, match='imu: non-finite'):
        imu_from_cdr(encode_imu(reading))
    with pytest.raises(ValueError, match='cannot deserialize'):
        imu_from_cdr(encode_imu(
            ImuReading(3.0, np.zeros(3), np.zeros(3)))[:100])
