"""Stamps: seconds and nanoseconds both ways, exactly."""

from __future__ import annotations

import numpy as np

from replan_core.common.types import ImuReading
from replan_ros.messages.imu import encode_imu, imu_from_cdr
from replan_ros.messages.stamps import (
    ns_to_sec,
    ns_to_stamp,
    sec_to_stamp,
    stamp_to_ns,
    stamp_to_sec,
)


def test_stamp_round_trip_is_exact_in_ns():
    for t in (0.0, 0.004, 12.348, 1234.5678):
        assert stamp_to_ns(sec_to_stamp(t)) == round(t * 1e9)


def test_ns_to_sec_is_the_float_the_decoders_give():
    """The wbc prepares the estimator's next step for ns_to_sec(next stamp) and the estimator
    uses it only for an equal float: the decoders must give exactly that float."""
    for tick in (0, 1, 3, 250, 5517, 123_457, 10_000_001):
        ns = tick * 4_000_000
        t = ns_to_sec(ns)
        assert t == stamp_to_sec(ns_to_stamp(ns))
        reading = ImuReading(tick * 0.004, np.zeros(3), np.array([0.0, 0.0, 9.81]))
        decoded_ns, decoded = imu_from_cdr(encode_imu(reading))
        assert decoded_ns == ns and decoded.stamp == t
