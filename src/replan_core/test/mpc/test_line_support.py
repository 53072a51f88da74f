"""Two feet: the line support of support.py, and LipMpc on walking-trot and trot plans."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from replan_core.common.types import FootholdPlan, Step
from replan_core.gait.crawl import CrawlSchedule, compute_footholds
from replan_core.gait.gait_file import load_gait
from replan_core.mpc.lip_mpc import STATUS_DEGENERATE, STATUS_SOLVED, LipMpc
from replan_core.mpc.settings import MpcSettings
from replan_core.mpc.support import polygon, stance_at, support_schedule

CONFIG = Path(__file__).resolve().parents[4] / 'config'
FEET = np.array([[0.37, 0.32, 0.0], [0.37, -0.32, 0.0], [-0.37, 0.32, 0.0], [-0.37, -0.32, 0.0]])
# HyQ's MPC (config/mpc.yaml)
HYQ = MpcSettings(com_height=0.55, velocity_weight=300.0, position_weight=10000.0,
                  position_sway=0.5, com_offset=(0.0393, 0.0151), zmp_margin=0.02)


def test_two_feet_are_a_strip_about_their_segment():
    p0, p1 = np.array([0.37, 0.32]), np.array([-0.37, -0.32])
    line = polygon(np.array([p0, p1]), margin=0.02, line_width=0.02)
    assert not line.degenerate
    assert line.chebyshev_radius == pytest.approx(0.01)
    e = (p1 - p0) / np.linalg.norm(p1 - p0)
    n = np.array([-e[1], e[0]])
    mid = 0.5 * (p0 + p1)
    assert line.margin_of(mid) == pytest.approx(0.01)          # half the width across
    assert line.margin_of(mid + 0.01 * n) == pytest.approx(0.0, abs=1e-12)
    assert line.margin_of(mid - 0.011 * n) == pytest.approx(-0.001)
    assert line.margin_of(p0 + 0.02 * e) == pytest.approx(0.0, abs=1e-12)   # margin along
    assert line.margin_of(p1) == pytest.approx(-0.02)
    # Without a width two feet stay degenerate (the crawl's case), as before.
    assert polygon(np.array([p0, p1]), margin=0.02).degenerate
    # Feet closer than twice the margin leave nothing along the segment.
    short = polygon(np.array([p0, p0 + 0.03 * e]), margin=0.02, line_width=0.02)
    assert short.degenerate and 'empty after' in short.reason


def _switch_plan(t_switch):
    """LF + RH swing until t_switch, RF + LH from t_switch: no four-feet phase."""
    steps = []
    for pair, lo, td in (((0, 3), 0.02, t_switch), ((1, 2), t_switch, t_switch + 0.3)):
        for leg in pair:
            steps.append(Step(leg, lo, td, FEET[leg] + [0.05, 0, 0], 0.08, True, True, 0.0))
    return FootholdPlan(0.0, FEET.copy(), 0.0, steps)


@pytest.mark.parametrize('t_switch', [0.32, 0.32 + 1e-12, 0.32 - 1e-12, 0.34])
def test_trot_switch_sample_stands_on_the_landing_pair(t_switch):
    plan = _switch_plan(t_switch)
    sched = support_schedule(plan, 0.0, 0.04, 20, 0.02, line_width=0.02)
    assert not sched.degenerate.any(), sched.reasons
    assert sched.n_feet.min() == 2
    if abs(t_switch - 0.32) < 1e-9:
        k = 7                                     # sample 8, t = 0.32 s: the switch itself
        assert sched.n_feet[k] == 2
        # Before the lift-off by a hair the lifting pair (RF, LH) is still down; at or after
        # it the landing pair (LF, RH) stands on its targets.
        early = sched.times[k] < t_switch
        pair = FEET[[1, 2], :2] if early else FEET[[0, 3], :2] + [0.05, 0]
        assert sched.polygons[k].margin_of(pair.mean(axis=0)) == pytest.approx(0.01)
    # Without a line width the switch is degenerate, as two feet are.
    assert support_schedule(plan, 0.0, 0.04, 20, 0.02).degenerate.any()


def _trot_run(name, speed, replans):
    """Closed-loop re-plans of gait ``name`` at ``speed`` m/s forward, flat ground, HyQ: each
    at the planned touchdown of the plan's first pair (on the sample grid), from the CoM plan
    there, feet on their targets. Yields (plan, result, settings)."""
    spec = load_gait(name, CONFIG)
    params = spec.params()
    settings = replace(HYQ, line_support_width=0.02)   # m, config/mpc.yaml
    mpc = LipMpc(settings)
    sched = CrawlSchedule(params.sequence, groups=params.groups)
    feet = np.column_stack([np.asarray(params.hip_offsets) + np.asarray(params.stance_offsets),
                            np.zeros(4)])
    pos = np.array([*(feet[:, :2].mean(axis=0) + HYQ.com_offset), 0.55])
    vel, acc = np.zeros(3), np.zeros(3)
    t = 0.0
    for i in range(replans):
        plan = compute_footholds((speed, 0.0, 0.0), feet, pos - [*HYQ.com_offset, 0.0], 0.0,
                                 None, sched.next_leg, t, params,
                                 delay=0.0 if i else params.swing_duration)
        res = mpc.solve(t, pos, vel, acc, plan)
        yield plan, res, settings
        first = [st for st in plan.steps if st.liftoff_time == plan.steps[0].liftoff_time]
        t_next = t + settings.dt * round((first[0].touchdown_time - t) / settings.dt)
        pos, vel, acc = (np.array(a, dtype=float) for a in res.plan.sample(t_next))
        for st in first:
            feet[st.leg] = st.target
            sched.touched_down(st.leg)
        t = t_next


@pytest.mark.parametrize('name', ['walking_trot', 'trot'])
def test_lip_mpc_plans_a_trot_with_the_zmp_on_each_diagonal(name):
    walked = []
    for plan, res, s in _trot_run(name, 0.1, 6):
        assert res.status == STATUS_SOLVED, res.reason
        assert not res.is_fallback
        assert res.max_zmp_violation_m <= 1e-5
        zmp = res.zmp[1:]
        times = res.plan.start_time + s.dt * np.arange(1, s.n + 1)
        two = 0
        for k, t in enumerate(times):
            xy, down = stance_at(plan, float(t))
            if down.sum() == 2:
                # On the segment between the two feet: within half the strip across it, the
                # margin inside its ends along it.
                p0, p1 = xy[down, :2]
                e = (p1 - p0) / np.linalg.norm(p1 - p0)
                d = zmp[k] - p0
                assert abs(d[0] * e[1] - d[1] * e[0]) <= 0.5 * s.line_support_width + 1e-5
                assert s.zmp_margin - 1e-5 <= d @ e <= np.linalg.norm(p1 - p0) \
                    - s.zmp_margin + 1e-5
                two += 1
            elif down.sum() >= 3:
                assert polygon(xy[down], s.zmp_margin).margin_of(zmp[k]) >= -1e-5
        assert two >= 50                           # the plan does stand on diagonals
        walked.append(res.plan.position[0, 0])
    # It walks forward at about the set-point.
    assert walked[-1] - walked[0] > 0.5 * 0.1 * (res.plan.start_time - 0.0)


def test_without_a_line_width_a_trot_is_degenerate():
    spec = load_gait('trot', CONFIG)
    params = spec.params()
    feet = np.column_stack([np.asarray(params.hip_offsets) + np.asarray(params.stance_offsets),
                            np.zeros(4)])
    plan = compute_footholds((0.1, 0, 0), feet, np.zeros(3), 0.0, None, 0, 0.0, params)
    res = LipMpc(HYQ).solve(0.0, np.array([0.04, 0.015, 0.55]), np.zeros(3), np.zeros(3), plan)
    assert res.status == STATUS_DEGENERATE
    assert '2 distinct stance feet' in res.reason


def test_line_support_width_is_checked():
    with pytest.raises(ValueError, match='line_support_width'):
        LipMpc(replace(HYQ, line_support_width=-0.01))
