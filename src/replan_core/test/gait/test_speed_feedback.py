"""Velocity feedback in foot placement (speed_feedback.py), with fixed stamps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from replan_core.gait.crawl import GaitParams, compute_footholds
from replan_core.gait.speed_feedback import (
    ReplanSample,
    SpeedFeedback,
    StepTiming,
    carried_correction,
    mean_body_velocity,
    trunk_trend,
)

STEP = 0.75          # s between re-plans (one step)
CYCLE = 4 * STEP     # s


def _sample(t, xy, yaw=0.0, setpoint=(0.15, 0.0, 0.0)):
    return ReplanSample(t, np.array(xy, dtype=float), yaw, np.array(setpoint, dtype=float))


def test_mean_velocity_of_a_straight_walk_in_any_heading():
    for yaw in (0.0, 1.0, -2.5):
        a = _sample(2.0, (1.0, 2.0), yaw)
        b = _sample(5.0, (1.0 + 0.3 * math.cos(yaw) - 0.06 * math.sin(yaw),
                          2.0 + 0.3 * math.sin(yaw) + 0.06 * math.cos(yaw)), yaw)
        np.testing.assert_allclose(mean_body_velocity(a, b), [0.1, 0.02], atol=1e-12)


def test_mean_velocity_on_an_arc_is_the_speed_along_it():
    v, w, t = 0.05, 0.2, 3.0                 # m/s, rad/s, s: 0.6 rad of turn
    radius = v / w
    a = _sample(0.0, (0.0, 0.0), 0.0)
    b = _sample(t, (radius * math.sin(w * t), radius * (1 - math.cos(w * t))), w * t)
    np.testing.assert_allclose(mean_body_velocity(a, b), [v, 0.0], atol=1e-12)
    with pytest.raises(ValueError, match='positive length'):
        mean_body_velocity(b, a)


def _walk(feedback, loss, cycles, v=0.15):
    """A crawl that loses ``loss`` m of every stride; returns the corrections per re-plan."""
    x, out = 0.0, []
    for k in range(int(cycles * 4) + 1):
        c = feedback.update(k * STEP, (x, 0.0), 0.0, (v, 0.0, 0.0))
        out.append(c.copy())
        x += (v * CYCLE + c[0] - loss) / 4            # the trunk follows the feet
    return out


def test_a_constant_loss_per_stride_is_compensated():
    loss = 0.02                                        # m per stride: -4.4 % at 0.15 m/s
    corrections = _walk(SpeedFeedback(0.5, 0.1, CYCLE, 0.03), loss, cycles=12)
    assert all(np.array_equal(c, [0.0, 0.0]) for c in corrections[:4])   # a full window first
    assert corrections[-1][0] == pytest.approx(loss, abs=1e-4)
    assert abs(corrections[-1][1]) < 1e-12


def test_off_at_gain_zero_and_cleared_by_a_zero_setpoint():
    assert all(not np.any(c) for c in _walk(SpeedFeedback(0.0, 0.1, CYCLE, 0.03), 0.02, cycles=4))
    fb = SpeedFeedback(0.5, 0.1, CYCLE, 0.03)
    _walk(fb, 0.02, cycles=4)
    assert fb.correction[0] > 0
    assert not np.any(fb.update(100.0, (5.0, 0.0), 0.0, (0.0, 0.0, 0.0)))


def test_the_correction_is_limited_and_a_setpoint_change_restarts_the_window():
    fb = SpeedFeedback(1.0, 0.03, CYCLE, 1.0)
    corrections = _walk(fb, 0.2, cycles=6)
    assert max(np.hypot(*c) for c in corrections) == pytest.approx(0.03)
    # A new set-point a third of the old, same direction: the correction carried over scaled
    # with it, then held for a cycle (no full window yet).
    kept = fb.correction * 0.05 / 0.15
    t0 = 100.0
    for k in range(4):
        assert np.array_equal(fb.update(t0 + k * STEP, (k * 0.05, 0.0), 0.0, (0.05, 0, 0)), kept)


def test_a_correction_is_carried_only_along_axes_that_keep_their_direction():
    c = np.array([0.02, -0.01])
    assert np.array_equal(carried_correction(c, (0.15, 0.05, 0.0), (0.30, 0.05, 0.2)),
                          [0.04, -0.01])
    # Forward to sideways: the forward loss is not the sideways one; carried, it would walk
    # the robot on forward.
    assert not np.any(carried_correction(c, (0.15, 0.0, 0.0), (0.0, 0.1, 0.0)))
    assert not np.any(carried_correction(c, (0.15, 0.05, 0.0), (-0.15, -0.05, 0.0)))
    fb = SpeedFeedback(1.0, 0.03, CYCLE, 1.0)
    _walk(fb, 0.2, cycles=6)
    assert fb.correction[0] > 0
    assert not np.any(fb.update(100.0, (5.0, 0.0), 0.0, (0.0, 0.1, 0.0)))


def test_a_push_is_not_integrated():
    """A 15 cm sideways push during a walk: its windows miss by 0.05 m/s, above max_error,
    so the correction the walk had is kept, not turned into a walk back."""
    fb = SpeedFeedback(0.5, 0.1, CYCLE, 0.03)
    _walk(fb, 0.02, cycles=8)
    kept = fb.correction.copy()
    t0, x0 = 8 * CYCLE + STEP, 8 * 0.15 * CYCLE
    for k in range(5):
        pushed = 0.15 if k >= 1 else 0.0                 # m, y, from the second re-plan on
        c = fb.update(t0 + k * STEP, (x0 + k * 0.15 * STEP, pushed), 0.0, (0.15, 0.0, 0.0))
        if k >= 1:
            assert abs(c[1] - kept[1]) < 1e-12, (k, c)


def test_the_acceleration_to_a_new_setpoint_is_not_wound_in():
    """Walking off at 0.05 m/s, the trunk reaches the speed over one cycle (its first window
    misses by 0.025 m/s, under max_error), then holds it exactly: nothing to correct, and
    the correction stays zero, as the first cycle after a set-point change does not count."""
    fb = SpeedFeedback(0.5, 0.1, CYCLE, 0.03)
    x, v = 0.0, 0.05
    for k in range(24):
        t = k * STEP
        c = fb.update(t, (x, 0.0), 0.0, (v, 0.0, 0.0))
        assert np.hypot(*c) < 1e-9, (t, c)
        x += v * STEP * min(1.0, (t + STEP) / CYCLE)      # ramping up over the first cycle


def test_the_crawls_sway_cancels_over_a_window_of_the_same_legs_touchdowns():
    """Re-plans every 0.74 s (a cycle of four is 2.96 s, just under the 3 s window) while the
    trunk sways 2 cm sideways and surges 1 cm with the leg phase and walks exactly at the
    set-point: the window runs from the same leg's touchdown, the sway cancels, and there is
    nothing to correct. (A window from the re-plan at least 3 s back, five steps, left the sway
    in it.)"""
    fb = SpeedFeedback(0.5, 0.1, CYCLE, 0.03)
    v, step = 0.1, 0.74
    for k in range(40):
        t = k * step
        phase = 2.0 * math.pi * k / 4
        xy = (v * t + 0.01 * math.cos(phase), 0.02 * math.sin(phase))
        c = fb.update(t, xy, 0.0, (v, 0.0, 0.0))
        assert np.hypot(*c) < 1e-9, (t, c)


def test_time_going_back_starts_a_new_window():
    fb = SpeedFeedback(0.5, 0.1, CYCLE, 0.03)
    _walk(fb, 0.02, cycles=3)
    kept = fb.correction.copy()
    assert np.array_equal(fb.update(0.0, (0.0, 0.0), 0.0, (0.15, 0.0, 0.0)), kept)


@pytest.mark.parametrize('bad', [(-0.1, 0.1, 3.0, 0.03), (0.5, math.nan, 3.0, 0.03),
                                 (0.5, 0.1, 0.0, 0.03), (0.5, 0.1, 3.0, 0.0)])
def test_bad_settings_are_refused(bad):
    with pytest.raises(ValueError, match='velocity feedback'):
        SpeedFeedback(*bad)


def test_every_stride_of_a_plan_carries_the_correction_in_the_heading_of_its_touchdown():
    params = GaitParams(foothold_correction=False)
    feet = np.array([[0.37, 0.32, 0.02], [0.37, -0.32, 0.02], [-0.37, 0.32, 0.02],
                     [-0.37, -0.32, 0.02]])
    base = np.array([0.0, 0.0, 0.6])
    twist = (0.1, 0.0, 0.1)
    plain = compute_footholds(twist, feet, base, 0.3, None, 2, 0.0, params)
    shifted = compute_footholds(twist, feet, base, 0.3, None, 2, 0.0, params,
                                stride_correction=np.array([0.01, -0.005]))
    expected: dict[int, np.ndarray] = {}
    for a, b in zip(plain.steps, shifted.steps, strict=True):
        c, s = math.cos(b.yaw), math.sin(b.yaw)
        # The k-th stride of a leg in the plan: k corrections, each turned to its touchdown.
        expected[a.leg] = expected.get(a.leg, np.zeros(2)) + np.array(
            [c * 0.01 + s * 0.005, s * 0.01 - c * 0.005])
        np.testing.assert_allclose(b.target[:2] - a.target[:2], expected[a.leg], atol=1e-12)
        assert b.target[2] == a.target[2]
    zero = compute_footholds(twist, feet, base, 0.3, None, 2, 0.0, params,
                             stride_correction=np.zeros(2))
    assert all(np.array_equal(a.target, b.target) for a, b in zip(plain.steps, zero.steps,
                                                                  strict=True))


# ------------------------------------------------------------------------------ step timing
def test_step_timing_is_the_median_interval_of_the_last_cycle():
    timing = StepTiming(STEP, 4)
    timing.touchdown(1.75)                # no interval yet: the planned period
    assert timing.measured_period is None and timing.scale == 1.0
    for t in (2.55, 3.34):                # two intervals, 0.80 and 0.79: their median
        timing.touchdown(t)
    assert timing.measured_period == pytest.approx(0.795, abs=1e-12)
    timing.touchdown(4.14)                # 0.80, 0.79, 0.80: median 0.80
    assert timing.measured_period == pytest.approx(0.80, abs=1e-12)
    for t in (4.93,):
        timing.touchdown(t)
    # intervals 0.80, 0.79, 0.80, 0.79: median 0.795
    assert timing.measured_period == pytest.approx(0.795, abs=1e-12)
    assert timing.scale == pytest.approx(0.795 / STEP, abs=1e-12)
    # One forced touchdown (0.3 s late) leaves the median where it was (0.79, 0.80, 0.79, 1.09).
    timing.touchdown(4.93 + 1.09)
    assert timing.measured_period == pytest.approx(0.795, abs=1e-12)


def test_step_timing_skips_the_stand_and_is_clipped():
    timing = StepTiming(STEP, 2, max_scale=1.25)
    for t in (1.0, 1.8, 2.6):
        timing.touchdown(t)
    assert timing.measured_period == pytest.approx(0.8)
    timing.restart()                       # stood for 10 s
    timing.touchdown(12.6)
    assert timing.measured_period == pytest.approx(0.8)     # no 10 s interval
    for t in (13.8, 15.0):                 # 1.2 s per step: stretched at most 1.25 times
        timing.touchdown(t)
    assert timing.scale == 1.25
    timing.touchdown(15.0)                 # a repeated tick opens no interval
    assert timing.measured_period == pytest.approx(1.2)


@pytest.mark.parametrize('bad', [(0.0, 4), (math.nan, 4), (0.75, 0), (0.75, 4, 0.9)])
def test_bad_step_timing_settings_are_refused(bad):
    with pytest.raises(ValueError):
        StepTiming(*bad)


def test_strides_are_laid_out_for_the_measured_step_period():
    """With the step period stretched by s, every stride is s times the planned one (straight)
    and the feet turn as the trunk will have turned at the later touchdowns (turning); the
    plan's times and yaw references stay as planned."""
    params = GaitParams(foothold_correction=False)
    feet = np.array([[0.37, 0.32, 0.02], [0.37, -0.32, 0.02], [-0.37, 0.32, 0.02],
                     [-0.37, -0.32, 0.02]])
    base = np.array([0.0, 0.0, 0.6])
    scale = 1.056
    for twist in ((0.1, 0.02, 0.0), (0.1, 0.0, 0.15)):
        plain = compute_footholds(twist, feet, base, 0.3, None, 2, 0.0, params)
        fast = compute_footholds(np.array(twist) * scale, feet, base, 0.3, None, 2, 0.0,
                                 params)
        placed = compute_footholds(twist, feet, base, 0.3, None, 2, 0.0, params,
                                   stride_time_scale=scale)
        for a, b, c in zip(plain.steps, fast.steps, placed.steps, strict=True):
            # Footholds as for a twist s times faster; times and yaw as planned.
            np.testing.assert_allclose(c.target, b.target, atol=1e-12)
            assert (c.liftoff_time, c.touchdown_time, c.yaw) == (
                a.liftoff_time, a.touchdown_time, a.yaw)
        if twist[2] == 0.0:
            first = {s.leg: s for s in reversed(placed.steps)}
            for leg, step in first.items():
                stride = step.target[:2] - feet[leg, :2]
                c, s = math.cos(0.3), math.sin(0.3)     # body to world at yaw 0.3 rad
                expected = np.array([[c, -s], [s, c]]) @ np.array(twist[:2]) * 3.0 * scale
                np.testing.assert_allclose(stride, expected, atol=1e-12)
    same = compute_footholds((0.1, 0.0, 0.1), feet, base, 0.3, None, 2, 0.0, params,
                             stride_time_scale=1.0)
    assert all(np.array_equal(a.target, b.target) for a, b in zip(
        compute_footholds((0.1, 0.0, 0.1), feet, base, 0.3, None, 2, 0.0, params).steps,
        same.steps, strict=True))
    # At the set-point limit (0.2 m/s) the strides are the limits' own: not stretched further.
    top = compute_footholds((0.2, 0.0, 0.0), feet, base, 0.3, None, 2, 0.0, params)
    top_placed = compute_footholds((0.2, 0.0, 0.0), feet, base, 0.3, None, 2, 0.0, params,
                                   stride_time_scale=scale)
    assert all(np.array_equal(a.target, b.target) for a, b in zip(top.steps, top_placed.steps,
                                                                  strict=True))
    with pytest.raises(ValueError, match='stride_time_scale'):
        compute_footholds((0.1, 0.0, 0.0), feet, base, 0.3, None, 2, 0.0, params,
                          stride_time_scale=0.0)


# ------------------------------------------------------------------------------ trunk trend
def test_the_trend_of_a_swaying_straight_walk_is_its_line():
    # 0.15 m/s along a heading of 0.7 rad, a sideways sway of 4 cm and a surge of 1 cm at the
    # crawl's cycle and twice it, sampled at the re-plans (one per step): the trend at the
    # newest re-plan is the line without the sway, to rounding.
    heading, v = 0.7, 0.15
    along = np.array([math.cos(heading), math.sin(heading)])
    side = np.array([-math.sin(heading), math.cos(heading)])

    def base(t):
        phase = 2 * math.pi * t / CYCLE
        return (np.array([1.0, -2.0]) + v * t * along + 0.04 * math.sin(phase + 0.3) * side
                + 0.01 * math.cos(2 * phase) * along)

    samples = [_sample(t, base(t), heading) for t in np.arange(6) * STEP + 10.0]
    t_now = samples[-1].t
    np.testing.assert_allclose(trunk_trend(samples, CYCLE),
                               np.array([1.0, -2.0]) + v * t_now * along, atol=1e-12)
    assert np.linalg.norm(samples[-1].xy - (np.array([1.0, -2.0]) + v * t_now * along)) > 0.02


def test_the_trend_of_a_steady_turn_is_on_its_arc():
    v, w = 0.1, 0.2                     # m/s, rad/s
    radius = v / w

    def pose(t):
        return (np.array([radius * math.sin(w * t), radius * (1 - math.cos(w * t))]), w * t)

    samples = [_sample(t, *pose(t), setpoint=(v, 0.0, w)) for t in np.arange(5) * STEP + 3.0]
    np.testing.assert_allclose(trunk_trend(samples, CYCLE), pose(samples[-1].t)[0], atol=1e-12)


def test_no_trend_without_a_cycle_at_the_set_point():
    samples = [_sample(t, (0.15 * t, 0.0)) for t in np.arange(5) * STEP]
    assert trunk_trend(samples, CYCLE) is not None
    assert trunk_trend(samples[-2:], CYCLE) is None            # half a cycle: not yet
    assert trunk_trend([], CYCLE) is None
    changed = [*samples[:-1], _sample(samples[-1].t, samples[-1].xy, setpoint=(0.1, 0, 0))]
    assert trunk_trend(changed, CYCLE) is None                 # on its way to the new speed
