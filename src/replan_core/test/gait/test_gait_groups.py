"""Steps of several legs at once: schedule, footholds and stance phases of the trots
(gait/crawl.py with GaitParams.groups)."""

import math
from dataclasses import replace
from itertools import pairwise

import numpy as np
import pytest
from gait_config import CONFIG, LF, LH, RF, RH

from replan_core.gait.crawl import (
    CrawlSchedule,
    GaitParams,
    ReferenceTrajectory,
    compute_footholds,
    stance_phases,
)
from replan_core.gait.gait_file import load_gait

FOOT_Z = 0.02


def gait(name: str) -> GaitParams:
    return load_gait(name, CONFIG).params()


def steady_feet(params, twist, t0, next_leg):
    """Feet of a robot that has walked with ``twist`` for a while, base at the origin at t0:
    each foot at the reference foot of its current stance's middle (the previous foothold).
    Groups from ``next_leg``'s on lift off at t0 + four_feet, + step_period, ..."""
    ref = ReferenceTrajectory(t0, np.zeros(2), 0.0, np.asarray(twist, dtype=float))
    groups = params.swing_groups
    k0 = next(k for k, g in enumerate(groups) if next_leg in g)
    feet = np.zeros((4, 3))
    for j in range(len(groups)):
        touchdown = t0 + params.four_feet_duration + j * params.step_period \
            + params.swing_duration
        mid = touchdown + 0.5 * params.stance_duration - params.cycle_duration
        for leg in groups[(k0 + j) % len(groups)]:
            off = np.asarray(params.hip_offsets[leg]) + np.asarray(params.stance_offsets[leg])
            feet[leg] = [*ref.foot(mid, off), FOOT_Z]
    return feet, ref


def test_schedule_of_pairs_continues_with_the_other_pair():
    params = gait('trot')
    sched = CrawlSchedule(params.sequence, groups=params.groups)
    assert sched.next_leg == LF
    assert sched.touched_down(RH) == RF          # either foot of a pair names its group
    assert sched.touched_down(LF) == RF
    assert sched.touched_down(LH) == LF
    crawl = CrawlSchedule()                       # the crawl: one leg at a time, as before
    assert [crawl.successor(leg) for leg in (LH, LF, RH, RF)] == [LF, RH, RF, LH]


def test_groups_must_match_the_sequence():
    with pytest.raises(ValueError, match='groups'):
        replace(GaitParams(), groups=((LF, RH), (RF, LH))).validate()   # sequence: the crawl's
    replace(GaitParams(), sequence=(LF, RH, RF, LH), groups=((LF, RH), (RF, LH))).validate()


@pytest.mark.parametrize('name', ['walking_trot', 'trot'])
@pytest.mark.parametrize('twist', [(0.1, 0.0, 0.0), (0.3, 0.1, 0.0), (0.2, 0.0, 0.3)])
def test_pairs_lift_off_together_and_land_at_the_reference_mid_stance(name, twist):
    params = replace(gait(name), velocity_feedback_gain=0.0)
    t0 = 3.2
    feet, ref = steady_feet(params, twist, t0, RF)
    plan = compute_footholds(twist, feet, np.array([0.0, 0.0, 0.55]), 0.0, None, LH, t0,
                             params, n=6)
    assert len(plan.steps) == 12                  # 6 steps of the gait, 2 legs each
    for j in range(6):
        a, b = plan.steps[2 * j], plan.steps[2 * j + 1]
        assert {a.leg, b.leg} == ({RF, LH} if j % 2 == 0 else {LF, RH})   # LH's pair first
        assert a.liftoff_time == b.liftoff_time and a.touchdown_time == b.touchdown_time
        assert a.liftoff_time == pytest.approx(
            t0 + params.four_feet_duration + j * params.step_period)
        assert a.touchdown_time - a.liftoff_time == pytest.approx(params.swing_duration)
        assert a.yaw == b.yaw
        for st in (a, b):
            # Each leg's foothold as in the crawl: its reference foot at its mid-stance.
            mid = st.touchdown_time + 0.5 * params.stance_duration
            off = np.asarray(params.hip_offsets[st.leg]) + np.asarray(
                params.stance_offsets[st.leg])
            np.testing.assert_allclose(st.target[:2], ref.foot(mid, off), atol=1e-9)
            assert st.target[2] == FOOT_Z
            assert st.step_height == params.step_height


def test_replan_flag_is_per_step_of_the_gait():
    params = replace(gait('trot'), replan_window=2)
    feet, _ = steady_feet(params, (0.0, 0.0, 0.0), 0.0, LF)
    plan = compute_footholds((0.1, 0, 0), feet, np.zeros(3), 0.0, None, LF, 0.0, params, n=4)
    assert [st.replan for st in plan.steps] == [False, False, True, True] * 2


def test_trot_stance_phases_alternate_diagonals():
    params = gait('trot')
    feet, _ = steady_feet(params, (0.2, 0.0, 0.0), 1.0, LF)
    plan = compute_footholds((0.2, 0, 0), feet, np.zeros(3), 0.0, None, LF, 1.0, params, n=4)
    phases = stance_phases(plan)
    # No four-feet phase: one diagonal after the other, then the final four-feet stance.
    assert len(phases) == 5
    expect = [(RF, LH), (LF, RH), (RF, LH), (LF, RH)]
    for (t_start, t_end, _, down), legs in zip(phases[:4], expect, strict=True):
        assert sorted(np.flatnonzero(down).tolist()) == sorted(legs)
        assert t_end - t_start == pytest.approx(params.swing_duration)
    assert phases[0][0] == 1.0
    assert phases[-1][1] == math.inf and phases[-1][3].all()
    for (_, t_end, _, _), (t_next, _, _, _) in pairwise(phases):
        assert t_end == t_next


def test_walking_trot_has_four_feet_between_the_pairs():
    params = gait('walking_trot')
    feet, _ = steady_feet(params, (0.2, 0.0, 0.0), 0.0, LF)
    plan = compute_footholds((0.2, 0, 0), feet, np.zeros(3), 0.0, None, LF, 0.0, params, n=3)
    counts = [int(p[3].sum()) for p in stance_phases(plan)]
    assert counts == [4, 2, 4, 2, 4, 2, 4]
    durations = [p[1] - p[0] for p in stance_phases(plan)[:-1]]
    np.testing.assert_allclose(durations[0::2], params.four_feet_duration)
    np.testing.assert_allclose(durations[1::2], params.swing_duration)
