"""Support polygons as half-spaces, eq. (7) rows."""

import math
from pathlib import Path

import numpy as np
import pytest

from replan_core.bench.mpc_bench import bench_crawl, crawl_plan
from replan_core.common.types import FootholdPlan, Step
from replan_core.mpc.support import MAX_ROWS, convex_hull, polygon, stance_at, support_schedule

# The bench crawl's standing feet (m, base frame xy): the project's reference robot, HyQ.
LAYOUT = bench_crawl('hyq', Path(__file__).resolve().parents[4]).feet_xy


SQUARE = np.array([[0.37, 0.21], [0.37, -0.21], [-0.37, 0.21], [-0.37, -0.21]])


def test_quadrilateral_rows_and_margin():
    p = polygon(SQUARE, margin=0.02)
    assert not p.degenerate and len(p.offsets) == 4
    np.testing.assert_allclose(np.linalg.norm(p.normals, axis=1), 1.0, atol=1e-12)
    assert p.margin_of(np.zeros(2)) == pytest.approx(0.21 - 0.02, abs=1e-12)
    assert p.margin_of(np.array([0.36, 0.0])) == pytest.approx(0.01 - 0.02, abs=1e-12)
    assert p.area == pytest.approx(0.74 * 0.42, abs=1e-12)
    assert p.chebyshev_radius == pytest.approx(0.19, abs=1e-12)


def test_triangle_inradius_and_points_inside():
    p = polygon(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    assert len(p.offsets) == 3
    assert p.chebyshev_radius == pytest.approx(1.0 / (2.0 + math.sqrt(2.0)), abs=1e-12)
    rng = np.random.default_rng(1)
    for z in rng.uniform(-0.5, 1.5, size=(200, 2)):
        inside = z[0] >= 0 and z[1] >= 0 and z[0] + z[1] <= 1
        assert (p.margin_of(z) >= 0) == inside


def test_hull_drops_interior_foot():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.2, 0.2]])
    assert len(convex_hull(pts)) == 3
    assert len(polygon(pts).offsets) == 3


def test_degenerate_polygons_are_flagged_not_raised():
    line = polygon(np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]))
    assert line.degenerate and 'collinear' in line.reason
    two = polygon(np.array([[0.0, 0.0], [1.0, 1.0]]))
    assert two.degenerate and '2 distinct' in two.reason and len(two.offsets) == 4
    small = polygon(np.array([[0.0, 0.0], [0.05, 0.0], [0.0, 0.05]]), margin=0.05)
    assert small.degenerate and 'margin' in small.reason
    assert polygon(np.zeros((0, 2))).degenerate


def test_schedule_of_a_crawl():
    feet = np.column_stack([LAYOUT, np.zeros(4)])
    plan = crawl_plan(0.0, np.zeros(3), 0.0, feet, 2, np.array([0.1, 0.0]),
                      np.random.default_rng(0), layout=LAYOUT)
    sched = support_schedule(plan, 0.0, 0.04, 200, margin=0.01)
    assert sched.A.shape == (200, MAX_ROWS, 2) and not sched.degenerate.any()
    assert set(np.unique(sched.n_feet)) == {3, 4}
    for k in range(0, 200, 7):                           # vectorised == per-sample reference
        t = sched.times[k]
        f, st = stance_at(plan, t)
        assert sched.n_feet[k] == st.sum()
        ref = polygon(f[st, :2], 0.01)
        np.testing.assert_allclose(sched.b[k, :len(ref.offsets)], ref.offsets, atol=1e-12)
    # Closed swing interval: a sample at exactly lift-off is already a triangle.
    s0 = plan.steps[0]
    sched2 = support_schedule(plan, s0.liftoff_time - 0.04, 0.04, 10)
    assert sched2.n_feet[0] == 3
    # After the last step (touchdown at 8.0 s) the final stance stays.
    assert support_schedule(plan, 0.0, 0.04, 210).n_feet[-10:].tolist() == [4] * 10


def test_schedule_centres_are_the_four_feet_with_a_swinging_foot_halfway():
    feet = np.column_stack([LAYOUT, np.zeros(4)])
    plan = crawl_plan(0.0, np.zeros(3), 0.0, feet, 2, np.array([0.1, 0.05]),
                      np.random.default_rng(3), layout=LAYOUT)
    sched = support_schedule(plan, 0.0, 0.04, 200, centres=True)
    assert support_schedule(plan, 0.0, 0.04, 200).centres is None    # only when asked for
    for k in range(0, 200, 3):
        t = sched.times[k]
        where = feet[:, :2].copy()                       # each leg's last target by time t
        for st in plan.steps:
            if st.touchdown_time < t:
                where[st.leg] = st.target[:2]
            elif st.liftoff_time <= t:                  # in the air: halfway
                where[st.leg] = (where[st.leg] + st.target[:2]) / 2
        np.testing.assert_allclose(sched.centres[k], where.mean(axis=0), atol=1e-12)
        f, st = stance_at(plan, t)                       # the feet in stance: their centroid
        np.testing.assert_allclose(sched.stance_centres[k], f[st, :2].mean(axis=0),
                                   atol=1e-12)


def test_two_legs_swinging_is_degenerate_with_sample_index():
    feet = np.column_stack([SQUARE, np.zeros(4)])
    steps = [Step(leg, 0.2, 0.6, feet[leg], 0.1, True, False, 0.0) for leg in (0, 3)]
    plan = FootholdPlan(0.0, feet, 0.0, steps)
    sched = support_schedule(plan, 0.0, 0.04, 20)
    assert sched.degenerate.any()
    assert sched.first_degenerate() == 4                 # sample 5: t = 0.2 s
    assert sched.reasons[0].startswith('sample 5')


def test_implied_velocity_is_the_stride_rate_not_the_catch_up():
    from replan_core.common.types import FootholdPlan, Step
    from replan_core.mpc.support import implied_velocity

    # Feet 5 cm behind their nominal place; then a crawl at 0.2 m/s, 0.75 s steps (3 s cycle).
    nominal = np.array([[0.37, 0.32, 0.0], [0.37, -0.32, 0.0], [-0.37, 0.32, 0.0],
                        [-0.37, -0.32, 0.0]])
    feet = nominal - [0.05, 0.0, 0.0]
    v, period, steps = 0.2, 0.75, []
    for i, leg in enumerate([2, 0, 3, 1] * 2):
        t_td = 10.0 + (i + 1) * period
        target = nominal[leg] + [v * (t_td - 10.0), 0.0, 0.0]
        steps.append(Step(leg, t_td - 0.5, t_td, target, 0.1, True, i == 0, 0.0))
    plan = FootholdPlan(10.0, feet, 0.0, steps)
    np.testing.assert_allclose(implied_velocity(plan), [v, 0.0], atol=1e-12)
    short = FootholdPlan(10.0, feet, 0.0, steps[:5])
    assert implied_velocity(short)[0] > 0
    # Fewer steps than legs: a plan that stops (gait.Replanner ends the plan before a stand).
    stopping = FootholdPlan(10.0, feet, 0.0, steps[:1])
    assert np.all(implied_velocity(stopping) == 0)
    assert np.all(implied_velocity(FootholdPlan(10.0, feet, 0.0, [])) == 0)


@pytest.mark.parametrize('shift', [0.0, 0.013, -1])
def test_schedule_matches_the_per_sample_stance_everywhere(shift):
    """Every sample (runs of one stance written as slices) against ``stance_at`` + ``polygon``,
    including horizons that start exactly one sample before a lift-off (closed swing interval)."""
    feet = np.column_stack([LAYOUT, np.zeros(4)])
    plan = crawl_plan(0.0, np.zeros(3), 0.0, feet, 2, np.array([0.1, 0.02]),
                      np.random.default_rng(5), layout=LAYOUT)
    t0 = plan.steps[1].liftoff_time - 0.04 if shift == -1 else shift
    sched = support_schedule(plan, t0, 0.04, 120, margin=0.02)
    assert len(sched.polygons) == 120
    for k in range(120):
        f, st = stance_at(plan, sched.times[k])
        ref = polygon(f[st, :2], 0.02)
        m = len(ref.offsets)
        assert sched.n_feet[k] == st.sum() and sched.active[k].sum() == m
        np.testing.assert_allclose(sched.A[k, :m], ref.normals, atol=1e-12)
        np.testing.assert_allclose(sched.b[k, :m], ref.offsets, atol=1e-12)
        assert sched.polygons[k].chebyshev_radius == pytest.approx(ref.chebyshev_radius)
