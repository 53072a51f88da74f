import numpy as np
import pytest

from replan_core.evaluation.metrics import (
    FallLimits,
    Segment,
    achieved_velocity,
    command_segments,
    detect_fall,
    distance_travelled,
    leg_cycle_velocities,
    rise_time,
    roll_pitch_yaw,
    steady_velocity,
    tracking_errors,
    whole_cycles,
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
    # The body velocity integrated along the 9 s arc of 1.8 rad: the speed walked (the chord
    # of the displacement would read 0.1 sin(0.9) / 0.9 = 0.087).
    assert vx == pytest.approx(0.1, rel=0.002)
    assert abs(vy) < 0.0005
    assert wz == pytest.approx(0.2, rel=0.01)
    assert rows[0]['achieved'] == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)


def test_whole_cycles_take_out_the_sway():
    """A trunk that walks 0.1 m/s sideways with a 0.03 m/s sway of the 3.2 s crawl cycle: over
    the segment after settling (not whole cycles) the mean keeps part of the sway, over the
    whole cycles between one leg's touchdowns it is the walk's speed."""
    dt, cycle = 0.004, 3.2
    t = np.arange(0.0, 13.8, dt)
    vy = np.where(t < 1.0, 0.0, 0.1 + 0.03 * np.sin(2 * np.pi * (t - 1.0) / cycle))
    pos = np.stack([np.zeros_like(t), np.concatenate([[0.0], np.cumsum(vy[:-1] * dt)])], 1)
    yaw = np.zeros_like(t)
    touchdowns = [(1.0 + cycle * (k + leg / 4.0), leg) for k in range(5) for leg in range(4)]
    segs = command_segments([(1.0, (0.0, 0.1, 0.0))], end_time=13.8)
    swaying, = [r for r in tracking_errors(t, pos, yaw, segs, settle=2.0) if any(r['commanded'])]
    row, = [r for r in tracking_errors(t, pos, yaw, segs, settle=2.0, touchdowns=touchdowns)
            if any(r['commanded'])]
    assert swaying['achieved'][1] < 0.098                      # the sway left in: not whole
    assert row['achieved'] == swaying['achieved']
    assert row['achieved_cycles'][1] == pytest.approx(0.1, abs=2e-4)
    assert row['cycles'] == 3
    assert row['cycles_span_s'][1] - row['cycles_span_s'][0] == pytest.approx(3 * cycle)
    assert whole_cycles(touchdowns, 3.0, 5.0) is None             # no leg touches down twice
    assert whole_cycles([], 0.0, 10.0) is None


def test_each_legs_cycles_show_a_catch_up_that_one_legs_cycles_hide():
    """Told 0.1 m/s sideways at 1 s, a trunk walks 0.05 m/s for a second (a 5 cm lag), then
    0.15 m/s for a second (the catch-up), then 0.1 m/s. The legs land 0.8 s apart in a 3.2 s
    cycle: leg 0's first cycle holds the lag and the catch-up and reads the set-point; leg
    1's and 2's hold only part of the lag and all of the catch-up."""
    dt, cycle = 0.004, 3.2
    t = np.arange(0.0, 14.0, dt)
    vy = np.select([t < 1.0, t < 2.0, t < 3.0], [0.0, 0.05, 0.15], 0.1)
    pos = np.stack([np.zeros_like(t), np.concatenate([[0.0], np.cumsum(vy[:-1] * dt)])], 1)
    yaw = np.zeros_like(t)
    touchdowns = [(1.0 + cycle * k + 0.8 * leg, leg) for k in range(4) for leg in range(4)]
    row, = [r for r in tracking_errors(t, pos, yaw, command_segments(
        [(1.0, (0.0, 0.1, 0.0))], end_time=14.0), settle=2.0, touchdowns=touchdowns)
        if any(r['commanded'])]
    assert row['cycle_velocities'][0]['velocity'][1] == pytest.approx(0.1, abs=1e-3)
    legs = row['leg_cycle_velocities']
    assert legs == leg_cycle_velocities(t, pos, yaw, touchdowns, 1.0, 14.0)
    assert [leg['leg'] for leg in legs] == [0, 1, 2, 3]           # in the order they land
    first = [leg['cycles'][0]['velocity'][1] for leg in legs]
    # leg 1: (0.2 s x 0.05 + 0.15 + 2 s x 0.1) / 3.2 s; leg 2: (0.4 s x 0.15 + 2.8 s x 0.1) / 3.2
    assert first == pytest.approx([0.1, 0.36 / 3.2, 0.34 / 3.2, 0.1], abs=1e-3)
    assert [len(leg['cycles']) for leg in legs] == [3, 3, 3, 3]
    assert all(c['velocity'][1] == pytest.approx(0.1, abs=1e-3)
               for leg in legs for c in leg['cycles'][1:])
    assert leg_cycle_velocities(t, pos, yaw, touchdowns, 3.0, 5.0) == []   # none lands twice


def test_achieved_velocity_on_a_known_arc():
    """0.05 m/s forward and 0.2 rad/s, 18 s (the chord read 0.026-0.028 m/s),
    sampled exactly on the circle at 250 Hz; and sideways on a circle."""
    t = np.arange(0.0, 18.0 + 1e-9, 0.004)
    v, w = 0.05, 0.2
    yaw = w * t
    forward = np.stack([v / w * np.sin(yaw), v / w * (1.0 - np.cos(yaw))], axis=1)
    vx, vy, wz = achieved_velocity(t, forward, yaw, 0.0, 18.0)
    assert vx == pytest.approx(v, rel=1e-5) and abs(vy) < 1e-7 and wz == pytest.approx(w)
    sideways = np.stack([-v / w * (1.0 - np.cos(yaw)), v / w * np.sin(yaw)], axis=1)
    vx, vy, _ = achieved_velocity(t, sideways, yaw, 0.0, 18.0)
    assert abs(vx) < 1e-7 and vy == pytest.approx(v, rel=1e-5)
    # Straight, heading 30 deg: the world displacement in the body frame.
    heading = np.full_like(t, np.pi / 6)
    line = np.outer(t, [np.cos(np.pi / 6), np.sin(np.pi / 6)]) * v
    vx, vy, wz = achieved_velocity(t, line, heading, 1.0, 17.0)
    assert vx == pytest.approx(v, rel=1e-9) and abs(vy) < 1e-12 and wz == 0.0


def test_achieved_velocity_needs_two_samples():
    t = np.array([0.0, 1.0])
    assert achieved_velocity(t, np.zeros((2, 2)), np.zeros(2), 5.0, 6.0) is None


def test_distance_travelled():
    pos = np.array([[0, 0], [3, 0], [3, 4]], dtype=float)
    assert distance_travelled(pos) == (5.0, 7.0)


def test_interval_stats_skips_the_start():
    from replan_core.evaluation.metrics import interval_stats
    stats = interval_stats(np.array([0.0, 1.4, 2.1, 2.8, 3.6]), skip=1)
    assert stats['count'] == 3
    assert stats['median'] == pytest.approx(0.7) and stats['max'] == pytest.approx(0.8)
    assert interval_stats(np.array([1.0]), skip=0) is None


def test_polygon_margin_inside_outside_and_degenerate():
    from replan_core.evaluation.metrics import polygon_margin
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert polygon_margin([0.5, 0.5], square) == pytest.approx(0.5)
    assert polygon_margin([0.9, 0.5], square[[2, 0, 3, 1]]) == pytest.approx(0.1)  # any order
    assert polygon_margin([1.5, 0.5], square) == pytest.approx(-0.5)
    assert polygon_margin([0.5, 0.5], square[:2]) == pytest.approx(-0.5)    # a segment
    assert polygon_margin([0.5, 0.0], square[:2]) == pytest.approx(0.0)


def test_cop_margin_follows_the_loaded_feet():
    from replan_core.evaluation.metrics import cop_margins
    feet = np.array([[[0.4, 0.3, 0], [0.4, -0.3, 0], [-0.4, 0.3, 0], [-0.4, -0.3, 0]]])
    forces = np.zeros((1, 4, 3))
    forces[0, :, 2] = [200.0, 200.0, 200.0, 200.0]
    cop, margin = cop_margins(feet, forces)
    np.testing.assert_allclose(cop[0], [0.0, 0.0], atol=1e-12)
    assert margin[0] == pytest.approx(0.3)
    forces[0, 3, 2] = 0.0                       # rh in swing: the triangle lf rf lh
    cop, margin = cop_margins(feet, forces)
    assert cop[0, 0] == pytest.approx(0.4 / 3) and margin[0] > 0
    forces[0, :, 2] = [0.0, 300.0, 300.0, 0.0]  # the diagonal only: no inside
    _, margin = cop_margins(feet, forces)
    assert margin[0] == pytest.approx(0.0, abs=1e-12)


def test_touchdown_timing_matches_executed_steps_only():
    from replan_core.evaluation.metrics import touchdown_timing
    planned = [(0.0, 2, 0.25, 0.75), (0.0, 0, 1.0, 1.5),     # lf superseded at 0.76
               (0.76, 0, 1.01, 1.51)]
    touchdowns = [(0.76, 2), (0.5, 1), (1.1, 0), (1.55, 0), (1.6, 2)]   # 0.5 rf, 1.6 lh: flicker
    errors, actual = touchdown_timing(touchdowns, planned)
    np.testing.assert_allclose(errors, [0.01, 0.04])
    np.testing.assert_allclose(actual, [0.76, 1.55])


def test_estimator_errors_and_peaks():
    from replan_core.evaluation.metrics import estimator_errors, peaks_around
    t = np.linspace(0.0, 10.0, 101)
    true = np.stack([0.1 * t, 0 * t, 0.6 + 0 * t], axis=1)
    est = true + np.array([0.0, 0.01, 0.0]) * t[:, None] / 10.0
    vel = np.tile([0.1, 0.0, 0.0], (101, 1))
    errors = estimator_errors(t, est, true, vel + 0.01, vel)
    assert errors['xy_error_end_m'] == pytest.approx(0.01)
    assert errors['xy_drift_fraction'] == pytest.approx(0.01)
    assert errors['velocity_rmse_mps'] == pytest.approx(0.01 * np.sqrt(3))
    pitch = np.where(np.abs(t - 5.0) < 0.15, 0.02, 0.0)
    np.testing.assert_allclose(peaks_around(t, pitch, np.array([5.0, 8.0])), [0.02, 0.0])


def test_planned_zmp_follows_the_newest_plan():
    from replan_core.evaluation.metrics import planned_zmp_at
    first = (0.0, np.array([0.0, 1.0]), np.array([[0.0, 0.0], [1.0, -1.0]]))
    second = (0.5, np.array([0.5, 1.5]), np.array([[5.0, 5.0], [6.0, 5.0]]))
    zmp = planned_zmp_at(np.array([-0.1, 0.25, 0.75]), [second, first])
    assert np.all(np.isnan(zmp[0]))
    np.testing.assert_allclose(zmp[1:], [[0.25, -0.25], [5.25, 5.0]])


def test_settle_time_of_a_velocity_step():
    from replan_core.evaluation.metrics import Segment, settle_time
    times = np.arange(0.0, 10.0, 0.01)
    # 0.1 m/s until 4 s, then a first-order rise to 0.2 m/s (time constant 0.5 s)
    speed = np.where(times < 4.0, 0.1, 0.2 - 0.1 * np.exp(-(times - 4.0) / 0.5))
    x = np.concatenate([[0.0], np.cumsum(speed[1:] * np.diff(times))])
    positions = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.5)])
    settle = settle_time(times, positions, np.zeros_like(times),
                         Segment(4.0, 10.0, (0.2, 0.0, 0.0)), window=1.0, tolerance=0.1)
    # for s >= 1 s the trailing 1 s mean is 0.2 - 0.05 e^(-2 s) (e^2 - 1): 0.18 m/s at
    # s = 0.5 ln((e^2 - 1) / 0.4) = 1.385 s
    assert settle == pytest.approx(0.5 * np.log((np.exp(2.0) - 1.0) / 0.4), abs=0.02)
    never = settle_time(times, positions, np.zeros_like(times),
                        Segment(4.0, 10.0, (0.4, 0.0, 0.0)))
    assert never is None


def test_support_inradius_after_a_push():
    from replan_core.evaluation.metrics import support_inradius_after, triangle_inradius
    assert triangle_inradius(np.array([[0, 0], [3, 0], [0, 4]])) == pytest.approx(1.0)
    square = np.array([[0.4, 0.2, 0], [0.4, -0.2, 0], [-0.4, 0.2, 0], [-0.4, -0.2, 0]])
    times = np.arange(0.0, 4.0, 0.1)
    feet = np.repeat(square[None], len(times), axis=0)
    in_contact = np.ones((len(times), 4), dtype=bool)
    for k, leg in enumerate([2, 0, 3, 1]):           # four swings of 0.5 s from 0.5 s
        in_contact[(times >= 0.5 + k * 0.8) & (times < 1.0 + k * 0.8), leg] = False
    feet[times >= 2.0, 0, 1] = 0.05                  # a narrower lf foothold after 2 s
    whole = support_inradius_after(times, feet, in_contact, 0.0, steps=4)
    first = support_inradius_after(times, feet, in_contact, 0.0, steps=2)
    assert first == pytest.approx(triangle_inradius(square[[0, 1, 3]][:, :2]))
    assert whole < first
    assert support_inradius_after(times, feet, in_contact, 3.9) is None


def test_rise_time_ignores_a_steady_offset():
    """A step 0.1 -> 0.2 m/s commanded, 0.09 -> 0.18 achieved (10 % short): never within 10 %
    of the set-point for long, but the change itself is followed as fast as the response."""
    from replan_core.evaluation.metrics import Segment, rise_time
    times = np.arange(0.0, 12.0, 0.01)
    speed = np.where(times < 4.0, 0.09, 0.18 - 0.09 * np.exp(-(times - 4.0) / 0.5))
    x = np.concatenate([[0.0], np.cumsum(speed[1:] * np.diff(times))])
    positions = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.5)])
    yaws = np.zeros_like(times)
    before, after = Segment(0.0, 4.0, (0.1, 0.0, 0.0)), Segment(4.0, 12.0, (0.2, 0.0, 0.0))
    rise = rise_time(times, positions, yaws, before, after)
    # trailing 1 s mean for s >= 1: 0.18 - 0.045 e^(-2 s) (e^2 - 1); 90 % of the way (0.171)
    # at s = 0.5 ln(0.045 (e^2 - 1) / 0.009)
    assert rise == pytest.approx(0.5 * np.log(0.045 * (np.exp(2.0) - 1.0) / 0.009), abs=0.02)
    assert rise_time(times, positions, yaws, before, Segment(4.0, 12.0, (0.1, 0.0, 0.0))) is None


def test_the_steady_state_is_the_last_whole_cycles_after_the_trunk_got_to_the_speed():
    """A trunk that gets to 0.1 m/s sideways with a 3 s time constant (it falls behind its
    feet while it accelerates) and sways with the 3.2 s crawl cycle: the whole cycles after
    2 s of settling still hold part of the acceleration, the last two do not."""
    dt, cycle, tau = 0.004, 3.2, 3.0
    t = np.arange(0.0, 22.0, dt)
    ramp = np.where(t < 1.0, 0.0, 1.0 - np.exp(-(t - 1.0) / tau))
    vy = 0.1 * ramp + np.where(t < 1.0, 0.0, 0.03 * np.sin(2 * np.pi * (t - 1.0) / cycle))
    pos = np.stack([np.zeros_like(t), np.concatenate([[0.0], np.cumsum(vy[:-1] * dt)])], 1)
    yaw = np.zeros_like(t)
    touchdowns = [(1.0 + cycle * (k + leg / 4.0), leg) for k in range(7) for leg in range(4)]
    segs = command_segments([(1.0, (0.0, 0.1, 0.0))], end_time=22.0)
    row, = [r for r in tracking_errors(t, pos, yaw, segs, settle=2.0, touchdowns=touchdowns)
            if any(r['commanded'])]
    per_cycle = row['cycle_velocities']
    assert len(per_cycle) == 6                                   # leg 0: 1.0 to 20.2 s
    assert [c['start_s'] for c in per_cycle] == pytest.approx([1.0 + cycle * k
                                                               for k in range(6)])
    assert np.all(np.diff([c['velocity'][1] for c in per_cycle]) > 0)   # getting to speed
    assert row['steady_cycles'] == 2
    assert row['achieved_steady'] == pytest.approx(
        steady_velocity(per_cycle, 2), abs=1e-12)
    # The mean over the last two cycles, against the exact mean of 0.1 * ramp over them.
    t0, t1 = per_cycle[-2]['start_s'], per_cycle[-1]['end_s']
    exact = 0.1 - 0.1 * tau * (np.exp(-(t0 - 1.0) / tau) - np.exp(-(t1 - 1.0) / tau)) / (t1 - t0)
    assert row['achieved_steady'][1] == pytest.approx(exact, abs=2e-4)
    assert row['achieved_steady'][1] > 0.098 > 0.095 > row['achieved_cycles'][1]
    assert steady_velocity(per_cycle, 7) is None and steady_velocity([], 1) is None
    # Rise to 90 % of the change: later against the steady state than against the mean that
    # keeps the acceleration in.
    before, after = command_segments([(1.0, (0.0, 0.1, 0.0))], end_time=22.0)
    early = rise_time(t, pos, yaw, Segment(before.start, before.end, (0.0, 0.05, 0.0)), after)
    late = rise_time(t, pos, yaw, Segment(before.start, before.end, (0.0, 0.05, 0.0)), after,
                     achieved_after=row['achieved_steady'])
    assert late > early
