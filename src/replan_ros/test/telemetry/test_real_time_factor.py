"""telemetry.real_time_factor: sim s per wall s over the last wall second."""

import pytest

from replan_ros.telemetry.real_time_factor import RealTimeFactor


def test_the_factor_is_measured_over_the_last_second_and_zero_when_stalled():
    rtf = RealTimeFactor()
    assert rtf.value(0.0, 0.0) == 0.0
    for k in range(1, 301):                 # 2 sim s per wall s for 3 wall s
        rtf.stepped(k * 0.01, k * 0.02)
    assert rtf.value(3.0, 6.0) == pytest.approx(2.0, rel=0.02)
    for k in range(1, 101):                 # then 0.5 sim s per wall s
        rtf.stepped(3.0 + k * 0.01, 6.0 + k * 0.005)
    assert rtf.value(4.0, 6.5) == pytest.approx(0.5, rel=0.05)
    assert rtf.value(5.5, 6.5) == 0.0       # nothing stepped for 1.5 wall s
