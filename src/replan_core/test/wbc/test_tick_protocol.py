"""The controller's per-tick protocol (tick_protocol.ControllerProtocol), with fixed stamps
and the real controller: every decision the graph tests see through processes (first plans,
re-plan waits, plan latency, missed re-plans, stale gaps, old plans, stand, stand-up, fall);
the wait's timer (PlanWait) with fixed times, and the answers kept for a republished tick
(AnsweredTicks)."""

import math

import numpy as np
import pytest

from replan_core.common.types import (
    STANDING_POSE,
    BaseState,
    ComPlan,
    ContactState,
    FootholdPlan,
    JointState,
    Step,
)
from replan_core.robot.model import RobotModel
from replan_core.wbc.controller import WholeBodyController
from replan_core.wbc.settings import ProtocolParams
from replan_core.wbc.tick_protocol import (
    KEEP_COMMANDS,
    KEEP_PLANS,
    AnsweredTicks,
    ControllerProtocol,
    PlanWait,
    WaitChange,
)

NS = 1_000_000_000
TICK = 4_000_000                  # ns, 250 Hz


@pytest.fixture(scope='module')
def wbc(urdf):
    return WholeBodyController(RobotModel(urdf))


class Robot:
    """The inputs of one tick: standing still (or tilted, or with folded legs)."""

    def __init__(self, wbc):
        self.model = wbc.robot

    def tick(self, stamp: int, pose=STANDING_POSE, roll: float = 0.0, contact=(1, 1, 1, 1)):
        t = stamp / NS
        joints = JointState(t, np.array(pose, float), np.zeros(12), np.zeros(12))
        quaternion = np.array([math.sin(roll / 2), 0.0, 0.0, math.cos(roll / 2)])
        base = BaseState(t, np.zeros(3), quaternion, np.zeros(3), np.zeros(3))
        base.position[2] = -self.model.foot_positions(base, joints)[:, 2].mean()
        feet = self.model.foot_positions(base, joints)
        force = np.zeros((4, 3))
        force[:, 2] = self.model.total_mass * 9.81 / 4
        contacts = ContactState(t, feet, force, np.array(contact, bool), np.zeros(4, bool),
                                np.zeros(4, bool))
        return stamp, base, joints, contacts


@pytest.fixture
def robot(wbc):
    return Robot(wbc)


def make_protocol(wbc, **settings) -> tuple[ControllerProtocol, list]:
    logs: list[tuple[str, str]] = []
    protocol = ControllerProtocol(wbc, ProtocolParams(**settings), STANDING_POSE,
                                  log=lambda level, text: logs.append((level, text)))
    return protocol, logs


def plan_pair(robot, stamp: int, liftoff: float = 0.2, swing: float = 0.2,
              steps: int = 1, latency: float = 0.0) -> tuple[FootholdPlan, ComPlan]:
    """``steps`` non-haptic steps (the first of the left front leg ``liftoff`` s after
    ``stamp``, then one every ``liftoff + swing`` s), each of whose planned touchdowns triggers
    a re-plan; the CoM held where it is, over 8 s; the plans of its re-plans take effect
    ``latency`` s after their trigger."""
    _, base, joints, contacts = robot.tick(stamp)
    t = stamp / NS
    feet = contacts.foot_position.copy()
    plan_steps = [Step(leg, t + liftoff + k * (liftoff + swing),
                       t + (k + 1) * (liftoff + swing), feet[leg] + [0.05, 0.0, 0.0], 0.08,
                       False, True, 0.0)
                  for k, leg in enumerate((0, 3, 1, 2)[:steps])]
    com, _ = robot.model.com_state(base, joints)
    samples = 201
    footholds = FootholdPlan(t, feet, 0.0, plan_steps, latency=latency)
    com_plan = ComPlan(t, 0.04, np.tile(com, (samples, 1)), np.zeros((samples, 3)),
                       np.zeros((samples, 3)))
    return footholds, com_plan


def add_pair(protocol, robot, stamp: int, **kw):
    """Both plans stamped ``stamp``; what the second one's arrival answers."""
    footholds, com_plan = plan_pair(robot, stamp, **kw)
    assert protocol.add_footholds(stamp, footholds) is None or not protocol.waiting
    return protocol.add_com_plan(stamp, com_plan)


def answer(protocol, stamp: int):
    result = protocol.control(stamp)
    assert np.all(np.isfinite(result.torque)) and not result.fallback
    restarted = protocol.answered(stamp)
    return result, restarted


def walk_until_replan(protocol, robot, start: int, limit: int = 200) -> int:
    """Ticks from ``start`` on, answered, until one is not answered (held); its stamp."""
    stamp = start
    for _ in range(limit):
        if not protocol.on_tick(*robot.tick(stamp)):
            return stamp
        answer(protocol, stamp)
        stamp += TICK
    raise AssertionError('no tick was held')


def test_the_first_tick_waits_for_the_first_plan_pair_then_answers_with_it(wbc, robot):
    protocol, _ = make_protocol(wbc)
    assert protocol.mode == 'plan' and protocol.waiting is None
    assert not protocol.on_tick(*robot.tick(0))
    assert protocol.waiting == 0 and protocol.waiting_first
    assert not protocol.on_tick(*robot.tick(0))          # the sim's republish: still held
    footholds, com_plan = plan_pair(robot, 0)
    assert protocol.add_footholds(0, footholds) is None   # half a pair answers nothing
    assert protocol.add_com_plan(0, com_plan) == 0        # the held tick, to answer now
    assert protocol.waiting is None and protocol.plan_stamp == 0 and protocol.mode == 'plan'
    result, restarted = answer(protocol, 0)
    assert not restarted and protocol.last_answered == 0
    assert result.stance.all()
    assert not protocol.on_tick(*robot.tick(0))           # answered already: an old stamp


def test_the_first_command_waits_until_the_caller_may_start(wbc, robot):
    protocol, _ = make_protocol(wbc)
    add_pair(protocol, robot, 0)
    assert not protocol.on_tick(*robot.tick(0), may_start=lambda: False)
    assert not protocol.started and protocol.waiting is None
    assert protocol.on_tick(*robot.tick(0), may_start=lambda: True)
    assert protocol.plan_stamp == 0


def test_no_first_plans_in_time_stand_and_a_plan_made_for_now_ends_the_stand(wbc, robot):
    protocol, logs = make_protocol(wbc)
    assert not protocol.on_tick(*robot.tick(0))
    assert protocol.wait_timed_out(30.0) == 0
    assert protocol.wait_timed_out(30.0) is None            # nothing held any more
    assert protocol.mode == 'stand' and protocol.stand_reason == 'no plan yet (plan_timeout)'
    assert protocol.plan_timeouts == 1
    assert any('no plans after 30.0 s' in text for _, text in logs)
    answer(protocol, 0)
    # A plan whose first swing is too close (lead < stand_adopt_lead) does not end it ...
    add_pair(protocol, robot, 2 * TICK, liftoff=0.05)
    assert protocol.on_tick(*robot.tick(3 * TICK))
    assert protocol.mode == 'stand'
    answer(protocol, 3 * TICK)
    # ... one made for now does.
    add_pair(protocol, robot, 4 * TICK)
    assert protocol.on_tick(*robot.tick(4 * TICK))
    assert protocol.mode == 'plan' and protocol.plan_stamp == 4 * TICK


def test_started_mid_plan_stands_until_a_plan_made_for_now(wbc, robot):
    protocol, _ = make_protocol(wbc)
    add_pair(protocol, robot, 0, liftoff=0.05)
    assert protocol.on_tick(*robot.tick(25 * TICK))       # 0.1 s: its lift-off has passed
    assert protocol.mode == 'stand'
    assert protocol.stand_reason == 'started mid-plan: waiting for plans made for now'


def test_a_replan_touchdown_holds_its_tick_until_both_plans_arrive(wbc, robot):
    protocol, _ = make_protocol(wbc)
    add_pair(protocol, robot, 0)
    held = walk_until_replan(protocol, robot, 0)
    assert held == 100 * TICK                     # the planned touchdown at 0.4 s
    assert protocol.waiting == held and not protocol.waiting_first
    assert protocol.pending == (held, held)
    footholds, com_plan = plan_pair(robot, held)
    assert protocol.add_com_plan(held, com_plan) is None
    assert protocol.add_footholds(held, footholds) == held
    assert protocol.plan_stamp == held and protocol.pending is None
    answer(protocol, held)
    assert protocol.missed_replans == 0
    # A newer pair that no touchdown of ours announced is adopted at its tick (here the one
    # the active plan's re-plan step would have touched down at): its step is next held.
    add_pair(protocol, robot, 200 * TICK)
    assert walk_until_replan(protocol, robot, held + TICK) == 300 * TICK
    assert protocol.plan_stamp == 200 * TICK and protocol.pending == (300 * TICK, 300 * TICK)


def test_plans_ready_at_the_replan_tick_are_adopted_without_a_wait(wbc, robot):
    protocol, _ = make_protocol(wbc)
    add_pair(protocol, robot, 0)
    stamp = 0
    while stamp < 100 * TICK:
        assert protocol.on_tick(*robot.tick(stamp))
        answer(protocol, stamp)
        stamp += TICK
    add_pair(protocol, robot, 100 * TICK)      # the planners were faster than the controller
    assert protocol.on_tick(*robot.tick(100 * TICK))
    assert protocol.plan_stamp == 100 * TICK and protocol.waiting is None


def test_the_plan_latency_keeps_the_old_plans_for_whole_ticks(wbc, robot):
    protocol, _ = make_protocol(wbc)
    assert protocol.latency_ns == 0
    add_pair(protocol, robot, 0, latency=0.010)     # 2.5 ticks: 3 ticks
    trigger = 100 * TICK
    stamp = 0
    while stamp < trigger:
        assert protocol.on_tick(*robot.tick(stamp))
        answer(protocol, stamp)
        stamp += TICK
    assert protocol.latency_ns == 3 * TICK          # the active plan's, in whole ticks
    for k in range(3):
        assert protocol.on_tick(*robot.tick(trigger + k * TICK))
        assert protocol.plan_stamp == 0 and protocol.pending == (trigger, trigger + 3 * TICK)
        answer(protocol, trigger + k * TICK)
        if k == 0:
            add_pair(protocol, robot, trigger)     # here at once, yet adopted 3 ticks later
    assert protocol.on_tick(*robot.tick(trigger + 3 * TICK))
    assert protocol.plan_stamp == trigger and protocol.pending is None


def test_the_swinging_legs_are_those_lifted_off_and_not_yet_down(wbc, robot):
    """What the estimator is told to anchor nothing on: the leg of the step in swing, from
    the tick of its lift-off to its touchdown; none before the first plan and once fallen."""
    protocol, _ = make_protocol(wbc, fall_time=0.004)
    assert not protocol.swinging_legs.any()                # no plan yet
    add_pair(protocol, robot, 0)                           # lf lifts off at 0.2 s, down at 0.4
    seen = {}
    stamp = 0
    while stamp < 100 * TICK:
        assert protocol.on_tick(*robot.tick(stamp))
        seen[stamp] = protocol.swinging_legs.copy()
        answer(protocol, stamp)
        stamp += TICK
    assert not any(seen[k * TICK].any() for k in range(50))
    assert all(seen[k * TICK].tolist() == [True, False, False, False] for k in range(50, 100))
    assert not protocol.on_tick(*robot.tick(100 * TICK))   # touched down: held for plans
    assert not protocol.swinging_legs.any()
    for k in range(101, 103):                              # tilted: fallen, nothing swings
        protocol.on_tick(*robot.tick(k * TICK, roll=1.2))
    assert protocol.mode == 'fallen' and not protocol.swinging_legs.any()


def test_missed_replans_go_on_with_the_old_plans_then_stand(wbc, robot):
    protocol, logs = make_protocol(wbc, missed_replans_to_stand=2)
    add_pair(protocol, robot, 0, steps=2)
    held = walk_until_replan(protocol, robot, 0)
    protocol.add_footholds(held, plan_pair(robot, held)[0])      # the mpc's never comes
    assert protocol.wait_timed_out(2.0) == held
    assert protocol.mode == 'plan' and protocol.missed_replans == 1
    assert protocol.missing == 'com_plan (mpc)'
    assert ('warning', f're-plan due at t = {held / NS:.3f} s: com_plan (mpc) not there after '
            '2.0 s, going on with the old plans') in logs
    answer(protocol, held)
    # The old plan's next step triggers the next re-plan, whose plans do not come either.
    held2 = walk_until_replan(protocol, robot, held + TICK)
    assert held2 == 200 * TICK and protocol.pending == (held2, held2)
    assert protocol.wait_timed_out(2.0) == held2
    assert protocol.mode == 'stand' and protocol.missed_replans == 2
    assert protocol.stand_reason == 'no footholds (gait) and com_plan (mpc) for 2 re-plans'
    answer(protocol, held2)


def test_stale_inputs_stand_until_a_new_plan(wbc, robot):
    protocol, _ = make_protocol(wbc, stale_ticks=3)
    add_pair(protocol, robot, 0)
    assert protocol.on_tick(*robot.tick(0))
    answer(protocol, 0)
    assert protocol.on_tick(*robot.tick(3 * TICK))        # a gap of 3 periods: not stale
    answer(protocol, 3 * TICK)
    assert protocol.mode == 'plan'
    assert protocol.on_tick(*robot.tick(7 * TICK))        # 4 periods: stale
    assert protocol.mode == 'stand'
    assert protocol.stand_reason.startswith('stale inputs: 0.016 s')


def test_a_plan_older_than_plan_max_age_or_past_its_end_is_left_for_a_stand(wbc, robot):
    protocol, _ = make_protocol(wbc, plan_max_age=0.1)
    add_pair(protocol, robot, 0, liftoff=1.0)
    stamp = 0
    while protocol.mode == 'plan':
        assert protocol.on_tick(*robot.tick(stamp))
        answer(protocol, stamp)
        stamp += TICK
    assert stamp - TICK == 26 * TICK            # first tick more than 0.1 s after the plan
    assert protocol.stand_reason == 'plan stamped 0.000 s is too old'


def test_a_fall_needs_fall_time_of_tilt_and_is_latched(wbc, robot):
    protocol, logs = make_protocol(wbc, fall_time=0.012)
    add_pair(protocol, robot, 0)
    assert protocol.on_tick(*robot.tick(0))
    answer(protocol, 0)
    # One odd tick beyond fall_tilt is no fall.
    assert protocol.on_tick(*robot.tick(TICK, roll=1.2))
    answer(protocol, TICK)
    assert protocol.on_tick(*robot.tick(2 * TICK))
    answer(protocol, 2 * TICK)
    assert protocol.fallen is None
    for k in range(3, 7):
        assert protocol.on_tick(*robot.tick(k * TICK, roll=1.2))
        if k < 6:
            assert protocol.fallen is None
            answer(protocol, k * TICK)
    assert protocol.fallen == (6 * TICK / NS, pytest.approx(1.2))
    assert protocol.mode == 'fallen'
    result, restarted = answer(protocol, 6 * TICK)
    assert not restarted and np.allclose(result.torque, 0.0)   # at rest: damping alone
    assert any(level == 'error' and 'fallen at t = 0.024 s' in text for level, text in logs)
    # Upright again and new plans: still fallen (restart the wbc).
    add_pair(protocol, robot, 7 * TICK)
    assert protocol.on_tick(*robot.tick(8 * TICK))
    assert protocol.mode == 'fallen' and protocol.plan_stamp == 0


def test_a_robot_that_sat_down_stands_up_then_takes_only_plans_made_after(wbc, robot):
    protocol, logs = make_protocol(wbc)
    sitting = STANDING_POSE.copy()
    sitting[1::3] *= 1.8             # hips and knees folded: the legs much shorter
    sitting[2::3] *= 1.5
    add_pair(protocol, robot, 0)
    assert protocol.on_tick(*robot.tick(0, pose=sitting))
    assert protocol.mode == 'stand_up'
    assert protocol.stand_reason == 'started on a robot sitting: standing up first'
    p = wbc.params
    end = round((p.stand_up_time + p.stand_up_hold) * NS)
    add_pair(protocol, robot, 4 * TICK)          # made from the sitting robot: not adopted
    stamp = 0
    while True:
        if stamp:
            assert protocol.on_tick(*robot.tick(stamp, pose=sitting))
        restarted = answer(protocol, stamp)[1]
        if restarted:
            break
        assert protocol.mode == 'stand_up'
        stamp += TICK
    assert stamp == end
    assert protocol.stand_floor == end + TICK
    assert protocol.stand_reason == 'stood up: waiting for plans made from here on'
    assert [text.split(' at t = ')[0] for _, text in logs] == ['standing up', 'standing',
                                                               'stood up']
    assert protocol.on_tick(*robot.tick(end + TICK))
    answer(protocol, end + TICK)
    assert protocol.mode == 'stand'              # the plan stamped 0.016 s is before it
    add_pair(protocol, robot, end + TICK)
    assert protocol.on_tick(*robot.tick(end + 2 * TICK))
    assert protocol.mode == 'plan' and protocol.plan_stamp == end + TICK


def test_a_held_tick_ends_when_the_sim_moves_on_without_it(wbc, robot):
    protocol, _ = make_protocol(wbc)
    add_pair(protocol, robot, 0)
    held = walk_until_replan(protocol, robot, 0)
    # A newer tick (the sim free-ran): the held one is dropped, the new one answered with a
    # stand (the gap since the last answered tick is stale).
    assert protocol.on_tick(*robot.tick(held + 10 * TICK))
    assert protocol.waiting is None
    assert protocol.mode == 'stand' and protocol.stand_reason.startswith('stale inputs')
    assert protocol.add_com_plan(held, plan_pair(robot, held)[1]) is None


def test_the_plan_buffers_keep_the_newest_pairs(wbc, robot):
    protocol, _ = make_protocol(wbc)
    for k in range(KEEP_PLANS + 3):
        add_pair(protocol, robot, k * TICK)
    assert protocol.pair_stamps() == [k * TICK for k in range(3, KEEP_PLANS + 3)]
    assert protocol.missing_plans(0) == 'footholds (gait) and com_plan (mpc)'


def test_control_refuses_a_tick_it_was_not_given(wbc, robot):
    protocol, _ = make_protocol(wbc)
    add_pair(protocol, robot, 0)
    assert protocol.on_tick(*robot.tick(0))
    with pytest.raises(ValueError, match='the last tick given was 0'):
        protocol.control(TICK)


def test_a_plan_latency_longer_than_the_four_feet_phase_is_reported(wbc, robot):
    protocol, logs = make_protocol(wbc)
    add_pair(protocol, robot, 0, latency=0.010)
    stamp = 0
    while not protocol.pending:
        assert protocol.on_tick(*robot.tick(stamp))
        answer(protocol, stamp)
        stamp += TICK
    trigger = protocol.pending[0]
    add_pair(protocol, robot, trigger, liftoff=0.004)     # lifts off before the latency ends
    while protocol.pending:
        assert protocol.on_tick(*robot.tick(stamp))
        answer(protocol, stamp)
        stamp += TICK
    assert protocol.plan_stamp == trigger
    assert ('warning_throttled', 'plan latency 0.012 s is longer than the four-feet phase: the '
            f'first swing of the plan stamped {trigger / NS:.3f} s starts late') in logs


def test_the_first_wait_arms_first_plan_timeout_and_its_end_is_timed(wbc, robot):
    protocol, _ = make_protocol(wbc)
    wait = PlanWait(protocol, plan_timeout=2.0, first_plan_timeout=30.0)
    assert wait.sync(now_ns=50) is None                   # nothing held, no timer
    assert not protocol.on_tick(*robot.tick(0))
    assert wait.sync(now_ns=100) == WaitChange(arm=30.0)
    assert wait.stamp == 0 and wait.first and wait.timeout == 30.0
    assert not protocol.on_tick(*robot.tick(0))           # the republish: the same timer
    assert wait.sync(now_ns=200) is None
    assert add_pair(protocol, robot, 0) == 0
    assert wait.sync(now_ns=1_100) == WaitChange(ended=0, ended_first=True, waited_ns=1_000)
    assert wait.stamp is None and wait.sync(now_ns=1_200) is None


def test_a_replan_wait_arms_plan_timeout_as_it_stands_when_the_wait_begins(wbc, robot):
    protocol, logs = make_protocol(wbc)
    wait = PlanWait(protocol, plan_timeout=2.0, first_plan_timeout=30.0)
    add_pair(protocol, robot, 0, steps=2)
    wait.plan_timeout = 1.5                               # a run-time parameter change
    held = walk_until_replan(protocol, robot, 0)
    assert wait.sync(now_ns=7_000) == WaitChange(arm=1.5)
    assert not wait.first
    # The timer fires: the protocol goes on with the old plans, and the wait has ended.
    assert wait.timed_out() == held
    assert any('not there after 1.5 s' in text for _, text in logs)
    assert wait.sync(now_ns=9_000) == WaitChange(ended=held, waited_ns=2_000)
    assert wait.timed_out() is None                       # a late timer: nothing held
    answer(protocol, held)


def test_a_wait_the_sim_moves_on_from_ends_and_a_new_one_is_armed_at_once(wbc, robot):
    protocol, _ = make_protocol(wbc)
    wait = PlanWait(protocol, plan_timeout=2.0, first_plan_timeout=30.0)
    assert not protocol.on_tick(*robot.tick(0))
    wait.sync(now_ns=0)
    add_pair(protocol, robot, 0, steps=2)
    wait.sync(now_ns=10)
    answer(protocol, 0)
    held = walk_until_replan(protocol, robot, TICK)
    assert wait.sync(now_ns=20) == WaitChange(arm=2.0)
    # The sim free-ran past the held tick: that wait ends; the new tick is not held.
    assert protocol.on_tick(*robot.tick(held + 10 * TICK))
    assert wait.sync(now_ns=50) == WaitChange(ended=held, waited_ns=30)


def test_answered_ticks_keep_the_estimates_until_answered_and_the_last_commands():
    ticks = AnsweredTicks()
    assert ticks.is_new(0) and ticks.estimate(0) is None and ticks.command(0) is None
    for k in range(3):
        ticks.estimated(k * TICK, ('state', k), ('estimate', k))
    assert ticks.last_estimated == 2 * TICK
    assert not ticks.is_new(2 * TICK) and not ticks.is_new(TICK) and ticks.is_new(3 * TICK)
    assert ticks.estimate(TICK) == ('estimate', 1) and ticks.state(TICK) == ('state', 1)
    ticks.answered(TICK, b'command 1')
    # The republish of an answered tick: the same estimate and command again.
    assert ticks.estimate(TICK) == ('estimate', 1) and ticks.command(TICK) == b'command 1'
    assert ticks.state(2 * TICK) == ('state', 2)          # estimated, not answered yet
    assert ticks.estimate(0) is None                      # older: never answered again
    with pytest.raises(KeyError):
        ticks.state(0)


def test_answered_ticks_keep_the_newest_commands():
    ticks = AnsweredTicks()
    for k in range(KEEP_COMMANDS + 3):
        ticks.estimated(k * TICK, k, k)
        ticks.answered(k * TICK, k)
    assert [k for k in range(KEEP_COMMANDS + 3) if ticks.command(k * TICK) is not None] == \
        list(range(3, KEEP_COMMANDS + 3))
    # Only the last answered tick's estimate is left for a republish.
    assert [k for k in range(KEEP_COMMANDS + 3) if ticks.estimate(k * TICK) is not None] == \
        [KEEP_COMMANDS + 2]
