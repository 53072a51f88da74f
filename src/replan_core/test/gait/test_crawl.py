"""Crawl schedule and footholds (gait/crawl.py)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from replan_core.common.types import LEGS
from replan_core.gait.crawl import (
    DEFAULT_SEQUENCE,
    CrawlSchedule,
    GaitParams,
    IdleMonitor,
    ReferenceTrajectory,
    clamp_velocity,
    compute_footholds,
    is_idle_trigger,
    is_stand_plan,
    stance_phases,
    stand_plan,
)
from replan_core.gait.touchdown import StepTracker
from replan_core.mpc.lip_mpc import STATUS_SOLVED, LipMpc
from replan_core.mpc.settings import MpcSettings
from replan_core.mpc.support import support_schedule

TOL = 1e-9
HEIGHT = 0.58   # m, trunk
FOOT_Z = 0.02   # m, sole centre above the ground


def rot(yaw):
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def hips_of(params, base_xy, yaw):
    xy = np.asarray(base_xy) + np.asarray(params.hip_offsets) @ rot(yaw).T
    return np.column_stack([xy, np.full(4, HEIGHT)])


def nominal(params, leg):
    """Nominal foot of ``leg`` in the base frame, xy."""
    return np.asarray(params.hip_offsets[leg]) + np.asarray(params.stance_offsets[leg])


def standing_feet(params, base_xy=(0.0, 0.0), yaw=0.0):
    xy = np.asarray(base_xy) + np.array([nominal(params, leg) for leg in range(4)]) @ rot(yaw).T
    return np.column_stack([xy, np.full(4, FOOT_Z)])


def steady_feet(params, twist, t0, next_leg, base_xy=(0.0, 0.0), yaw=0.0):
    """Feet where a robot that has been walking with ``twist`` for a while has them: each on its
    previous foothold, the reference foot at the middle of its current stance."""
    ref = ReferenceTrajectory(t0, np.asarray(base_xy, dtype=float), yaw, np.asarray(twist))
    feet = standing_feet(params, base_xy, yaw)
    order = params.sequence
    k0 = order.index(next_leg)
    for j in range(4):
        leg = order[(k0 + j) % 4]
        touchdown = t0 + params.four_feet_duration + params.swing_duration + j * params.step_period
        mid = touchdown - params.cycle_duration + 0.5 * params.stance_duration
        feet[leg, :2] = ref.foot(mid, nominal(params, leg))
    return feet


def plan_for(v, params=None, base_xy=(0.0, 0.0), yaw=0.0, feet=None, next_leg=2, t0=10.0,
             delay=0.0, n=None):
    params = params or GaitParams()
    feet = standing_feet(params, base_xy, yaw) if feet is None else feet
    base = np.array([base_xy[0], base_xy[1], HEIGHT])
    return compute_footholds(v, feet, base, yaw, hips_of(params, base_xy, yaw), next_leg, t0,
                             params, n=n, delay=delay)


def legs_first_last(plan):
    first, last = {}, {}
    for step in plan.steps:
        first.setdefault(step.leg, step)
        last[step.leg] = step
    return first, last


def test_default_sequence_is_lh_lf_rh_rf():
    assert [LEGS[i] for i in DEFAULT_SEQUENCE] == ['lh', 'lf', 'rh', 'rf']


def test_schedule_timing_order_and_flags():
    params = GaitParams()
    plan = plan_for((0.1, 0.0, 0.0), params, next_leg=LEGS.index('rh'), t0=3.0)
    assert len(plan.steps) == 8
    assert [LEGS[s.leg] for s in plan.steps] == ['rh', 'rf', 'lh', 'lf'] * 2
    lo = 3.0 + params.four_feet_duration
    for step in plan.steps:
        assert step.liftoff_time == pytest.approx(lo, abs=TOL)
        assert step.touchdown_time == pytest.approx(lo + params.swing_duration, abs=TOL)
        assert step.haptic and step.replan
        assert step.step_height == params.step_height
        lo = step.touchdown_time + params.four_feet_duration
    # The paper's 8 footholds span its 8 s horizon with the defaults.
    assert plan.steps[-1].touchdown_time - plan.start_time == pytest.approx(
        params.n_footholds * params.step_period, abs=TOL)


def test_start_delay_stands_first():
    plan = plan_for((0.1, 0.0, 0.0), delay=1.5, t0=0.0)
    assert plan.steps[0].liftoff_time == pytest.approx(1.5, abs=TOL)


def test_replan_window_flags_every_kth_step():
    params = GaitParams(replan_window=2, haptic=False)
    plan = plan_for((0.0, 0.0, 0.0), params)
    assert [s.replan for s in plan.steps] == [False, True] * 4
    assert not any(s.haptic for s in plan.steps)


def test_schedule_continues_across_replans():
    schedule = CrawlSchedule()
    assert LEGS[schedule.next_leg] == 'lh'
    seen = []
    for _ in range(6):
        leg = schedule.next_leg
        seen.append(LEGS[leg])
        schedule.touched_down(leg)
    assert seen == ['lh', 'lf', 'rh', 'rf', 'lh', 'lf']


@pytest.mark.parametrize('correction', [True, False])
@pytest.mark.parametrize('yaw', [0.0, 0.7])
def test_zero_set_point_keeps_nominal_stance(correction, yaw):
    params = GaitParams(foothold_correction=correction)
    plan = plan_for((0.0, 0.0, 0.0), params, base_xy=(1.0, -2.0), yaw=yaw)
    feet = standing_feet(params, (1.0, -2.0), yaw)
    for step in plan.steps:
        np.testing.assert_allclose(step.target, feet[step.leg], atol=TOL)
        assert step.yaw == pytest.approx(yaw, abs=TOL)


def test_nominal_stance_offsets_apply():
    params = GaitParams(stance_offsets=((0.02, 0.05), (0.0, -0.05), (0.0, 0.05), (0.0, -0.05)))
    plan = plan_for((0.0, 0.0, 0.0), params)
    hips = hips_of(params, (0.0, 0.0), 0.0)
    for step in plan.steps:
        np.testing.assert_allclose(step.target[:2] - hips[step.leg, :2],
                                   params.stance_offsets[step.leg], atol=TOL)


@pytest.mark.parametrize('correction', [True, False])
@pytest.mark.parametrize('v', [(0.15, 0.0), (0.0, 0.1), (-0.1, 0.05)])
def test_linear_set_point_advances_footholds_by_v_times_t(correction, v):
    params = GaitParams(foothold_correction=correction)
    yaw = 0.3
    twist = (v[0], v[1], 0.0)
    feet = steady_feet(params, twist, 10.0, 2, yaw=yaw)
    plan = plan_for(twist, params, yaw=yaw, feet=feet)
    v_world = rot(yaw) @ np.array(v)
    feet = standing_feet(params, (0.0, 0.0), yaw)
    first, last = legs_first_last(plan)
    half_stance = 0.5 * params.stance_duration
    for leg, step in last.items():
        # Exact: the last foothold is the nominal foot carried by v until its mid-stance.
        t_mid = step.touchdown_time + half_stance - plan.start_time
        np.testing.assert_allclose(step.target[:2] - feet[leg, :2], v_world * t_mid, atol=1e-6)
    # Loose, the wording: over the horizon T the footholds advance by about v T.
    horizon = plan.steps[-1].touchdown_time - plan.start_time
    advance = np.mean([last[leg].target[:2] - feet[leg, :2] for leg in range(4)], axis=0)
    assert np.linalg.norm(advance - v_world * horizon) <= 0.5 * np.linalg.norm(v_world) * (
        params.cycle_duration + params.stance_duration) + 1e-9
    # Consecutive footholds of a leg are one stride (v times a cycle) apart.
    for leg in range(4):
        steps = [s for s in plan.steps if s.leg == leg]
        np.testing.assert_allclose(steps[1].target[:2] - steps[0].target[:2],
                                   v_world * params.cycle_duration, atol=1e-9)
    for leg, step in first.items():
        t_mid = step.touchdown_time + half_stance - plan.start_time
        np.testing.assert_allclose(step.target[:2] - feet[leg, :2], v_world * t_mid, atol=1e-9)


@pytest.mark.parametrize('correction', [True, False])
def test_walking_off_from_standing(correction):
    # From the nominal stance the first footholds are clamped if the set-point asks for more.
    params = GaitParams(foothold_correction=correction, correction_threshold=0.0)
    v = 0.05
    plan = plan_for((v, 0.0, 0.0), params, t0=0.0, delay=1.0)
    feet = standing_feet(params)
    first, last = legs_first_last(plan)
    for leg in range(4):
        assert first[leg].target[0] > feet[leg, 0]
        assert last[leg].target[0] - first[leg].target[0] == pytest.approx(
            v * params.cycle_duration)
    if correction:   # about the hips: the reference starts to move after the delay
        for leg, step in first.items():
            t_move = step.touchdown_time + 0.5 * params.stance_duration - 1.0
            assert step.target[0] - feet[leg, 0] == pytest.approx(v * t_move, abs=1e-9)


@pytest.mark.parametrize('old, new', [((0.15, 0.0, 0.0), (0.0, 0.1, 0.0)),
                                      ((0.0, 0.1, 0.0), (0.0, 0.0, 0.2)),
                                      ((0.0, 0.0, 0.0), (0.15, 0.0, 0.0))])
def test_a_setpoint_change_gives_the_new_pattern_from_the_first_step(old, new):
    """Feet in the steady pattern of ``old``: with the twist each was placed for, every first
    foothold is where the new reference puts it (its hip at mid-stance), with no foothold
    correction at all; without, it keeps the old pattern's stagger."""
    params = GaitParams(foothold_correction=False)
    t0, base = 10.0, np.array([0.0, 0.0, HEIGHT])
    feet = steady_feet(params, old, t0, next_leg=2)
    ref = ReferenceTrajectory(t0, np.zeros(2), 0.0, np.asarray(new))
    placed = np.tile(np.asarray(old, dtype=float), (4, 1))
    until = np.full(4, t0)                             # the set-point changes now
    plan = compute_footholds(new, feet, base, 0.0, None, 2, t0, params, placed_twists=placed,
                             placed_until=until, placed_poses=np.zeros((4, 3)))
    stale = compute_footholds(new, feet, base, 0.0, None, 2, t0, params)
    first, _ = legs_first_last(plan)
    first_stale, _ = legs_first_last(stale)
    half_stance = 0.5 * params.stance_duration
    worst_stale = 0.0
    for leg, step in first.items():
        hip_at_mid = ref.foot(step.touchdown_time + half_stance, nominal(params, leg))
        np.testing.assert_allclose(step.target[:2], hip_at_mid, atol=1e-9)
        worst_stale = max(worst_stale, np.linalg.norm(first_stale[leg].target[:2] - hip_at_mid))
    assert worst_stale > 0.05     # m: the old stagger, which the feed-forward removes
    # The same twist as placed: the plan of today, bit for bit.
    same = compute_footholds(old, feet, base, 0.0, None, 2, t0, params, placed_twists=placed,
                             placed_until=np.full(4, np.inf))
    plain = compute_footholds(old, feet, base, 0.0, None, 2, t0, params)
    assert all(np.array_equal(a.target, b.target)
               for a, b in zip(same.steps, plain.steps, strict=True))


def test_a_leg_not_yet_stepped_since_a_change_takes_the_old_reference_up_to_the_change():
    """The set-point changed one step ago and the trunk has followed the new reference since:
    the legs that have not stepped yet are placed from the old reference up to the change and
    the new one after it, so they land where the new reference puts their hips."""
    params = GaitParams(foothold_correction=False)
    old, new = np.array([0.15, 0.0, 0.0]), np.array([0.0, 0.1, 0.0])
    t_change = 10.0
    feet = steady_feet(params, old, t_change, next_leg=2)
    ref = ReferenceTrajectory(t_change, np.zeros(2), 0.0, new)
    t1 = t_change + params.step_period                 # the next re-plan
    base_xy, _ = ref.pose(t1)
    placed = np.tile(old, (4, 1))
    placed[2] = new                                    # lh stepped with the new set-point
    feet[2, :2] = ref.foot(t_change + params.four_feet_duration + params.swing_duration
                           + 0.5 * params.stance_duration, nominal(params, 2))
    until = np.array([t_change, t_change, np.inf, t_change])
    poses = np.zeros((4, 3))                           # the base at the change
    plan = compute_footholds(new, feet, np.array([*base_xy, HEIGHT]), 0.0, None, 0, t1, params,
                             placed_twists=placed, placed_until=until, placed_poses=poses)
    first, _ = legs_first_last(plan)
    for leg, step in first.items():
        hip_at_mid = ref.foot(step.touchdown_time + 0.5 * params.stance_duration,
                              nominal(params, leg))
        np.testing.assert_allclose(step.target[:2], hip_at_mid, atol=1e-9)


def test_yaw_set_point_rotates_footholds_about_the_com():
    params = GaitParams(correction_threshold=0.0)      # every first foothold about the hips
    wz, yaw0, base_xy = 0.2, 0.4, np.array([0.5, 0.3])
    plan = plan_for((0.0, 0.0, wz), params, base_xy=base_xy, yaw=yaw0)
    half_stance = 0.5 * params.stance_duration
    for step in plan.steps:
        offset = nominal(params, step.leg)
        rel = step.target[:2] - base_xy
        assert np.linalg.norm(rel) == pytest.approx(np.linalg.norm(offset), abs=1e-9)
        angle = yaw0 + wz * (step.touchdown_time + half_stance - plan.start_time)
        np.testing.assert_allclose(rel, rot(angle) @ offset, atol=1e-9)
        assert step.yaw == pytest.approx(yaw0 + wz * (step.touchdown_time - plan.start_time),
                                         abs=TOL)


def test_turning_while_walking_follows_the_arc():
    params = GaitParams()
    twist = np.array([0.1, 0.0, 0.1])
    plan = plan_for(twist, params, feet=steady_feet(params, twist, 10.0, 2))
    ref = ReferenceTrajectory(plan.start_time, np.zeros(2), 0.0, twist)
    half_stance = 0.5 * params.stance_duration
    for step in plan.steps:
        expected = ref.foot(step.touchdown_time + half_stance, nominal(params, step.leg))
        np.testing.assert_allclose(step.target[:2], expected, atol=1e-9)
    # The arc itself: radius v / wz about the centre (0, v / wz).
    centre = np.array([0.0, twist[0] / twist[2]])
    for t in (0.0, 3.0, 7.5):
        p, _ = ref.pose(plan.start_time + t)
        assert np.linalg.norm(p - centre) == pytest.approx(twist[0] / twist[2], abs=1e-12)


def test_foothold_correction_follows_the_hips_after_a_lateral_push():
    params_on = GaitParams(foothold_correction=True)
    params_off = GaitParams(foothold_correction=False)
    push = np.array([0.0, 0.15])          # the CoM was pushed 15 cm to the left
    feet = standing_feet(params_on)       # the feet stayed where they were
    on = plan_for((0.0, 0.0, 0.0), params_on, base_xy=push, feet=feet)
    off = plan_for((0.0, 0.0, 0.0), params_off, base_xy=push, feet=feet)
    hips = hips_of(params_on, push, 0.0)
    first_on, _ = legs_first_last(on)
    first_off, _ = legs_first_last(off)
    for leg in range(4):
        np.testing.assert_allclose(first_on[leg].target[:2],
                                   hips[leg, :2] + params_on.stance_offsets[leg], atol=TOL)
        np.testing.assert_allclose(first_off[leg].target[:2], feet[leg, :2], atol=TOL)
        assert np.linalg.norm(first_off[leg].target[:2] - first_on[leg].target[:2]) == (
            pytest.approx(0.15))
    # Later footholds keep the first one's placement (stride only).
    for plan in (on, off):
        for leg in range(4):
            steps = [s for s in plan.steps if s.leg == leg]
            np.testing.assert_allclose(steps[1].target, steps[0].target, atol=TOL)


def test_correction_uses_the_actual_hips_not_the_nominal_offsets():
    params = GaitParams(correction_threshold=0.0)
    feet = standing_feet(params)
    hips = hips_of(params, (0.0, 0.0), 0.0)
    hips[:, 1] += 0.01                    # e.g. a rolled trunk moves the hips sideways
    plan = compute_footholds((0.0, 0.0, 0.0), feet, np.array([0.0, 0.0, HEIGHT]), 0.0, hips, 2,
                             0.0, params)
    first, _ = legs_first_last(plan)
    for leg in range(4):
        np.testing.assert_allclose(first[leg].target[:2],
                                   hips[leg, :2] + params.stance_offsets[leg], atol=TOL)


def test_correction_threshold_keeps_small_deviations_foot_relative():
    # 5 cm off (the crawl's own sway): below the 10 cm default, the first footholds stay
    # foot-relative (no lag feedback in steady walking); 15 cm (a push): they move to the hips.
    params = GaitParams()
    feet = standing_feet(params)
    for shift, follows_hips in ((0.05, False), (0.15, True)):
        push = np.array([0.0, shift])
        plan = plan_for((0.0, 0.0, 0.0), params, base_xy=push, feet=feet)
        hips = hips_of(params, push, 0.0)
        first, _ = legs_first_last(plan)
        for leg in range(4):
            expected = (hips[leg, :2] + params.stance_offsets[leg] if follows_hips
                        else feet[leg, :2])
            np.testing.assert_allclose(first[leg].target[:2], expected, atol=TOL)


def test_a_stopping_plan_puts_the_feet_about_the_hips_below_the_threshold_too():
    # Coming to rest (a rest offset given), the 5 cm common offset that a walking plan keeps
    # foot-relative goes: the feet land about the hips, shifted by the rest offset.
    params = GaitParams()
    feet = standing_feet(params)
    push = np.array([0.0, 0.05])
    base = np.array([push[0], push[1], HEIGHT])
    hips = hips_of(params, push, 0.0)
    rest = np.array([0.02, -0.01])
    for rest_offset, about_hips in ((None, False), (rest, True)):
        plan = compute_footholds((0.0, 0.0, 0.0), feet, base, 0.0, hips, 2, 10.0, params,
                                 rest_offset=rest_offset)
        first, _ = legs_first_last(plan)
        for leg in range(4):
            expected = (hips[leg, :2] + params.stance_offsets[leg] + rest if about_hips
                        else feet[leg, :2])
            np.testing.assert_allclose(first[leg].target[:2], expected, atol=TOL)


def test_sway_free_correction_restores_the_pattern_and_leaves_a_small_common_offset():
    # About sway-free hips (the trunk's trend), every first foothold goes back to its place in
    # the pattern: one foot 6 cm off it is put back. An offset common to all four feet below the
    # threshold (the trunk lagging its feet) stays, for the velocity feedback; a 15 cm one (a
    # push) is followed.
    params = GaitParams()
    plain = replace(params, foothold_correction=False)
    feet = standing_feet(params)
    off = feet.copy()
    off[0, :2] += (0.06, -0.02)
    for shift, followed in ((0.0, False), (0.05, False), (0.15, True)):
        base = np.array([0.0, shift])
        hips = hips_of(params, base, 0.0)
        corrected = compute_footholds((0.0, 0.0, 0.0), off, np.array([*base, HEIGHT]), 0.0,
                                      hips, 2, 10.0, params, trend_shift=np.zeros(2))
        nominal_plan = compute_footholds((0.0, 0.0, 0.0), feet, np.array([*base, HEIGHT]), 0.0,
                                         hips, 2, 10.0, plain)
        # The same hips given as the actual ones at the origin moved by the trend's shift.
        shifted = compute_footholds((0.0, 0.0, 0.0), off, np.array([*base, HEIGHT]), 0.0,
                                    hips_of(params, (0.0, 0.0), 0.0), 2, 10.0, params,
                                    trend_shift=base)
        for a, b in zip(corrected.steps, shifted.steps, strict=True):
            np.testing.assert_allclose(a.target, b.target, atol=TOL)
        first, _ = legs_first_last(corrected)
        first_nominal, _ = legs_first_last(nominal_plan)
        moved = np.array([first[leg].target[:2] - first_nominal[leg].target[:2]
                          for leg in range(4)])
        # The shape: every foot moved alike from its foot-relative place in the pattern.
        np.testing.assert_allclose(moved - moved.mean(axis=0), 0.0, atol=TOL)
        common = moved.mean(axis=0)
        expected = (np.array([0.0, shift]) if followed
                    else np.array([0.06, -0.02]) / 4)    # the one foot's share of the mean
        np.testing.assert_allclose(common, expected, atol=TOL)


def test_actual_hips_are_corrected_about_beyond_the_threshold_only():
    # The same feet and the hips of the trunk 5 cm aside: the actual hips (sway_free False)
    # leave every foothold foot-relative (below the 10 cm threshold), where the sway-free ones
    # restore the shape.
    params = GaitParams()
    feet = standing_feet(params)
    feet[0, :2] += (0.06, 0.0)
    hips = hips_of(params, (0.0, 0.05), 0.0)
    base = np.array([0.0, 0.05, HEIGHT])
    actual = compute_footholds((0.0, 0.0, 0.0), feet, base, 0.0, hips, 2, 10.0, params)
    plain = compute_footholds((0.0, 0.0, 0.0), feet, base, 0.0, hips, 2, 10.0,
                              replace(params, foothold_correction=False))
    for a, b in zip(actual.steps, plain.steps, strict=True):
        np.testing.assert_allclose(a.target, b.target, atol=TOL)
    sway_free = compute_footholds((0.0, 0.0, 0.0), feet, base, 0.0, hips, 2, 10.0, params,
                                  trend_shift=np.zeros(2))
    first, _ = legs_first_last(sway_free)
    first_plain, _ = legs_first_last(plain)
    assert first[0].target[0] < first_plain[0].target[0] - 0.04


def test_step_length_is_clamped():
    params = GaitParams()
    feet = standing_feet(params)
    plan = plan_for((0.0, 0.0, 0.0), params, base_xy=(2.0, 1.0), feet=feet)
    prev = {leg: feet[leg].copy() for leg in range(4)}
    for step in plan.steps:
        d = step.target - prev[step.leg]
        assert abs(d[0]) <= params.max_step_length_x + TOL
        assert abs(d[1]) <= params.max_step_length_y + TOL
        prev[step.leg] = step.target
    first, _ = legs_first_last(plan)
    assert first[0].target[0] - feet[0, 0] == pytest.approx(params.max_step_length_x)


def test_clamp_velocity_limits_and_rejects_non_finite():
    params = GaitParams()
    np.testing.assert_allclose(clamp_velocity((1e9, 0.0, 0.0), params),
                               [params.max_linear_x, 0.0, 0.0])
    np.testing.assert_allclose(clamp_velocity((0.0, -1e9, 0.0), params),
                               [0.0, -params.max_linear_y, 0.0])
    v = clamp_velocity((1e9, -1e9, 5.0), params)
    assert 0 < v[0] <= params.max_linear_x and -params.max_linear_y <= v[1] < 0
    assert 0 < v[2] <= params.max_angular_z
    for bad in ((math.nan, 0, 0), (0, math.inf, 0), (0, 0, -math.inf)):
        with pytest.raises(ValueError):
            clamp_velocity(bad, params)
    # compute_footholds clamps too: an absurd set-point walks at the limit.
    fast = plan_for((1e9, 0.0, 0.0))
    limit = plan_for((GaitParams().max_linear_x, 0.0, 0.0))
    for a, b in zip(fast.steps, limit.steps, strict=True):
        np.testing.assert_allclose(a.target, b.target, atol=TOL)


def test_invalid_parameters_are_rejected():
    with pytest.raises(ValueError):
        plan_for((0, 0, 0), GaitParams(sequence=(0, 1, 2, 2)))
    with pytest.raises(ValueError):
        plan_for((0, 0, 0), GaitParams(replan_window=0))
    with pytest.raises(ValueError):
        plan_for((0, 0, 0), next_leg=7)


def test_stance_phases_alternate_four_and_three_feet():
    params = GaitParams()
    plan = plan_for((0.1, 0.0, 0.0), params, n=3)
    phases = stance_phases(plan)
    assert [int(p[3].sum()) for p in phases] == [4, 3, 4, 3, 4, 3, 4]
    assert phases[-1][1] == math.inf
    swing = phases[1]
    assert not swing[3][plan.steps[0].leg]
    np.testing.assert_allclose(phases[2][2][plan.steps[0].leg], plan.steps[0].target)


def test_walking_and_turning_at_once_is_scaled_to_feasible_strides():
    params = GaitParams()
    twist = clamp_velocity((0.15, 0.0, 0.2), params)
    # Same turning radius, slower, so that the outer feet's strides fit the step limits.
    assert twist[0] / twist[2] == pytest.approx(0.15 / 0.2)
    assert 0.0 < twist[0] < 0.15
    feet = steady_feet(params, twist, 10.0, 2)
    plan = plan_for(twist, params, feet=feet)
    prev = {leg: feet[leg] for leg in range(4)}
    for step in plan.steps:
        d = rot(step.yaw).T @ (step.target[:2] - prev[step.leg][:2])
        assert abs(d[0]) <= params.max_step_length_x + 1e-6
        assert abs(d[1]) <= params.max_step_length_y + 1e-6
        prev[step.leg] = step.target
    # The targets of the issue, one at a time, are not scaled.
    for v in ((0.15, 0.0, 0.0), (0.0, 0.1, 0.0), (0.0, 0.0, 0.2), (0.15, 0.1, 0.0)):
        np.testing.assert_allclose(clamp_velocity(v, params), v)


# ------------------------------------------------------------------------------ idle stance
TICK = 0.004     # s, control period


@pytest.mark.parametrize('trigger', [False, True])
def test_stand_plan_keeps_the_four_feet_polygon_and_the_qp_keeps_the_zmp_in_it(trigger):
    """A plan with no (real) step: one four-feet polygon over the whole 8 s horizon, and the
    QP, started off-centre and moving, keeps its ZMP inside it (margin included)."""
    params = GaitParams()
    feet = standing_feet(params)
    t0 = 10.0
    plan = stand_plan(feet, 0.0, t0, 2 if trigger else None,
                      t0 + params.idle_replan_period - TICK / 2 if trigger else None)
    assert len(plan.steps) == (1 if trigger else 0) and is_stand_plan(plan)
    # As config/mpc.yaml: 2 cm margin, velocity term 300 (pulls to the plan's zero velocity).
    settings = MpcSettings(zmp_margin=0.02, velocity_weight=300.0)
    sched = support_schedule(plan, t0, settings.dt, settings.n, settings.zmp_margin)
    assert np.all(sched.n_feet == 4) and not np.any(sched.degenerate)
    np.testing.assert_allclose(sched.A, sched.A[:1].repeat(settings.n, axis=0))
    np.testing.assert_allclose(sched.b, sched.b[:1].repeat(settings.n, axis=0))
    phases = stance_phases(plan)
    assert len(phases) == 1 and phases[0][3].all() and phases[0][1] == math.inf
    res = LipMpc(settings).solve(t0, np.array([0.08, -0.05, 0.55]), np.array([0.1, 0.05, 0.0]),
                                 np.zeros(3), plan, v_ref=np.zeros(2))
    assert res.status == STATUS_SOLVED and not res.is_fallback, res.reason
    assert res.min_zmp_margin_m >= settings.zmp_margin - 1e-5
    zmp = res.plan.position[1:, :2] - (settings.com_height / settings.gravity
                                       * res.plan.acceleration[1:, :2])
    assert np.min(sched.margins(zmp)) >= -1e-6
    assert np.linalg.norm(res.plan.velocity[25:, :2], axis=1).max() < 1e-2   # rest in 1 s


def test_idle_trigger_is_a_replan_one_tick_after_it_moving_no_foot():
    """Both trackers (gait node, controller) end the trigger one tick after its lift-off tick
    and call for the re-plan there: the same tick in both, as for a touchdown."""
    feet = standing_feet(GaitParams())
    t0 = 10.0
    plan = stand_plan(feet, 0.3, t0, 2, t0 + 0.5 - TICK / 2)
    step = plan.steps[0]
    assert is_idle_trigger(step) and step.replan and not step.haptic
    assert step.step_height == 0.0 and step.yaw == 0.3
    np.testing.assert_allclose(step.target, feet[2])
    tracker = StepTracker(plan)
    ticks = t0 + TICK * np.arange(1, 200)
    due = []
    for t in ticks:
        events = tracker.update(float(t), np.ones(4, dtype=bool))
        if tracker.replan_due:
            due.append((float(t), [(e.kind, e.reason) for e in events]))
            break
    assert due and due[0][0] == pytest.approx(t0 + 0.5 + TICK)
    assert due[0][1] == [('touchdown', 'planned')]           # lifted off at t0 + 0.5
    assert tracker.liftoff_tick[0] == pytest.approx(t0 + 0.5)
    with pytest.raises(ValueError):
        stand_plan(feet, 0.0, t0, 2, t0)                        # not after the plan start
    # A walking plan is not a stand plan.
    assert not is_stand_plan(plan_for((0.0, 0.0, 0.0)))
    assert not any(is_idle_trigger(s) for s in plan_for((0.0, 0.0, 0.0)).steps)


def test_idle_monitor_stands_after_a_cycle_of_zero_set_point():
    params = GaitParams()
    assert params.idle_after == pytest.approx(params.cycle_duration)   # one crawl cycle
    idle = IdleMonitor(params.idle_after, tolerance=0.5 * params.step_period)   # as the node
    walk = np.array([0.1, 0.0, 0.0])
    assert not idle.update(5.28, walk)
    # Zero from 6.0 (after walking), first used by the re-plan at the touchdown of 6.03: the
    # crawl steps in
    # place for the four steps of a cycle, then stands at the fifth touchdown, also when the
    # four steps took a little less than 3 s (haptic touchdowns jitter).
    touchdowns = 6.03 + params.step_period * np.arange(6) - np.array([0, 0, 0, 0, 0.03, 0])
    assert [idle.update(float(t), np.zeros(3)) for t in touchdowns] == [False] * 4 + [True] * 2
    assert idle.zero_since == 6.03
    # The stand's own re-plans (every idle_replan_period) go on standing.
    assert idle.update(10.3, np.zeros(3))
    # Any non-zero component ends the stand, and the count starts over.
    assert not idle.update(10.8, np.array([0.0, 0.0, 0.05]))
    assert idle.zero_since is None
    assert not idle.update(11.5, np.zeros(3))
    assert not idle.update(14.1, np.zeros(3))
    assert idle.update(14.125, np.zeros(3))
    # Switched off: never stands (steps in place).
    off = IdleMonitor(params.idle_after, enabled=False)
    assert not off.update(0.0, np.zeros(3)) and not off.update(100.0, np.zeros(3))


def test_idle_monitor_stands_from_the_start_until_the_first_set_point():
    idle = IdleMonitor(3.0, tolerance=0.375)
    assert idle.update(0.0, np.zeros(3)) and idle.update(0.504, np.zeros(3))
    assert idle.stands_at(0.6)
    assert not idle.update(1.008, np.array([0.1, 0.0, 0.0]))
    # Once walked, a zero set-point stands only after idle_after.
    assert not idle.update(2.0, np.zeros(3)) and not idle.stands_at(4.0)
    assert idle.update(4.7, np.zeros(3))


def test_restart_from_a_stand_walks_off_after_the_four_feet_phase():
    """The re-plan that sees a new set-point while standing: its first lift-off is one
    four-feet phase after it (within one step of the set-point's first trigger), and the
    reference trunk stands until then, so the first strides are partial, as at the start."""
    params = GaitParams()
    t0 = 12.004
    v = (0.1, 0.0, 0.0)
    restart = plan_for(v, params, t0=t0, delay=params.four_feet_duration)
    moving = plan_for(v, params, t0=t0)
    assert restart.steps[0].liftoff_time == pytest.approx(t0 + params.four_feet_duration)
    assert not is_stand_plan(restart)
    first, _ = legs_first_last(restart)
    first_moving, _ = legs_first_last(moving)
    feet = standing_feet(params)
    for leg, step in first.items():
        advance = step.target[0] - feet[leg, 0]
        assert 0.0 < advance < first_moving[leg].target[0] - feet[leg, 0]
    assert 0.0 < first[restart.steps[0].leg].target[0] - feet[restart.steps[0].leg, 0] < \
        0.1 * params.cycle_duration


def test_idle_parameters_are_checked():
    with pytest.raises(ValueError):
        plan_for((0, 0, 0), GaitParams(idle_replan_period=0.0))
    with pytest.raises(ValueError):
        plan_for((0, 0, 0), GaitParams(idle_after=-1.0))
