import numpy as np
import pytest

from replan_core.metrics import (
    FallLimits,
    achieved_velocity,
    command_segments,
    detect_fall,
    distance_travelled,
    roll_pitch_yaw,
    tracking_errors,
)


def _yaw_quat(yaw):
    return np.stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)],
                    axis=1)


def test_roll_pitch_yaw_of_pure_yaw():
    yaw = np.array([0.0, 0.5, -2.0])
    np.testing.assert_allclose(roll_pitch_yaw(_yaw_quat(yaw))[:, 2], yaw, atol=1e-12)


def test_fall_detection_names_the_limit():
    t = np.linspace(0, 1, 11)
    h = np.full(11, 0.55)
    rpy = np.zeros((11, 3))
    assert detect_fall(t, h, rpy, FallLimits()) == (False, None, '')
    h[7:] = 0.2
    fell, when, why = detect_fall(t, h, rpy, FallLimits())
    assert fell and when == pytest.approx(0.7) and 'height' in why
    h[:] = 0.55
    rpy[4, 1] = 0.8
    fell, when, why = detect_fall(t, h, rpy, FallLimits())
    assert fell and when == pytest.approx(0.4) and 'tilt' in why


def test_segments_and_tracking_on_a_turning_walk():
    # Walk at 0.1 m/s forward in the body frame while turning at 0.2 rad/s from t = 2 s.
    dt = 0.01
    t = np.arange(0, 12, dt)
    yaw = np.where(t < 2, 0.0, 0.2 * (t - 2))
    v = np.where(t < 2, 0.0, 0.1)
    vel = np.stack([v * np.cos(yaw), v * np.sin(yaw)], axis=1)
    pos = np.vstack([[0, 0], np.cumsum(vel[:-1] * dt, axis=0)])
    segs = command_segments([(2.0, (0.1, 0.0, 0.2))], end_time=12.0)
    assert [(s.start, s.end) for s in segs] == [(0.0, 2.0), (2.0, 12.0)]
    rows = tracking_errors(t, pos, yaw, segs, settle=1.0)
    vx, vy, wz = rows[1]['achieved']
    # Chord over a 9 s arc of 1.8 rad shortens the mean speed by sin(0.9)/0.9.
    assert vx == pytest.approx(0.1 * np.sin(0.9) / 0.9, rel=0.02)
    assert abs(vy) < 0.005
    assert wz == pytest.approx(0.2, rel=0.01)
    assert rows[0]['achieved'] == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)


def test_achieved_velocity_needs_two_samples():
    t = np.array([0.0, 1.0])
    assert achieved_velocity(t, np.zeros((2, 2)), np.zeros(2), 5.0, 6.0) is None


def test_distance_travelled():
    pos = np.array([[0, 0], [3, 0], [3, 4]], dtype=float)
    assert distance_travelled(pos) == (5.0, 7.0)


def test_interval_stats_skips_the_start():
    from replan_core.metrics import interval_stats
    stats = interval_stats(np.array([0.0, 1.4, 2.1, 2.8, 3.6]), skip=1)
    assert stats['count'] == 3
    assert stats['median'] == pytest.approx(0.7) and stats['max'] == pytest.approx(0.8)
    assert interval_stats(np.array([1.0]), skip=0) is None
