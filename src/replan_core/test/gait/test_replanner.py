"""The gait side of the re-plan protocol (replanner.GaitReplanner), with fixed stamps: the
initial plan, re-plan triggers, forced touchdowns, republished and lost ticks, a new run,
idle stance and walking off, a foot still in the air, and set-point checks."""


import numpy as np
import pytest
from gait_config import CONFIG

from replan_core.common.types import GRAVITY, BaseState, ContactState
from replan_core.gait.crawl import GaitParams, is_stand_plan
from replan_core.gait.gait_file import load_gait
from replan_core.gait.replanner import GaitReplanner, Replan, capture_offset, check_setpoint

TICK = 0.004          # s
FEET = np.array([[0.44, 0.33, 0.0], [0.44, -0.33, 0.0], [-0.44, 0.33, 0.0],
                 [-0.44, -0.33, 0.0]])
BASE = BaseState(0.0, np.array([0.0, 0.0, 0.55]), np.array([0.0, 0.0, 0.0, 1.0]),
                 np.zeros(3), np.zeros(3))
WALK = np.array([0.1, 0.0, 0.0])
ZERO = np.zeros(3)


def contacts(t: float, contact=(1, 1, 1, 1), feet=FEET) -> ContactState:
    return ContactState(t, feet.copy(), np.zeros((4, 3)), np.array(contact, bool),
                        np.zeros(4, bool), np.zeros(4, bool))


def make(**gait) -> tuple[GaitReplanner, list, list]:
    logs, warnings = [], []
    replanner = GaitReplanner(GaitParams(**gait), 0.5, 0.3, start_delay=1.0,
                              log=lambda level, text: logs.append((level, text)),
                              warn=lambda key, text: warnings.append(key))
    return replanner, logs, warnings


def plan_now(replanner, setpoint=WALK, source='cmd_vel'):
    plan = replanner.plan_pending(BASE, None, setpoint, source)
    assert plan is not None and replanner.pending is None
    replanner.adopt(plan)
    return plan


def run_until_pending(replanner, t: float, contact_of=lambda t: (1, 1, 1, 1),
                      limit: float = 20.0) -> float:
    """Ticks from ``t`` on until a re-plan is due; its time."""
    while t < limit:
        replanner.tick(contacts(t, contact_of(t)))
        if replanner.pending is not None:
            return t
        t = round(t + TICK, 6)
    raise AssertionError('no re-plan came')


def test_the_first_state_seen_is_planned_with_the_start_delay():
    replanner, logs, _ = make()
    replanner.tick(contacts(0.0))
    assert replanner.pending.initial and replanner.pending.stamp == 0
    plan = plan_now(replanner)
    assert plan.start_time == 0.0 and len(plan.steps) == 8
    assert plan.steps[0].liftoff_time == pytest.approx(1.0)      # after start_delay
    assert plan.min_swing_fraction == 0.5 and plan.max_extension == 0.3
    assert replanner.replans == 1
    assert logs == [('info', 'initial plan at t=0.000 s: stand 1.0 s, then lh first')]


def test_a_replan_step_touching_down_makes_a_replan_due_at_its_tick():
    replanner, _, _ = make()
    replanner.tick(contacts(0.0))
    plan = plan_now(replanner)
    first = plan.steps[0]
    # The swing leg's contact comes back at its planned touchdown (haptic).
    def contact_of(t):
        flags = [1, 1, 1, 1]
        if first.liftoff_time < t < first.touchdown_time:
            flags[first.leg] = 0
        return flags
    t = run_until_pending(replanner, TICK, contact_of)
    assert first.replan
    assert t == pytest.approx(first.touchdown_time, abs=TICK)
    assert not replanner.pending.initial
    assert replanner.schedule.next_leg != first.leg
    # A republished tick changes nothing.
    pending = replanner.pending
    replanner.tick(contacts(t))
    assert replanner.pending is pending


def test_a_forced_touchdown_is_counted_and_logged():
    replanner, logs, _ = make()
    replanner.tick(contacts(0.0))
    first = plan_now(replanner).steps[0]
    # Never any contact of the swing leg after its lift-off: forced at touchdown + 0.3 s.
    def contact_of(t):
        flags = [1, 1, 1, 1]
        if t > first.liftoff_time:
            flags[first.leg] = 0
        return flags
    t = run_until_pending(replanner, TICK, contact_of)
    assert t == pytest.approx(first.touchdown_time + 0.3, abs=TICK)
    assert replanner.forced == 1
    assert logs[-1][0] == 'warning' and 'touchdown forced' in logs[-1][1]
    # The foot is still in the air: it is planned at the height of its foothold.
    air = FEET.copy()
    air[first.leg, 2] = 0.07
    replanner.pending.contacts = contacts(t, contact_of(t), feet=air)
    plan = plan_now(replanner)
    assert plan.initial_feet[first.leg, 2] == pytest.approx(first.target[2])


def test_lost_ticks_are_warned_and_time_going_back_starts_a_new_run():
    replanner, logs, warnings = make()
    replanner.tick(contacts(0.0))
    plan_now(replanner)
    replanner.tick(contacts(TICK))
    replanner.tick(contacts(2 * TICK))
    assert not replanner.tick(contacts(5 * TICK))      # two ticks lost
    assert warnings == ['ticks lost']
    assert replanner.tick(contacts(TICK))              # a new run
    assert replanner.pending.initial and replanner.replans == 0 and replanner.plan is None
    assert logs[-1] == ('warning', 'gait: sim time went back from 0.020 s to 0.004 s; '
                                   'starting over with a new initial plan')


def test_a_robot_never_told_to_walk_stands_from_its_first_plan_until_a_setpoint():
    replanner, logs, _ = make()
    replanner.tick(contacts(0.0))
    plan = plan_now(replanner, ZERO)
    assert is_stand_plan(plan) and replanner.standing
    assert logs == [('info', 'initial plan at t=0.000 s: standing still until a non-zero '
                             'set-point')]
    # A trigger every idle_replan_period, each re-plan standing again: no step ever lifts off.
    t = 0.0
    for _ in range(6):
        trigger = replanner.plan.steps[0]
        assert trigger.liftoff_time == trigger.touchdown_time == pytest.approx(
            t + 0.5 - 0.5 * TICK)
        t = run_until_pending(replanner, round(t + TICK, 6))
        assert is_stand_plan(plan_now(replanner, ZERO))
    # The first set-point walks off after one four-feet phase, the first leg of the sequence.
    t = run_until_pending(replanner, round(t + TICK, 6))
    plan = plan_now(replanner, WALK)
    assert not is_stand_plan(plan) and len(plan.steps) == 8
    assert plan.steps[0].liftoff_time == pytest.approx(t + 0.25)
    assert plan.steps[0].leg == 2                      # lh, the sequence's first
    assert logs[-1][1].startswith(f'walking again at t={t:.3f} s (cmd_vel')


def test_without_idle_stance_the_first_plan_steps_in_place_after_the_start_delay():
    replanner, _, _ = make(idle_stance=False)
    replanner.tick(contacts(0.0))
    plan = plan_now(replanner, ZERO)
    assert not is_stand_plan(plan) and plan.steps[0].liftoff_time == pytest.approx(1.0)


def test_zero_setpoint_for_idle_after_stands_and_a_new_one_walks_off():
    replanner, logs, _ = make(idle_after=2.5)
    replanner.tick(contacts(0.0))
    t, plans = 0.0, [plan_now(replanner, WALK)]
    on_time = late_touchdowns(replanner, 0.0)
    t = run_until_pending(replanner, round(t + TICK, 6), on_time)
    plans.append(plan_now(replanner, ZERO))
    zero_at = t
    while not replanner.standing:
        t = run_until_pending(replanner, round(t + TICK, 6), on_time)
        plans.append(plan_now(replanner, ZERO))
    assert t - zero_at >= 2.5 - 0.5 * GaitParams().step_period
    # The plan before the stand ends at its trigger (the feet stay down from that touchdown
    # on, so the MPC settles the CoM during the last swing); the ones before it do not.
    before = plans[-2]
    assert len(before.steps) == 1 and before.steps[0].replan
    assert len(plans) >= 3 and all(len(p.steps) == 8 for p in plans[:-2])
    assert is_stand_plan(replanner.plan) and len(replanner.plan.steps) == 1
    trigger = replanner.plan.steps[0]
    assert trigger.liftoff_time == pytest.approx(t + 0.5 - 0.5 * TICK)   # off the tick grid
    assert ('info', f'idle stance at t={t:.3f} s: set-point zero since {zero_at:.3f} s, all '
                    'four feet down') in logs
    # The trigger's tick re-plans; a set-point then walks off: the reference trunk stands
    # through a four-feet phase first.
    t = run_until_pending(replanner, round(t + TICK, 6))
    plan = plan_now(replanner, WALK, 'cmd_vel_stamped')
    assert not is_stand_plan(plan)
    assert plan.steps[0].liftoff_time == pytest.approx(t + 0.25)
    assert logs[-1][1].startswith(f'walking again at t={t:.3f} s (cmd_vel_stamped')


def late_touchdowns(replanner, late: float):
    """Contact flags of a swing leg that comes back ``late`` s after its planned touchdown."""
    def contact_of(t):
        flags = [1, 1, 1, 1]
        step = replanner.plan.steps[0]
        if step.liftoff_time < t < step.touchdown_time + late:
            flags[step.leg] = 0
        return flags
    return contact_of


@pytest.mark.parametrize('measured', [True, False])
def test_late_touchdowns_stretch_the_strides_from_the_second_step(measured):
    replanner, _, _ = make(measured_step_period=measured, foothold_correction=False)
    replanner.tick(contacts(0.0))
    plan_now(replanner)
    t, scales = 0.0, []
    for _ in range(7):
        t = run_until_pending(replanner, round(t + TICK, 6), late_touchdowns(replanner, 0.04))
        scales.append(replanner.stride_time_scale)
        plan = plan_now(replanner)
    # Steps of 0.75 + 0.04 s (on the tick grid): measured from the second touchdown on (the
    # first interval), never from the start's standing delay.
    period = replanner.timing.measured_period
    assert period == pytest.approx(0.79, abs=TICK)
    expected = period / 0.75 if measured else 1.0
    assert scales[0] == 1.0 and scales[1:] == [pytest.approx(expected, abs=TICK)] * 6
    # The first stride of the last plan is stretched accordingly (0.1 m/s straight walk).
    step = plan.steps[0]
    stride = step.target[0] - plan.initial_feet[step.leg, 0]
    assert stride == pytest.approx(0.1 * 3.0 * expected, abs=1e-9)


def test_a_plan_that_cannot_be_computed_keeps_the_previous_one():
    replanner, logs, _ = make()
    replanner.tick(contacts(0.0))
    plan = plan_now(replanner)
    replanner.params.n_footholds = 0             # invalid: compute_footholds refuses
    replanner.pending = Replan(4_000_000, contacts(TICK), False)
    assert replanner.plan_pending(BASE, None, WALK, 'cmd_vel') is None
    assert replanner.pending is None and replanner.plan is plan
    assert logs[-1][0] == 'error' and 'keeping the previous plan' in logs[-1][1]


@pytest.mark.parametrize('value, expected, problem', [
    ((0.1, 0.0, 0.0), (0.1, 0.0, 0.0), ''),
    ((0.5, 0.0, 0.0), (0.2, 0.0, 0.0), 'clamped to'),
    ((float('nan'), 0.0, 0.0), None, 'non-finite or above 10.0'),
    ((11.0, 0.0, 0.0), None, 'non-finite or above 10.0'),
])
def test_setpoints_are_rejected_or_clamped(value, expected, problem):
    v, text = check_setpoint(value, 10.0, [GaitParams()])
    assert (v is None) == (expected is None)
    if expected is not None:
        assert np.allclose(v, expected)
    assert problem in text and (text == '') == (problem == '')


def test_the_trend_shift_is_known_once_a_cycle_is_walked_at_the_set_point():
    """The shift of the hips the foothold correction places the feet about: none (the actual
    hips) until a cycle of re-plans at the set-point is known, then the trunk's trend minus the
    base (speed_feedback.trunk_trend), sway removed; a new set-point goes back to none, and so
    does correction_hips 'actual'."""
    replanner, _, _ = make()
    params = replanner.params
    step = params.step_period
    shifts = []
    for k in range(6):
        t = 5.0 + k * step
        sway = 0.03 * np.sin(2 * np.pi * t / params.cycle_duration)
        base = BaseState(t, np.array([0.1 * t, sway, 0.55]), np.array([0.0, 0.0, 0.0, 1.0]),
                         np.zeros(3), np.zeros(3))
        shifts.append(replanner._trend_shift(t, base, 0.0, WALK))
    assert [s is not None for s in shifts] == [False, False, False, True, True, True]
    np.testing.assert_allclose(shifts[-1], [0.0, -sway], atol=1e-12)   # the trend: y = 0
    base = BaseState(t + step, np.array([0.1 * (t + step), 0.0, 0.55]),
                     np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))
    assert replanner._trend_shift(t + step, base, 0.0, np.array([0.05, 0.0, 0.0])) is None
    actual = make(correction_hips='actual')[0]
    assert actual._trend_shift(t, base, 0.0, WALK) is None


def test_each_leg_remembers_the_setpoint_it_was_placed_for_and_when_it_changed():
    """The feed-forward of a set-point change (gait.compute_footholds, placed_twists): a leg's
    touchdown records the twist of the plan in force; a plan with another twist marks, for the
    legs placed before, the re-plan it came at."""
    replanner, _, _ = make()
    replanner.tick(contacts(0.0))
    plan_now(replanner, WALK)
    assert not np.any(replanner.placed_twists) and np.all(replanner.placed_until == 0.0)
    lift = replanner.plan.steps[0]
    swinging = tuple(0 if leg == lift.leg else 1 for leg in range(4))
    t = run_until_pending(replanner, TICK, lambda t: swinging
                          if lift.liftoff_time < t < lift.touchdown_time else (1, 1, 1, 1))
    assert np.array_equal(replanner.placed_twists[lift.leg], WALK)
    assert replanner.placed_until[lift.leg] == np.inf
    side = np.array([0.0, 0.05, 0.0])
    plan_now(replanner, side)
    assert replanner.placed_until[lift.leg] == t      # placed for WALK, changed now
    others = [leg for leg in range(4) if leg != lift.leg]
    assert np.all(replanner.placed_until[others] == 0.0)   # placed standing: since the start


def test_a_trot_replans_at_the_second_touchdown_of_each_pair():
    params = load_gait('trot', CONFIG).params()
    replanner = GaitReplanner(params, 0.5, 0.3, start_delay=1.0)
    replanner.tick(contacts(0.0))
    plan = plan_now(replanner)
    assert len(plan.steps) == 2 * params.n_footholds
    a, b = plan.steps[:2]
    assert {a.leg, b.leg} == {0, 3} and a.liftoff_time == b.liftoff_time

    def contact_of(t):                # LF lands at its planned touchdown, RH 20 ms later
        flags = [1, 1, 1, 1]
        if a.liftoff_time < t < a.touchdown_time:
            flags[0] = 0
        if a.liftoff_time < t < a.touchdown_time + 0.02:
            flags[3] = 0
        return flags

    t = run_until_pending(replanner, TICK, contact_of)
    assert t == pytest.approx(a.touchdown_time + 0.02, abs=TICK)
    assert replanner.schedule.next_leg == 1          # the other pair: RF (with LH)
    plan = plan_now(replanner)
    assert {plan.steps[0].leg, plan.steps[1].leg} == {1, 2}
    assert plan.steps[0].liftoff_time == pytest.approx(t)   # no four-feet phase


def swing_contacts(plan):
    """Each swing's contact away from lift-off to the planned touchdown (haptic)."""
    def contact_of(t):
        flags = [1, 1, 1, 1]
        for step in plan.steps:
            if step.liftoff_time < t < step.touchdown_time:
                flags[step.leg] = 0
        return flags
    return contact_of


def test_a_gait_switch_waits_for_the_next_replan_and_starts_after_the_last_leg_down():
    crawl, trot = load_gait('crawl', CONFIG).params(), load_gait('trot', CONFIG).params()
    replanner, logs, _ = make()
    replanner.tick(contacts(0.0))
    plan = plan_now(replanner)
    replanner.switch_gait(trot)
    assert replanner.params == crawl          # not before the next re-plan: mid-step
    t = run_until_pending(replanner, TICK, swing_contacts(plan))
    first = plan.steps[0]
    assert t == pytest.approx(first.touchdown_time, abs=TICK)
    plan = plan_now(replanner)
    assert replanner.params == trot and replanner.next_params is None
    # The crawl's first leg (lh) touched down last: the trot's next pair is the one after
    # lh's, (lf, rh); both lift off together after the crawl's four-feet phase (the trot has
    # none), in which the trunk moves from the crawl's staggered stance over the diagonals.
    pair = plan.steps[:2]
    assert {s.leg for s in pair} == {0, 3}
    assert crawl.four_feet_duration > trot.four_feet_duration == 0.0
    assert pair[0].liftoff_time == pair[1].liftoff_time == pytest.approx(
        t + crawl.four_feet_duration)
    assert pair[0].touchdown_time - pair[0].liftoff_time == pytest.approx(trot.swing_duration)
    assert any('gait switched' in text for _, text in logs)
    # The measures over a cycle restart with the new gait's.
    assert replanner.timing.measured_period is None
    # And back: the crawl after the trot's pair, one leg at a time.
    replanner.switch_gait(crawl)
    t = run_until_pending(replanner, t + TICK, swing_contacts(plan))
    plan = plan_now(replanner)
    assert replanner.params == crawl
    assert plan.steps[0].liftoff_time != plan.steps[1].liftoff_time
    assert plan.steps[0].liftoff_time == pytest.approx(t + crawl.four_feet_duration)


def test_switching_to_the_gait_in_force_changes_nothing():
    replanner, _, _ = make()
    replanner.switch_gait(GaitParams())
    assert replanner.next_params is None


def test_a_setpoint_is_clamped_to_the_widest_gait_of_the_run():
    crawl, trot = load_gait('crawl', CONFIG).params(), load_gait('trot', CONFIG).params()
    v, text = check_setpoint([0.37, 0.0, 0.0], 10.0, [crawl])
    assert v[0] < 0.37 and 'clamped' in text
    v, text = check_setpoint([0.37, 0.0, 0.0], 10.0, [crawl, trot])
    assert v[0] == 0.37 and text == ''


def test_a_stopping_plan_places_the_feet_about_where_the_moving_trunk_comes_to_rest():
    # Two runs the same but for the base's velocity at the re-plan after the stop: the
    # footholds of the moving trunk are shifted by its capture point, v / omega (LIP), once:
    # a leg's later footholds follow its first.
    moving = BaseState(0.0, BASE.position.copy(), BASE.quaternion.copy(),
                       np.array([0.3, -0.1, 0.0]), np.zeros(3))
    stop_plans = []
    for base in (BASE, moving):
        replanner, _, _ = make()
        replanner.tick(contacts(0.0))
        plan = plan_now(replanner)
        run_until_pending(replanner, TICK, swing_contacts(plan))
        stop = replanner.plan_pending(base, None, ZERO, 'cmd_vel')
        assert stop is not None and not is_stand_plan(stop)   # steps in place before standing
        stop_plans.append(stop)
    omega = np.sqrt(GRAVITY / 0.55)                   # 1/s, the base 0.55 m above the feet
    for still, shifted in zip(*(p.steps for p in stop_plans), strict=True):
        np.testing.assert_allclose(shifted.target[:2] - still.target[:2],
                                   np.array([0.3, -0.1]) / omega, atol=1e-12)


def test_capture_offset_is_in_the_body_frame_and_zero_at_rest():
    half_turn = BaseState(0.0, BASE.position.copy(), np.array([0.0, 0.0, 1.0, 0.0]),
                          np.array([0.3, 0.0, 0.0]), np.zeros(3))
    omega = np.sqrt(GRAVITY / 0.55)
    np.testing.assert_allclose(capture_offset(half_turn, FEET, np.pi), [-0.3 / omega, 0.0],
                               atol=1e-12)
    np.testing.assert_array_equal(capture_offset(BASE, FEET, 0.0), np.zeros(2))


def test_capture_offset_is_zero_for_a_base_not_above_its_feet():
    moving = np.array([0.3, 0.2, 0.0])
    for height in (0.0, -0.1, np.nan):
        base = BaseState(0.0, np.array([0.0, 0.0, height]), BASE.quaternion.copy(),
                         moving, np.zeros(3))
        np.testing.assert_array_equal(capture_offset(base, FEET, 0.0), np.zeros(2))
    above = BaseState(0.0, np.array([0.0, 0.0, 0.55]), BASE.quaternion.copy(), moving,
                      np.zeros(3))
    assert np.all(capture_offset(above, FEET, 0.0) != 0.0)     # the same motion, standing
