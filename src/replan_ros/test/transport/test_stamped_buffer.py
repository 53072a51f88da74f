import math

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message

from replan_core.common.types import BaseState
from replan_ros.messages.odom import base_state_from_odom, odom_from_base_state
from replan_ros.transport.stamped_buffer import (
    RawStampedBuffer,
    cdr_byte_order,
    cdr_header_stamp_ns,
)


def _odom_cdr(t: float, x: float) -> bytes:
    base = BaseState(t, np.array([x, 0.0, 0.6]), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3),
                     np.zeros(3))
    return serialize_message(odom_from_base_state(base))


def _decode(msg: Odometry) -> BaseState:
    base = base_state_from_odom(msg)
    if not math.isfinite(base.position[0]):
        raise ValueError('non-finite')
    return base


def test_stamp_is_read_from_the_cdr_header():
    assert cdr_header_stamp_ns(_odom_cdr(12.348, 0.0)) == 12_348_000_000
    assert cdr_header_stamp_ns(b'\x00\x01') is None


def test_buffer_keeps_the_last_ones_and_decodes_on_request():
    buffer = RawStampedBuffer(Odometry, _decode, capacity=3)
    for k in range(5):
        assert buffer.add(_odom_cdr(k * 0.004, float(k))) == k * 4_000_000
    assert buffer.stamps() == [8_000_000, 12_000_000, 16_000_000]
    assert buffer.get(4_000_000) is None                       # dropped: capacity 3
    assert buffer.get(12_000_000).position[0] == 3.0


def test_a_message_that_fails_to_decode_is_dropped_with_the_error():
    buffer = RawStampedBuffer(Odometry, _decode, capacity=3)
    ns = buffer.add(_odom_cdr(1.0, float('nan')))
    with pytest.raises(ValueError, match='non-finite'):
        buffer.get(ns)
    assert ns not in buffer


@pytest.mark.parametrize('kind, order', [
    (0, 'big'), (1, 'little'), (2, 'big'), (3, 'little'),          # CDR, PL_CDR
    (6, 'big'), (7, 'little'), (8, 'big'), (9, 'little'),          # CDR2, D_CDR2
    (10, 'big'), (11, 'little')])                                  # PL_CDR2
def test_byte_order_follows_the_encapsulation_identifier(kind, order):
    """Odd identifiers are the little-endian ones (XCDR2 included: 7, 9, 11)."""
    stamp = 12_348_000_000
    sec, nanosec = divmod(stamp, 1_000_000_000)
    body = sec.to_bytes(4, order, signed=True) + nanosec.to_bytes(4, order)
    cdr = bytes([0, kind, 0, 0]) + body + b'\x00' * 8
    assert cdr_byte_order(cdr) == order
    assert cdr_header_stamp_ns(cdr) == stamp
