"""The shared touchdown rule (touchdown.StepTracker)."""

import numpy as np
import pytest

from replan_core.common.types import FootholdPlan, Step
from replan_core.gait.touchdown import StepTracker

DT = 0.004    # s, control tick


def tick(k):
    """Tick times as the simulator makes them: integer count times the period."""
    return k * DT


def make_plan(haptic=True, replan=(True, True, True), four_feet=0.2, swing=0.4, t0=0.0):
    feet = np.array([[0.37, 0.2, 0.0], [0.37, -0.2, 0.0], [-0.37, 0.2, 0.0], [-0.37, -0.2, 0.0]])
    steps = []
    t = t0
    for i, leg in enumerate((2, 0, 3)):
        lo = t + four_feet
        td = lo + swing
        steps.append(Step(leg=leg, liftoff_time=lo, touchdown_time=td,
                          target=feet[leg] + [0.1, 0.0, 0.0], step_height=0.1, haptic=haptic,
                          replan=replan[i], yaw=0.0))
        t = td
    return FootholdPlan(start_time=t0, initial_feet=feet, initial_yaw=0.0, steps=steps)


def run(tracker, flags_of, k_end):
    """Feed ticks 0..k_end; ``flags_of(k)`` gives the contact flags. Returns all events."""
    events = []
    for k in range(k_end + 1):
        events += tracker.update(tick(k), flags_of(k))
    return events


def all_down(_k):
    return np.ones(4, dtype=bool)


def test_liftoff_at_planned_time_and_swing_state():
    plan = make_plan()
    tracker = StepTracker(plan, min_swing_fraction=0.5, max_extension=0.1)
    k_lo = round(0.2 / DT)
    assert run(tracker, all_down, k_lo - 1) == []
    events = tracker.update(tick(k_lo), np.ones(4, dtype=bool))
    assert [(e.kind, e.step, e.leg) for e in events] == [('liftoff', 0, 2)]
    assert events[0].time == tick(k_lo)
    assert tracker.in_swing.tolist() == [False, False, True, False]
    assert tracker.active_step(2) == 0 and tracker.active_step(0) is None
    assert not tracker.replan_due


def test_non_haptic_ends_at_planned_touchdown_whatever_the_contacts():
    plan = make_plan(haptic=False)
    tracker = StepTracker(plan, min_swing_fraction=0.1, max_extension=0.1)
    # Contact flags set all the time (an early touchdown): ignored without haptic mode.
    events = run(tracker, all_down, round(0.7 / DT))
    td = [e for e in events if e.kind == 'touchdown']
    assert td[0].time == pytest.approx(0.6, abs=1e-9) and td[0].reason == 'planned'
    # No contact at all: it still ends on time.
    tracker2 = StepTracker(plan)
    events2 = run(tracker2, lambda k: np.zeros(4, dtype=bool), round(0.7 / DT))
    first_td = next(e.time for e in events2 if e.kind == 'touchdown')
    assert first_td == pytest.approx(0.6, abs=1e-9)


def test_haptic_ignores_contact_before_min_swing_fraction_then_ends_at_contact():
    plan = make_plan()
    tracker = StepTracker(plan, min_swing_fraction=0.5, max_extension=0.1)
    contact_from = 0.5    # s: contact sensed from here on, before the planned 0.6
    events = run(tracker, lambda k: np.array([True, True, tick(k) < 0.25 or tick(k) >= contact_from,
                                              True]), round(0.5 / DT))
    td = [e for e in events if e.kind == 'touchdown']
    assert len(td) == 1
    assert td[0].time == pytest.approx(0.5, abs=1e-9)
    assert td[0].reason == 'contact' and td[0].replan
    assert tracker.replan_due and tracker.touchdown_reason[0] == 'contact'
    # Flags set right after lift-off (debounce lag) did not end the swing before 0.2 + 0.5 * 0.4.
    assert tracker.touchdown_tick[0] >= 0.4


def test_haptic_contact_exactly_at_the_window_start_counts():
    plan = make_plan()
    tracker = StepTracker(plan, min_swing_fraction=0.5, max_extension=0.1)
    events = run(tracker, all_down, round(0.45 / DT))
    td = [e for e in events if e.kind == 'touchdown']
    assert td[0].time == pytest.approx(0.4, abs=1e-9)   # 0.2 + 0.5 * 0.4, float-tolerant


def test_haptic_late_contact_extends_the_swing():
    plan = make_plan()
    tracker = StepTracker(plan, min_swing_fraction=0.5, max_extension=0.2)
    events = run(tracker, lambda k: np.array([True, True, tick(k) >= 0.66, True]),
                 round(0.9 / DT))
    td = [e for e in events if e.kind == 'touchdown']
    assert td[0].time == pytest.approx(0.66, abs=1e-9) and td[0].reason == 'contact'


def test_haptic_forced_after_max_extension():
    plan = make_plan()
    tracker = StepTracker(plan, min_swing_fraction=0.5, max_extension=0.2)
    events = run(tracker, lambda k: np.array([True, True, False, True]), round(0.9 / DT))
    td = [e for e in events if e.kind == 'touchdown']
    assert td[0].time == pytest.approx(0.8, abs=1e-9) and td[0].reason == 'forced'
    assert tracker.touchdown_reason[0] == 'forced'


def test_replan_touchdown_stops_and_next_liftoff_waits_for_previous_touchdown():
    # K = 2: the first touchdown does not re-plan; the next step lifts off at
    # max(planned lift-off, actual touchdown).
    plan = make_plan(replan=(False, True, False), four_feet=0.048)
    tracker = StepTracker(plan, min_swing_fraction=0.5, max_extension=0.3)
    # Leg 2 touches down at 0.7, 0.252 s late; step 1 was planned to lift off at 0.496.
    late = 0.7
    flags = lambda k: np.array([tracker.active_step(0) is None or tick(k) >= 1.0,  # noqa: E731
                                True, tick(k) < 0.1 or tick(k) >= late, True])
    events = []
    for k in range(round(1.6 / DT) + 1):
        events += tracker.update(tick(k), flags(k))
        if tracker.replan_due:
            break
    kinds = [(e.kind, e.step, round(e.time, 6), e.reason) for e in events]
    assert kinds[:3] == [('liftoff', 0, 0.048, 'planned'), ('touchdown', 0, 0.7, 'contact'),
                         ('liftoff', 1, 0.7, 'planned')]
    # The haptic window of step 1 opens at 0.7 + 0.5 * 0.4 = 0.9; forced would be 1.196.
    assert kinds[3] == ('touchdown', 1, 1.0, 'contact')
    assert len(kinds) == 4
    assert tracker.replan_due and events[-1].replan
    assert tracker.next_step == 2      # a replan touchdown does not start the next step


def test_duplicate_and_start_ticks_change_nothing():
    plan = make_plan(t0=1.0)
    tracker = StepTracker(plan)
    assert tracker.update(1.0, np.zeros(4, dtype=bool)) == []
    assert tracker.update(0.5, np.zeros(4, dtype=bool)) == []
    events = tracker.update(1.2, np.ones(4, dtype=bool))
    assert [e.kind for e in events] == ['liftoff']
    assert tracker.update(1.2, np.ones(4, dtype=bool)) == []
    assert tracker.in_swing[2]


def test_done_after_last_step():
    plan = make_plan(haptic=False, replan=(False, False, False))
    tracker = StepTracker(plan)
    run(tracker, all_down, round(2.0 / DT))
    assert tracker.done and not tracker.in_swing.any()
    assert [tracker.touchdown_reason[i] for i in range(3)] == ['planned'] * 3


def test_two_trackers_fed_the_same_ticks_decide_the_same():
    rng = np.random.default_rng(4)
    plan = make_plan(replan=(False, False, True))
    flags = rng.random((400, 4)) < 0.3
    a, b = StepTracker(plan, 0.4, 0.15), StepTracker(plan, 0.4, 0.15)
    for k in range(400):
        ea = a.update(tick(k), flags[k])
        eb = b.update(tick(k), flags[k].copy())
        assert ea == eb
        assert a.replan_due == b.replan_due


def test_bad_parameters_are_rejected():
    with pytest.raises(ValueError):
        StepTracker(make_plan(), min_swing_fraction=1.5)
    with pytest.raises(ValueError):
        StepTracker(make_plan(), max_extension=-0.1)


# -- groups of legs (a trot's diagonal pairs) ---------------------------------------------------
def make_pair_plan(haptic=True, replan=True, four_feet=0.0, swing=0.3, t0=0.0):
    """Two steps of a trot: LF + RH, then RF + LH (leg indices 0, 3 then 1, 2)."""
    feet = np.array([[0.37, 0.2, 0.0], [0.37, -0.2, 0.0], [-0.37, 0.2, 0.0], [-0.37, -0.2, 0.0]])
    steps = []
    t = t0
    for pair in ((0, 3), (1, 2)):
        lo = t + four_feet
        td = lo + swing
        for leg in pair:
            steps.append(Step(leg=leg, liftoff_time=lo, touchdown_time=td,
                              target=feet[leg] + [0.1, 0.0, 0.0], step_height=0.08,
                              haptic=haptic, replan=replan, yaw=0.0))
        t = td
    return FootholdPlan(start_time=t0, initial_feet=feet, initial_yaw=0.0, steps=steps)


def test_pair_lifts_off_together():
    tr = StepTracker(make_pair_plan(four_feet=0.1), 0.5, 0.3)
    events = run(tr, all_down, 25)               # lift-off planned at 0.1 s = tick 25
    assert [(e.kind, e.leg, e.time) for e in events] == [('liftoff', 0, tick(25)),
                                                         ('liftoff', 3, tick(25))]
    assert tr.in_swing.tolist() == [True, False, False, True]
    assert tr.active_step(0) == 0 and tr.active_step(3) == 1 and tr.active_step(1) is None
    assert tr.active == 0


def test_each_foot_lands_by_itself_and_the_second_touchdown_replans():
    tr = StepTracker(make_pair_plan(), 0.5, 0.3)
    # LF (leg 0) touches at tick 60 (0.24 s), RH (leg 3) at tick 80 (0.32 s).
    def flags(k):
        f = np.zeros(4, dtype=bool)
        f[1] = f[2] = True
        f[0] = k >= 60
        f[3] = k >= 80
        return f

    events = run(tr, flags, 79)
    first = [e for e in events if e.kind == 'touchdown']
    assert [(e.leg, e.time, e.reason, e.replan, e.completes_group) for e in first] == [
        (0, tick(60), 'contact', False, False)]
    assert not tr.replan_due
    assert tr.in_swing.tolist() == [False, False, False, True]
    assert tr.swing_start(2) == pytest.approx(0.3)     # the other pair waits for RH's plan
    events = tr.update(tick(80), flags(80))
    assert [(e.kind, e.leg, e.replan, e.completes_group) for e in events] == [
        ('touchdown', 3, True, True)]
    assert tr.replan_due                          # the pair's second touchdown
    assert tr.liftoff_tick[2] is None             # the rest is superseded


def test_both_feet_on_one_tick_give_one_replan_on_the_last_event():
    tr = StepTracker(make_pair_plan(), 0.5, 0.3)
    # Contact all along: lift-off at the first tick after the start, touchdown at the first
    # tick half a swing later (0.004 + 0.15 s: tick 39).
    events = run(tr, all_down, 39)
    downs = [e for e in events if e.kind == 'touchdown']
    assert [(e.leg, e.time) for e in downs] == [(0, tick(39)), (3, tick(39))]
    assert [(e.replan, e.completes_group) for e in downs] == [(False, False), (True, True)]
    assert tr.replan_due


def test_next_pair_waits_for_the_late_foot_of_the_previous_one():
    tr = StepTracker(make_pair_plan(replan=False), 0.5, 0.3)

    def flags(k):                                 # RH late: 0.36 s (tick 90)
        f = np.ones(4, dtype=bool)
        f[0] = k >= 70
        f[3] = k >= 90
        f[1] = f[2] = k < 91 or k >= 130
        return f

    events = run(tr, flags, 140)
    lifts = [(e.leg, e.time) for e in events if e.kind == 'liftoff']
    assert lifts[2:] == [(1, tick(90)), (2, tick(90))]     # on the tick RH landed, as a crawl
    assert tr.swing_start(2) == pytest.approx(tick(90))
    downs = [(e.leg, e.time, e.replan) for e in events if e.kind == 'touchdown']
    assert downs == [(0, tick(70), False), (3, tick(90), False), (1, tick(130), False),
                     (2, tick(130), False)]
    assert tr.done


def test_forced_foot_of_a_pair_completes_it():
    tr = StepTracker(make_pair_plan(), 0.5, 0.3)

    def flags(k):                                 # RH never senses contact
        f = np.ones(4, dtype=bool)
        f[3] = False
        return f

    events = run(tr, flags, 150)                  # forced at 0.3 + 0.3 = 0.6 s = tick 150
    downs = [(e.leg, e.time, e.reason, e.replan) for e in events if e.kind == 'touchdown']
    assert downs == [(0, tick(39), 'contact', False), (3, tick(150), 'forced', True)]
    assert tr.replan_due


def test_crawl_steps_with_equal_times_of_one_leg_are_not_a_group():
    from replan_core.gait.touchdown import step_groups
    plan = make_plan()
    assert step_groups(plan.steps) == [[0], [1], [2]]
    assert step_groups(make_pair_plan().steps) == [[0, 1], [2, 3]]
    same = [plan.steps[0], plan.steps[0]]          # the same leg twice: two steps
    assert step_groups(same) == [[0], [1]]


# -- the plan latency -----------------------------------------------------------------------------
def test_nothing_lifts_off_before_the_plan_takes_effect():
    plan = make_pair_plan(four_feet=0.0)
    plan.latency = 0.058                         # takes effect at the first tick >= 0.058 s
    tr = StepTracker(plan, 0.5, 0.3)
    assert run(tr, all_down, 14) == []
    events = tr.update(tick(15), all_down(15))
    assert [(e.kind, e.leg) for e in events] == [('liftoff', 0), ('liftoff', 3)]
    # The touchdown window counts from the actual lift-off: 0.060 + 0.5 * 0.3 = 0.210 s.
    assert run_from(tr, all_down, 16, 52) == []
    assert [e.kind for e in tr.update(tick(53), all_down(53))] == ['touchdown', 'touchdown']


def run_from(tracker, flags_of, k_start, k_end):
    events = []
    for k in range(k_start, k_end + 1):
        events += tracker.update(tick(k), flags_of(k))
    return events


def test_a_tracker_started_when_the_plan_takes_effect_decides_as_one_started_at_its_trigger():
    """The gait node tracks a plan from its trigger, the controller from the tick it takes
    effect (it tracks the old plan until then): both must decide every event alike, or the
    controller meets re-plans it did not expect."""
    rng = np.random.default_rng(7)
    flags = rng.random((300, 4)) < 0.4
    for latency in (0.0, 0.01, 0.058, 0.2):
        plan = make_pair_plan(four_feet=0.0, swing=0.2)
        plan.latency = latency
        gait, wbc = StepTracker(plan, 0.5, 0.3), StepTracker(plan, 0.5, 0.3)
        effect = int(np.ceil(latency / DT - 1e-9)) or 1      # the controller's first tick
        for k in range(1, 300):
            from_trigger = gait.update(tick(k), flags[k])
            if k >= effect:
                assert wbc.update(tick(k), flags[k]) == from_trigger, (latency, k)
                assert wbc.replan_due == gait.replan_due
            else:
                assert from_trigger == [], (latency, k)
