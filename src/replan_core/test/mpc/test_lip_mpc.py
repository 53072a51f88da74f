"""The jerk QP eq. (6)-(7): optimality, feasibility, warm start, failures, interpolation."""

import math
from pathlib import Path

import numpy as np
import pytest

from replan_core.bench.mpc_bench import (
    CRAWL_ORDER,
    FOUR_FEET,
    SWING,
    bench_crawl,
    crawl_plan,
    run,
    velocity_profile,
)
from replan_core.common.types import FootholdPlan, Step
from replan_core.gait.crawl import stand_plan
from replan_core.mpc.lip import rollout
from replan_core.mpc.lip_mpc import (
    FALLBACK_HOLD,
    FALLBACK_RELAXED,
    FALLBACK_SHIFTED,
    STATUS_DEGENERATE,
    STATUS_INFEASIBLE,
    STATUS_REJECTED,
    STATUS_SOLVED,
    LipMpc,
    replan_start_state,
)
from replan_core.mpc.settings import MpcSettings
from replan_core.mpc.support import support_schedule
from replan_core.mpc.working_set import _nnqp

# The bench crawl's standing feet (m, base frame xy): the project's reference robot, HyQ.
ROOT = Path(__file__).resolve().parents[4]
LAYOUT = bench_crawl('hyq', ROOT).feet_xy


FEET = np.column_stack([LAYOUT, np.zeros(4)])


def crawl(mpc: LipMpc, seed: int, replans: int, jitter: float = 0.03):
    """Consecutive re-plans of a seeded crawl; yields (plan, result) after each solve."""
    rng = np.random.default_rng(seed)
    feet, com, vel, acc, t, leg = FEET.copy(), np.zeros(3), np.zeros(3), np.zeros(3), 0.0, 2
    for i in range(replans):
        v_ref = velocity_profile(i * 7 + seed)
        plan = crawl_plan(t, com, 0.0, feet, leg, v_ref, rng, layout=LAYOUT)
        res = mpc.solve(t, com, vel, acc, plan, v_ref=v_ref)
        yield plan, res
        first = plan.steps[0]
        t_next = first.touchdown_time + rng.uniform(-jitter, jitter)
        p, v, a = res.plan.sample(t_next)
        com = p + np.r_[rng.normal(0.0, 0.003, 2), 0.0]
        vel = v + np.r_[rng.normal(0.0, 0.01, 2), 0.0]
        acc = a
        feet = feet.copy()
        feet[first.leg] = first.target
        leg = CRAWL_ORDER[(CRAWL_ORDER.index(first.leg) + 1) % 4]
        t = t_next


def zmp_violation(res, plan, settings) -> float:
    """Largest violation (m) of the polygons by the plan's ZMP, recomputed from scratch."""
    sched = support_schedule(plan, res.plan.start_time, settings.dt, settings.n,
                             settings.zmp_margin)
    z = res.plan.position[1:, :2] - settings.com_height / settings.gravity * \
        res.plan.acceleration[1:, :2]
    return float(max(0.0, -np.min(sched.margins(z))))


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_zmp_inside_every_polygon_on_random_crawls(seed):
    s = MpcSettings(zmp_margin=0.02)
    mpc = LipMpc(s)
    for plan, res in crawl(mpc, seed, 12):
        assert res.status == STATUS_SOLVED, res.reason
        assert not res.is_fallback
        assert zmp_violation(res, plan, s) <= 1e-5
        assert res.min_zmp_margin_m >= s.zmp_margin - 1e-5
        # The LIP is unstable: the capture-point terminal rows keep the end bounded.
        assert np.linalg.norm(res.plan.velocity[-1, :2]) < 0.5
        assert np.all(np.abs(res.plan.acceleration[-1, :2]) < 1.0)


def test_cost_not_above_a_known_feasible_plan():
    """The working-set optimum against the full dense QP (proxsuite on all 804 rows)."""
    s = MpcSettings(zmp_margin=0.02)
    ws = LipMpc(s)
    dense = LipMpc(MpcSettings(zmp_margin=0.02, formulation='dense', eps_abs=1e-8))
    for plan, res in crawl(ws, 5, 3):
        ref = dense.solve(res.plan.start_time, res.plan.position[0], res.plan.velocity[0],
                          res.plan.acceleration[0], plan)
        assert ref.status == STATUS_SOLVED
        assert zmp_violation(ref, plan, s) <= 1e-5            # a known feasible plan
        assert res.cost <= ref.cost * (1 + 1e-4) + 1e-9
        assert res.cost == pytest.approx(ref.cost, rel=1e-3)


def test_large_polygon_gives_zero_jerk():
    big = np.array([[5.0, 5.0, 0.0], [5.0, -5.0, 0.0], [-5.0, 5.0, 0.0], [-5.0, -5.0, 0.0]])
    steps = [Step(2, 0.3, 0.8, big[2], 0.1, True, True, 0.0)]
    plan = FootholdPlan(0.0, big, 0.0, steps)
    res = LipMpc().solve(0.0, np.array([0.3, -0.2, 0.55]), np.zeros(3), np.zeros(3), plan)
    assert res.status == STATUS_SOLVED
    np.testing.assert_allclose(res.jerk, 0.0, atol=1e-9)
    np.testing.assert_allclose(res.plan.position[:, :2], [[0.3, -0.2]] * 201, atol=1e-9)


def test_velocity_weight_tracks_the_reference():
    v_ref = np.array([0.15, 0.05])
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, v_ref, np.random.default_rng(4),
                      layout=LAYOUT)
    errors = []
    for w in (0.0, 0.1, 10.0):
        res = LipMpc(MpcSettings(velocity_weight=w)).solve(
            0.0, np.zeros(3), np.zeros(3), np.zeros(3), plan, v_ref=v_ref)
        assert res.status == STATUS_SOLVED
        # The cost's own term, sum |v_k - v_ref|^2: at the optimum it cannot grow with its
        # weight. The plan's mean velocity need not follow (with HyQ's standing feet it did not).
        errors.append(float(np.sum((res.plan.velocity[1:, :2] - v_ref) ** 2)))
    assert errors[2] < errors[1] < errors[0]


def test_position_weight_pulls_the_com_over_its_feet():
    """A CoM 8 cm beside the standing feet stays there without the term (the QP of eq. (6)
    has no position target) and is brought over the feet with it, the ZMP still inside."""
    plan = stand_plan(FEET, 0.0, 0.0, None, None)
    offset = np.array([0.0, 0.08, 0.0])
    centre = np.r_[FEET[:, :2].mean(axis=0), 0.0]
    ends = []
    for w in (0.0, 100.0):
        settings = MpcSettings(zmp_margin=0.02, position_weight=w)
        res = LipMpc(settings).solve(0.0, centre + offset, np.zeros(3), np.zeros(3), plan)
        assert res.status == STATUS_SOLVED
        assert zmp_violation(res, plan, settings) <= 1e-4
        ends.append(float(np.linalg.norm(res.plan.position[-1, :2] - centre[:2])))
    assert ends[0] == pytest.approx(0.08, abs=1e-6)
    assert ends[1] < 0.005


def test_position_sway_moves_the_reference_into_the_support_triangles():
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.array([0.1, 0.0]),
                      np.random.default_rng(6), layout=LAYOUT)
    sched = support_schedule(plan, 0.0, 0.04, 200, centres=True)
    for sway, want in ((0.0, sched.centres), (1.0, sched.stance_centres),
                       (0.25, 0.75 * sched.centres + 0.25 * sched.stance_centres)):
        got = MpcSettings(position_sway=sway).position_reference(sched)
        np.testing.assert_allclose(got, want, atol=1e-12)
    assert np.abs(sched.stance_centres - sched.centres).max() > 0.05   # the triangles' sway
    # A ready schedule without the centres cannot feed the term: rejected, not solved wrong.
    res = LipMpc(MpcSettings(position_weight=10.0)).solve(
        0.0, np.zeros(3), np.zeros(3), np.zeros(3), support_schedule(plan, 0.0, 0.04, 200))
    assert res.status == STATUS_REJECTED and 'centres' in res.reason


def test_the_com_offset_turns_with_the_yaw_reference_of_each_sample():
    """The reference is the centre of the feet plus ``com_offset`` turned by the yaw of the
    last step down (the plan's initial yaw before the first); an offset of 0 leaves the
    reference the very array of the centres, so the default plans do not change."""
    plan = crawl_plan(0.0, np.zeros(3), 0.3, FEET, 2, np.array([0.05, 0.0]),
                      np.random.default_rng(6), layout=LAYOUT)
    for j, step in enumerate(plan.steps):
        step.yaw = 0.3 + 0.1 * (j + 1)
    sched = support_schedule(plan, 0.0, 0.04, 200, centres=True)
    assert MpcSettings().position_reference(sched) is sched.centres
    first_down = plan.steps[0].touchdown_time
    assert sched.yaws[sched.times <= first_down] == pytest.approx(0.3)
    down = [step.yaw for step in plan.steps if step.touchdown_time < sched.times[-1]]
    assert len(down) >= 4 and sched.yaws[-1] == pytest.approx(down[-1])
    got = MpcSettings(com_offset=(0.04, 0.015)).position_reference(sched) - sched.centres
    want = np.column_stack([np.cos(sched.yaws) * 0.04 - np.sin(sched.yaws) * 0.015,
                            np.sin(sched.yaws) * 0.04 + np.cos(sched.yaws) * 0.015])
    np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize('formulation', ['dense', 'sparse'])
def test_full_formulations_agree_with_the_position_term(formulation):
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.array([0.1, 0.05]),
                      np.random.default_rng(5), layout=LAYOUT)
    com = np.array([0.02, 0.05, 0.0])
    v_ref = np.array([0.1, 0.05])
    ref = LipMpc(MpcSettings(position_weight=30.0, position_sway=0.5,
                             velocity_weight=300.0)).solve(
        0.0, com, np.zeros(3), np.zeros(3), plan, v_ref=v_ref)
    other = LipMpc(MpcSettings(position_weight=30.0, position_sway=0.5, velocity_weight=300.0,
                               formulation=formulation, eps_abs=1e-7, max_iter=2000)).solve(
        0.0, com, np.zeros(3), np.zeros(3), plan, v_ref=v_ref)
    assert ref.status == other.status == STATUS_SOLVED
    np.testing.assert_allclose(other.plan.position, ref.plan.position, atol=1e-3)


def test_warm_and_cold_agree():
    warm = LipMpc(MpcSettings(zmp_margin=0.02))
    cold = LipMpc(MpcSettings(zmp_margin=0.02, warm_start=False))
    for plan, res in crawl(warm, 7, 6):
        ref = cold.solve(res.plan.start_time, res.plan.position[0], res.plan.velocity[0],
                         res.plan.acceleration[0], plan)
        assert ref.status == res.status == STATUS_SOLVED
        np.testing.assert_allclose(res.zmp, ref.zmp, atol=1e-4)
        np.testing.assert_allclose(res.plan.position, ref.plan.position, atol=1e-3)
        assert res.cost == pytest.approx(ref.cost, rel=1e-3)


def test_com_outside_returns_infeasible_status_and_relaxed_fallback():
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.zeros(2), np.random.default_rng(0),
                      layout=LAYOUT)
    mpc = LipMpc()
    res = mpc.solve(0.0, np.array([1.5, 0.0, 0.55]), np.array([1.0, 0.0, 0.0]), np.zeros(3),
                    plan)
    assert res.status == STATUS_INFEASIBLE
    assert res.fallback == FALLBACK_RELAXED and res.is_fallback and not res.ok
    assert 'sample' in res.reason or 'terminal' in res.reason
    assert res.plan is not None and np.all(np.isfinite(res.plan.position))


def test_degenerate_polygon_reports_the_sample():
    steps = [Step(leg, 0.2, 0.6, FEET[leg], 0.1, True, False, 0.0) for leg in (0, 3)]
    plan = FootholdPlan(0.0, FEET, 0.0, steps)
    res = LipMpc().solve(0.0, np.zeros(3), np.zeros(3), np.zeros(3), plan)
    assert res.status == STATUS_DEGENERATE and res.is_fallback
    assert 'sample 5' in res.reason


def test_nan_state_rejected_with_message_and_previous_plan_shifted():
    mpc = LipMpc()
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.zeros(2), np.random.default_rng(0),
                      layout=LAYOUT)
    res = mpc.solve(0.0, np.array([math.nan, 0.0, 0.55]), np.zeros(3), np.zeros(3), plan)
    assert res.status == STATUS_REJECTED and 'com_pos' in res.reason and 'NaN' in res.reason
    assert res.fallback == FALLBACK_HOLD and res.plan is None
    good = mpc.solve(0.0, np.zeros(3), np.zeros(3), np.zeros(3), plan)
    assert good.ok
    bad = mpc.solve(0.5, np.zeros(3), np.array([0.0, np.inf, 0.0]), np.zeros(3), plan)
    assert bad.status == STATUS_REJECTED and 'com_vel' in bad.reason
    assert bad.fallback == FALLBACK_SHIFTED
    np.testing.assert_allclose(bad.plan.position[0], good.plan.sample(0.5)[0], atol=1e-12)
    plan.steps[3].target = np.array([0.0, math.nan, 0.0])
    nan_step = mpc.solve(0.5, np.zeros(3), np.zeros(3), np.zeros(3), plan)
    assert nan_step.status == STATUS_REJECTED and 'steps [3]' in nan_step.reason


def test_plan_interpolation_is_exact():
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.array([0.1, 0.0]),
                      np.random.default_rng(2), layout=LAYOUT)
    res = LipMpc().solve(0.0, np.zeros(3), np.zeros(3), np.zeros(3), plan)
    k, frac = 37, 0.3
    t = (k + frac) * 0.04
    x0 = np.column_stack([res.plan.position[k, :2], res.plan.velocity[k, :2],
                          res.plan.acceleration[k, :2]])            # (2 axes, 3)
    for ax in range(2):
        ref = rollout(x0[ax], [res.jerk[k, ax]], frac * 0.04)[1]   # eq. (2) over frac * dt
        p, v, a = res.plan.sample(t)
        np.testing.assert_allclose([p[ax], v[ax], a[ax]], ref, atol=1e-12)


@pytest.mark.parametrize('formulation', ['dense', 'sparse'])
@pytest.mark.slow
def test_full_formulations_agree(formulation):
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.array([0.1, 0.0]),
                      np.random.default_rng(2), layout=LAYOUT)
    ref = LipMpc().solve(0.0, np.zeros(3), np.zeros(3), np.zeros(3), plan)
    other = LipMpc(MpcSettings(formulation=formulation, eps_abs=1e-7, max_iter=2000)).solve(
        0.0, np.zeros(3), np.zeros(3), np.zeros(3), plan)
    assert other.status == STATUS_SOLVED
    np.testing.assert_allclose(other.zmp, ref.zmp, atol=1e-3)


def test_standing_after_a_crawl_solves_with_no_binding_row():
    """A stand plan (four feet, no step) at rest in the middle of the polygon after crawl
    re-plans (the gait's idle stance): solved, no fallback, the CoM stays where it is."""
    mpc = LipMpc(MpcSettings(zmp_margin=0.02))
    _, res = list(crawl(mpc, seed=3, replans=3))[-1]
    plan = res.plan
    offset = np.array([plan.position[0, 0], plan.position[0, 1], 0.0])
    feet = np.array([[0.37, 0.32, 0.0], [0.37, -0.32, 0.0], [-0.37, 0.32, 0.0],
                     [-0.37, -0.32, 0.0]]) + offset
    t = plan.start_time + 0.76
    stand = FootholdPlan(t, feet, 0.0, [])
    com = np.array([feet[:, 0].mean(), feet[:, 1].mean(), 0.55])
    out = mpc.solve(t, com, np.zeros(3), np.zeros(3), stand)
    assert out.status == STATUS_SOLVED, out.message
    assert not out.fallback
    np.testing.assert_allclose(out.plan.position[:, :2], [com[:2]] * len(out.plan.position),
                               atol=1e-5)


def test_a_stand_replan_after_a_stand_plan_continues_the_plan_in_force():
    """Algorithm 1: a re-plan starts from the measured CoM with the planned acceleration; a
    stand plan after a stand plan continues the plan in force (the idle re-plans must not add
    the controller's tracking offset to the reference every 0.5 s)."""
    mpc = LipMpc(MpcSettings(zmp_margin=0.02))
    walk, res = list(crawl(mpc, seed=3, replans=2))[-1]
    last, t = res.plan, res.plan.start_time + 0.2
    planned = last.sample(t)
    measured_com, measured_vcom = planned[0] + [0.004, -0.002, 0.0], np.array([0.01, 0.0, 0.0])
    stand = stand_plan(FEET, 0.0, t, 0, t + 0.5)
    # Walking, or the first stand plan after walking: the measured state, the planned acc.
    for footholds, stood in ((walk, False), (walk, True), (stand, False)):
        com, vcom, acc = replan_start_state(t, measured_com, measured_vcom, footholds, last,
                                            stood)
        assert com is measured_com and vcom is measured_vcom
        np.testing.assert_array_equal(acc, planned[2])
    # Standing on: the plan in force at t, exactly.
    com, vcom, acc = replan_start_state(t, measured_com, measured_vcom, stand, last, True)
    for got, want in zip((com, vcom, acc), planned, strict=True):
        np.testing.assert_array_equal(got, want)
    # No plan in force yet (or one from the future: a new run): measured, at rest.
    for plan in (None, res.plan):
        com, vcom, acc = replan_start_state(res.plan.start_time - 1.0, measured_com,
                                            measured_vcom, stand, plan, True)
        assert com is measured_com and not acc.any()


def test_polish_keeps_a_working_set_whose_multipliers_are_all_zero():
    """The warm-started rows of a stand re-plan can all end with zero multipliers: the exact
    polish then has nothing to solve (it used to fail on an empty minimum, and the re-plan
    fell back to the relaxed plan)."""
    mpc = LipMpc()
    work, lam = np.array([3, 7]), np.zeros(2)
    out_work, out_lam = mpc._polish(work, lam, None, None, None, None, None)
    assert out_work is work and out_lam is lam


def test_exact_dual_matches_proxsuite_dual_and_a_cold_solve():
    """The active-set dual (default) gives the plan of the proxsuite dual (within the latter's
    tolerance), and a re-plan seeded with the previous plan's rows (shifted in time) the same
    plan as a cold one, to rounding."""
    exact = LipMpc(MpcSettings(zmp_margin=0.02))
    prox = LipMpc(MpcSettings(zmp_margin=0.02, exact_dual=False))
    cold = LipMpc(MpcSettings(zmp_margin=0.02, warm_start=False))
    for plan, res in crawl(exact, 11, 25):
        args = (res.plan.start_time, res.plan.position[0], res.plan.velocity[0],
                res.plan.acceleration[0], plan)
        ref = prox.solve(*args)
        cold.reset()
        fresh = cold.solve(*args)
        assert res.status == ref.status == fresh.status == STATUS_SOLVED
        assert res.max_zmp_violation_m <= 1e-6
        np.testing.assert_allclose(res.jerk, fresh.jerk, atol=1e-8)
        np.testing.assert_allclose(res.zmp, ref.zmp, atol=1e-5)
        assert res.cost == pytest.approx(ref.cost, rel=1e-6)


def test_nnqp_meets_the_kkt_conditions_or_reports_unboundedness():
    """Random non-negative QPs, full-rank and rank-deficient (rows of one sample), warm and
    cold: the active-set solver returns a KKT point, or says the dual is unbounded."""
    rng = np.random.default_rng(0)
    for trial in range(300):
        m = int(rng.integers(1, 20))
        r = int(rng.integers(1, m + 4))
        B = rng.normal(size=(m, r))
        M = B @ B.T
        dg = np.sqrt(np.diag(M))
        M = M / dg[:, None] / dg[None, :]
        if trial % 3:              # bounded: g'v >= 0 on every v >= 0 with M v = 0
            g = -M @ rng.normal(size=m) + np.abs(rng.normal(size=m)) * (rng.random(m) < 0.5)
        else:
            g = rng.normal(size=m)
        x0 = np.maximum(rng.normal(size=m), 0.0) * (trial % 2)
        x, _, why = _nnqp(M, g, x0, 3 * m + 10)
        if r >= m or trial % 3:
            assert why == '', (trial, why)
        if why == '':
            w = M @ x + g
            assert x.min() >= 0.0 and w.min() >= -1e-6 and abs(x @ w) < 1e-6
        else:
            assert why == 'unbounded'
    # Two opposite rows of one sample that cannot both hold: unbounded.
    x, _, why = _nnqp(np.array([[1.0, -1.0], [-1.0, 1.0]]), np.array([-1.0, -1.0]),
                      np.zeros(2), 10)
    assert x is None and why == 'unbounded'


def test_infeasible_replan_fails_fast_to_the_relaxed_plan():
    """The infeasible problem of test_bad_input.py: the exact dual reports it (unbounded or
    dependent rows) within the iteration budget instead of handing it to proxsuite, which
    iterated for seconds on it."""
    plan = crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.zeros(2), np.random.default_rng(0),
                      layout=LAYOUT)
    mpc = LipMpc()
    res = mpc.solve(0.0, np.array([1.5, 0.0, 0.55]), np.array([1.0, 0.0, 0.0]), np.zeros(3),
                    plan)
    assert res.status == STATUS_INFEASIBLE and res.fallback == FALLBACK_RELAXED
    assert 'working-set dual' in res.reason or 'iteration budget' in res.reason, res.reason
    assert res.iterations < 3 * mpc.settings.iteration_budget


def test_solve_reports_its_cpu_time_next_to_its_wall_time():
    mpc = LipMpc(MpcSettings())
    results = [res for _, res in crawl(mpc, 4, 5)]
    results.append(mpc.solve(0.0, np.full(3, np.nan), np.zeros(3), np.zeros(3),
                             crawl_plan(0.0, np.zeros(3), 0.0, FEET, 2, np.zeros(2),
                                        np.random.default_rng(0),
                                        layout=LAYOUT)))     # a rejected input
    for res in results:
        assert math.isfinite(res.solve_cpu_ms) and res.solve_cpu_ms > 0.0
        # One thread: it cannot use more CPU than wall time (the CPU clock's span is a few
        # calls longer; 0.2 ms covers it).
        assert res.solve_cpu_ms <= res.solve_time_ms + 0.2


def test_bench_idle_modes_solve_the_same_problems():
    """The benchmark's idle modes change only what happens between re-plans, not the problems
    solved; an unknown mode is refused."""

    results = [run(MpcSettings(), bench_crawl('hyq', ROOT), replans=4, idle=0.002, idle_mode=mode)
               for mode in ('sleep', 'spin', 'evict')]
    assert [r['idle_mode'] for r in results] == ['sleep', 'spin', 'evict']
    for key in ('n_variables', 'triangle_samples_first_plan', 'quad_samples_first_plan'):
        assert len({r[key] for r in results}) == 1, key
    with pytest.raises(ValueError, match='idle_mode'):
        run(MpcSettings(), bench_crawl('hyq', ROOT), replans=2, idle=0.001, idle_mode='nap')


def test_the_bench_crawl_is_the_robot_files():
    """mpc_bench --robot: the crawl of a robot file, scaled from the reference's; a bad name is
    a one-line error."""
    hyq, go1 = bench_crawl('hyq', ROOT), bench_crawl('go1', ROOT)
    assert hyq.com_height is None and (hyq.swing, hyq.four_feet, hyq.speed_scale) == (
        SWING, FOUR_FEET, 1.0)
    # Go1's legs are 0.61 of HyQ's: its pendulum time and Froude speed 0.78 of HyQ's.
    assert 0.6 < go1.swing / SWING < 0.85
    assert go1.swing / SWING == pytest.approx(go1.four_feet / FOUR_FEET)
    assert 0.6 < go1.speed_scale < 0.85 and 0.2 < go1.com_height < 0.3
    assert np.all(np.abs(go1.feet_xy) < np.abs(hyq.feet_xy))
    result = run(MpcSettings(com_height=go1.com_height), go1, replans=6)
    assert result['statuses'] == {'solved': 6} and result['max_zmp_violation_m'] < 1e-6
    with pytest.raises(ValueError, match="unknown robot 'nosuch'"):
        bench_crawl('nosuch', ROOT)
