"""The controller's per-tick protocol: which plan pair drives each tick, when a tick waits for
its plans, stand, stand-up and fall (docs/ARCHITECTURE.md, "Re-plan protocol").

ROS-free and clock-free: ticks and plans are stamped in integer ns of sim time, and the one
wall-clock element of the protocol, the timeout of a held tick, is the caller's (it calls
``wait_timed_out``). The wbc node converts messages, calls this, times the phases and
publishes.

One tick, as the node drives it::

    if protocol.on_tick(stamp, base, joints, contacts):  # False: held (``waiting``) or no answer
        result = protocol.control(stamp)                 # the controller maths
        ... publish result.torque ...
        if protocol.answered(stamp):                     # True: a stand-up ended
            estimator.restart()

A held tick is answered when its plans arrive (``add_footholds`` / ``add_com_plan`` return its
stamp) or when the caller's timer fires (``wait_timed_out`` returns it); then ``control`` and
``answered`` as above.

Two smaller objects keep the rest of the controller side's state, so that the node keeps none:
``PlanWait`` says, after each call that may hold or release a tick, which one-shot wall-clock
timer to cancel and which to arm (``plan_timeout``, ``first_plan_timeout``), and how long the
wait lasted, from times the caller passes in; ``AnsweredTicks`` keeps the estimate published
for each tick and the commands answered, so that a tick the sim publishes again gets the same
estimate and command again.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from replan_core.common.rotations import yaw_of
from replan_core.common.types import (
    LEGS,
    BaseState,
    ComPlan,
    ContactState,
    FootholdPlan,
    JointState,
)
from replan_core.wbc.controller import (
    JointStandUp,
    PlanFollower,
    StandHold,
    WbcResult,
    WholeBodyController,
    plan_ends_stand,
    trunk_tilt,
)
from replan_core.wbc.settings import ProtocolParams

_NS = 1_000_000_000
KEEP_PLANS = 8          # plans kept per topic, by stamp (a few re-plans ahead of the ticks)
# Answered commands kept: the sim republishes only its current tick, so a few cover a command
# lost on the way while the controller has already answered the next ones.
KEEP_COMMANDS = 8

# log(level, text): level is 'info', 'warning', 'error' or 'warning_throttled' (a message that
# may repeat every tick: the caller rate-limits it).
Log = Callable[[str, str], None]


def _ns(seconds: float) -> int:
    return round(seconds * 1e9)         # as the messages round their stamps


def _ignore(level: str, text: str) -> None:
    del level, text


class ControllerProtocol:
    """Decides, tick by tick, what the controller tracks: a plan pair, a stand, a stand-up, or
    nothing (fallen). Holds the plan buffers and the state of the last tick it was given."""

    def __init__(self, wbc: WholeBodyController, params: ProtocolParams,
                 standing_pose: np.ndarray, log: Log = _ignore) -> None:
        self.wbc = wbc
        self.params = params
        self.log = log
        self.period_ns = _ns(1.0 / params.control_rate)
        self.stale_gap_ns = _ns(params.stale_ticks / params.control_rate)
        self.fall_time_ns = _ns(params.fall_time)
        self.standing_pose = np.array(standing_pose, dtype=float)        # rad
        standing = JointState(0.0, self.standing_pose.copy(), np.zeros(12), np.zeros(12))
        self.standing_leg_height = float(np.median(wbc.leg_heights(standing)))   # m
        self.footholds: dict[int, FootholdPlan] = {}
        self.com_plans: dict[int, ComPlan] = {}
        self._tick: tuple[int, BaseState, JointState, ContactState] | None = None
        self.started = False
        self.last_answered: int | None = None     # ns
        self.follower: PlanFollower | None = None
        self.plan_stamp: int | None = None         # ns, of the active plan pair
        self.pending: tuple[int, int] | None = None   # (plan stamp, tick it takes effect), ns
        self.stand: StandHold | None = None
        self.stand_reason = 'no plan yet'
        self.stand_since = 0.0                     # sim s the current stand began
        self.stand_floor = 0                       # ns: a stand ends with plans from here on
        self.stand_up: JointStandUp | None = None  # a robot that sat down standing up
        self.fallen: tuple[float, float] | None = None   # (sim s, tilt rad) of the fall
        self.tilt = 0.0                            # rad, trunk tilt of the last tick
        self._tilted_since: int | None = None      # ns, first tick beyond fall_tilt
        self.waiting: int | None = None            # ns, the tick held until its plans arrive
        self.waiting_first = False                 # the wait is the first tick's
        self.plan_timeouts = 0
        # Due re-plans in a row whose plans never came, and what was missing at the last one
        # (a planner that is gone, not slow).
        self.missed_replans = 0
        self.missing = ''

    # ------------------------------------------------------------------------------ plans
    def add_footholds(self, stamp: int, plan: FootholdPlan) -> int | None:
        """Keep the footholds stamped ``stamp`` (ns); the stamp of a held tick that is to be
        answered now, else None."""
        self._keep(self.footholds, stamp, plan)
        return self._plans_arrived()

    def add_com_plan(self, stamp: int, plan: ComPlan) -> int | None:
        """Keep the CoM plan stamped ``stamp`` (ns); as ``add_footholds``."""
        self._keep(self.com_plans, stamp, plan)
        return self._plans_arrived()

    @staticmethod
    def _keep(buffer: dict, stamp: int, value) -> None:
        buffer[stamp] = value
        while len(buffer) > KEEP_PLANS:
            del buffer[min(buffer)]

    def pair_stamps(self) -> list[int]:
        """Stamps (ns) with both footholds and a CoM plan, ascending."""
        return sorted(set(self.footholds) & set(self.com_plans))

    def _plans_arrived(self) -> int | None:
        """Event-driven end of a wait: the held tick, once its plans are here."""
        if self.waiting is None:
            return None
        pairs = self.pair_stamps()
        if self.waiting_first:
            ready = [s for s in pairs if s <= self.waiting]
        else:
            ready = [s for s in pairs if self.pending is not None and s == self.pending[0]]
        if not ready:
            return None
        stamp, first = self.waiting, self.waiting_first
        self.waiting = None
        self.pending = None
        self._adopt(ready[-1], stamp, announced=not first)
        return stamp

    def wait_timed_out(self, after: float) -> int | None:
        """The caller's timeout of the held tick, ``after`` (wall) s: go on without its plans
        (stand at the first tick, or after ``missed_replans_to_stand`` missed re-plans; else
        with the old plans). Returns the held tick's stamp, to be answered now (None: nothing
        was held)."""
        stamp = self.waiting
        if stamp is None:
            return None
        first = self.waiting_first
        self.waiting = None
        self.plan_timeouts += 1
        if first or self.follower is None:
            self.log('warning', f'no plans after {after} s at t = {stamp / _NS:.3f}: standing')
            self._enter_stand(stamp, 'no plan yet (plan_timeout)')
            return stamp
        plan_stamp = self.pending[0] if self.pending is not None else stamp
        self.pending = None
        self.missed_replans += 1
        self.missing = self.missing_plans(plan_stamp)
        if self.missed_replans >= self.params.missed_replans_to_stand:
            # The feet are all down at a re-plan touchdown: the safest moment to stop.
            self.log('error', f're-plan due at t = {stamp / _NS:.3f} s: {self.missing} missing '
                              f'{self.missed_replans} re-plans in a row (after {after} s '
                              'each): a planner is gone')
            self._enter_stand(stamp, f'no {self.missing} for {self.missed_replans} re-plans')
        else:
            self.log('warning', f're-plan due at t = {stamp / _NS:.3f} s: {self.missing} not '
                                f'there after {after} s, going on with the old plans')
        return stamp

    def missing_plans(self, plan_stamp: int) -> str:
        """Which plans stamped ``plan_stamp`` never came, with the node that sends them."""
        missing = [f'{topic} ({node})' for topic, node, buffer in
                   (('footholds', 'gait', self.footholds), ('com_plan', 'mpc', self.com_plans))
                   if plan_stamp not in buffer]
        return ' and '.join(missing) or 'footholds/com_plan'

    # ------------------------------------------------------------------------------ ticks
    @property
    def latency_ns(self) -> int:
        """The active plan's latency (FootholdPlan.latency, the gait's ``plan_latency``) in ns,
        rounded up to whole ticks: a trigger at t_k takes effect at a tick, never between, the
        first tick t >= t_k + latency, as touchdown.StepTracker lifts the new plan off; 0
        without a plan."""
        if self.follower is None:
            return 0
        return math.ceil(_ns(self.follower.footholds.latency) / self.period_ns - 1e-9) \
            * self.period_ns

    @property
    def swinging_legs(self) -> np.ndarray:
        """(4,) bool: the legs in swing after the last processed tick (lifted off by the
        touchdown rule, not yet down); none while standing, fallen or without a plan. The
        estimator anchors none of them (``StateEstimator.update``)."""
        if self.follower is not None and self.stand is None and self.fallen is None:
            return self.follower.tracker.in_swing
        return np.zeros(len(LEGS), dtype=bool)

    @property
    def mode(self) -> str:
        """'fallen', 'stand_up', 'stand' or 'plan'."""
        return ('fallen' if self.fallen is not None
                else 'stand_up' if self.stand_up is not None
                else 'stand' if self.stand is not None else 'plan')

    def on_tick(self, stamp: int, base: BaseState, joints: JointState, contacts: ContactState,
                may_start: Callable[[], bool] = lambda: True) -> bool:
        """The state of tick ``stamp`` (ns): True if it is to be answered now (``control``);
        False if it is held for its plans (``waiting``) or not to be answered (an old stamp,
        a repeat of the held one, or the first tick before ``may_start()``: the caller's
        condition for letting the sim move)."""
        if self.waiting is not None:
            if stamp <= self.waiting:
                return False                         # still waiting for this tick's plans
            # The sim moved on without us (free-run): stop waiting, the inputs are stale.
            self.waiting = None
        if self.last_answered is not None and stamp <= self.last_answered:
            return False                             # an old stamp: nothing to answer
        if not self.started and not may_start():
            return False
        self._tick = (stamp, base, joints, contacts)
        self.tilt = trunk_tilt(base.quaternion)
        if self.tilt <= self.wbc.params.fall_tilt:
            self._tilted_since = None
        elif self._tilted_since is None:
            self._tilted_since = stamp
        # Tilted for fall_time: one odd estimate is not a fall.
        if (self.fallen is None and self._tilted_since is not None
                and stamp - self._tilted_since >= self.fall_time_ns):
            self._fall(stamp)
        if self.fallen is not None:        # latched: no plan can right a fallen robot
            self.started = True
            return True
        t = stamp / _NS
        if not self.started:
            self.started = True
            pairs = [s for s in self.pair_stamps() if s <= stamp]
            if self._sat_down(stamp):
                # Started (again) on a robot that sat down in the sim's damping mode.
                self._enter_stand(stamp, 'started on a robot sitting: standing up first')
            elif pairs and self._ends_stand(pairs[-1], stamp):
                self._adopt(pairs[-1], stamp)
            elif pairs:
                self._enter_stand(stamp, 'started mid-plan: waiting for plans made for now')
            else:
                self._hold(stamp, first=True)
                return False
        elif (self.last_answered is not None and stamp - self.last_answered > self.stale_gap_ns
              and self.stand is None):
            self._enter_stand(stamp, f'stale inputs: {(stamp - self.last_answered) / _NS:.3f} s '
                                     'since the last answered tick')
        # A newer plan pair than the active one (e.g. not announced by a touchdown we saw):
        # adopt it; this is also how a stand ends.
        # While a re-plan is pending its plans are not adopted before their time.
        newer = [s for s in self.pair_stamps()
                 if s <= stamp and (self.plan_stamp is None or s > self.plan_stamp)]
        if self.stand is not None:
            # Leave a stand only for a plan made for about now (controller.plan_ends_stand).
            # After a stand-up, only plans made from the estimate started over then.
            newer = [s for s in newer if s >= self.stand_floor and self._ends_stand(s, stamp)]
        # A robot that sat down (the sim's damping mode) stands up before it walks: a plan
        # from the low posture asks the MPC for a CoM it cannot keep in the support.
        if newer and self.pending is None and self.stand_up is None and (
                self.stand is not None or self.follower is not None):
            self._adopt(newer[-1], stamp)
        if self.follower is not None and self.stand is None:
            if self.pending is None:
                # Frozen while a re-plan is pending: the old plan's next lift-off waits for
                # the new plan (whose first lift-off is a four-feet phase after its trigger).
                self.follower.update(t, contacts)
                if self.follower.replan_due:
                    self.pending = (stamp, stamp + self.latency_ns)
            if self.pending is not None and stamp >= self.pending[1]:
                plan_stamp = self.pending[0]
                if plan_stamp in self.footholds and plan_stamp in self.com_plans:
                    self.pending = None
                    self._adopt(plan_stamp, stamp, announced=True)
                else:
                    self._hold(stamp, first=False)
                    return False
        return True

    def _hold(self, stamp: int, first: bool) -> None:
        self.waiting = stamp
        self.waiting_first = first

    def control(self, stamp: int) -> WbcResult:
        """The controller's answer to tick ``stamp``, the last one given to ``on_tick``."""
        tick_stamp, base, joints, contacts = self._tick
        if tick_stamp != stamp:
            raise ValueError(f'control({stamp}): the last tick given was {tick_stamp}')
        if self.fallen is not None:
            return self.wbc.fallen(joints, contacts.contact)
        t = stamp / _NS
        if self.stand is None and self.follower is not None:
            plan = self.follower.com_plan
            if t - plan.start_time > self.params.plan_max_age or t > plan.end_time:
                self._enter_stand(stamp, f'plan stamped {plan.start_time:.3f} s is too old')
        if self.stand is None and self.follower is None:
            self._enter_stand(stamp, self.stand_reason)
        if self.stand_up is not None:
            return self.wbc.stand_up(joints, self.stand_up, t, contacts.contact)
        if self.stand is not None:
            com_ref, yaw, stance, swing = self.stand.references(t, contacts)
            yaw_rate = 0.0
        else:
            com_ref, yaw, stance, swing = self.follower.references(t)
            yaw_rate = self.follower.yaw_rate(t)
        return self.wbc.compute(base, joints, contacts.contact, com_ref, yaw, stance, swing,
                                yaw_rate_reference=yaw_rate)

    def answered(self, stamp: int) -> bool:
        """Tick ``stamp`` was answered with ``control``'s result. True if that ended a
        stand-up: the caller starts its base estimate over (plans made from the next tick on
        end the stand that follows)."""
        self.last_answered = stamp
        if self.stand_up is None or self.fallen is not None or not self.stand_up.done(
                stamp / _NS):
            return False
        self.stand_up = None
        self.stand = None
        self.stand_reason = 'stood up: waiting for plans made from here on'
        self.stand_floor = stamp + self.period_ns
        self.log('info', f'stood up at t = {stamp / _NS:.3f} s: the base estimate starts over, '
                         'plans stamped from the next tick on are adopted')
        return True

    # ------------------------------------------------------------------------------ decisions
    def _adopt(self, plan_stamp: int, stamp: int, announced: bool = False) -> None:
        """Make the pair stamped ``plan_stamp`` active at tick ``stamp`` (``announced``: the
        re-plan our tracker expected, after the plan latency)."""
        footholds, com_plan = self.footholds[plan_stamp], self.com_plans[plan_stamp]
        wbc = self.wbc.params
        self.follower = PlanFollower(footholds, com_plan, wbc.haptic_velocity,
                                     wbc.touchdown_depth)
        if stamp > plan_stamp:       # late: the plan latency, the first tick, or unannounced
            self.follower.update(stamp / _NS, self._tick[3])
            if not announced:
                self.log('info', f'adopted plans stamped {plan_stamp / _NS:.3f} s at '
                                 f'tick {stamp / _NS:.3f} s')
            first_liftoff = min((step.liftoff_time for step in footholds.steps), default=None)
            if announced and first_liftoff is not None and first_liftoff < stamp / _NS - 1e-9:
                self.log('warning_throttled',
                         f'plan latency {(stamp - plan_stamp) / _NS:.3f} s is longer than the '
                         'four-feet phase: the first swing of the plan stamped '
                         f'{plan_stamp / _NS:.3f} s starts late')
        self.plan_stamp = plan_stamp
        self.missed_replans = 0
        self.missing = ''
        if self.stand is not None:
            self.log('info', f'plans stamped {plan_stamp / _NS:.3f} s: leaving the stand')
        self.stand = None

    def _ends_stand(self, plan_stamp: int, stamp: int) -> bool:
        return plan_ends_stand(self.footholds[plan_stamp], stamp / _NS,
                               self.params.stand_adopt_age, self.params.stand_adopt_lead)

    def _sat_down(self, stamp: int) -> bool:
        """The legs are folded (joint kinematics alone: the base estimate of a robot that
        sat down is not to be trusted)."""
        height = float(np.median(self.wbc.leg_heights(self._tick[2])))
        return height < self.standing_leg_height - self.params.sat_down_height

    def _enter_stand(self, stamp: int, reason: str) -> None:
        _, base, joints, contacts = self._tick
        com, _ = self.wbc.robot.com_state(base, joints)
        self.stand = StandHold(stamp / _NS, com, yaw_of(base.quaternion), contacts,
                               self.wbc.params.haptic_velocity)
        self.stand_reason = reason
        self.stand_since = stamp / _NS
        if self.stand_up is None and self._sat_down(stamp):
            p = self.wbc.params
            self.stand_up = JointStandUp(stamp / _NS, joints.position, self.standing_pose,
                                         p.stand_up_time, p.stand_up_hold)
            self.log('warning',
                     f'standing up at t = {stamp / _NS:.3f} s: the legs are folded (median '
                     f'{np.median(self.wbc.leg_heights(joints)):.3f} m, standing '
                     f'{self.standing_leg_height:.3f} m); joint-space stand-up in '
                     f'{p.stand_up_time + p.stand_up_hold:.1f} s')
        self.follower = None
        self.pending = None
        self.log('warning', f'standing at t = {stamp / _NS:.3f} s: {reason}')

    def _fall(self, stamp: int) -> None:
        """The trunk tilted beyond ``fall_tilt``: damp the joints from now on, until the
        protocol is made anew (the node restarted: docs/usage.md, "Faults and recovery")."""
        p = self.wbc.params
        self.fallen = (stamp / _NS, self.tilt)
        self.follower = None
        self.pending = None
        self.stand = None
        self.stand_up = None
        self.log('error',
                 f'fallen at t = {stamp / _NS:.3f} s: the trunk is tilted '
                 f'{math.degrees(self.tilt):.0f} deg from upright (fall_tilt '
                 f'{math.degrees(p.fall_tilt):.0f} deg): joints damped '
                 f'({p.fall_damping:g} N m s/rad), plans ignored; restart the wbc once the '
                 'robot is upright')


@dataclass(frozen=True)
class WaitChange:
    """What ``PlanWait.sync`` found: a wait that ended and a timer to arm (either may be
    absent)."""

    ended: int | None = None      # ns, the held tick whose wait ended; cancel its timer
    ended_first: bool = False     # that wait was the first tick's (for the planners' start)
    waited_ns: int = 0            # the ended wait's length on the caller's clock
    arm: float | None = None      # wall s: arm a one-shot timer for the tick held now


class PlanWait:
    """The wall-clock timeout of the tick ``protocol`` holds for its plans, as state: after
    every call that may hold or release a tick (``on_tick``, ``add_footholds``,
    ``add_com_plan``, ``wait_timed_out``) the caller asks ``sync``, cancels the timer of a
    wait that ended and arms one of ``arm`` s for a new wait; when that timer fires it calls
    ``timed_out``. Times (``now_ns``) are the caller's monotonic clock; none is read here."""

    def __init__(self, protocol: ControllerProtocol, plan_timeout: float,
                 first_plan_timeout: float) -> None:
        self.protocol = protocol
        self.plan_timeout = plan_timeout              # wall s; may change at run time
        self.first_plan_timeout = first_plan_timeout  # wall s, the first tick's wait
        self.stamp: int | None = None   # ns, the held tick a timer is armed for
        self.first = False              # ... and whether it is the first tick
        self._since_ns = 0              # the caller's clock when that wait began

    @property
    def timeout(self) -> float:
        """Wall s the current wait may last (the first tick's, or a re-plan's)."""
        return self.first_plan_timeout if self.first else self.plan_timeout

    def sync(self, now_ns: int) -> WaitChange | None:
        """Follow the protocol's held tick at ``now_ns``: None if it is the one the timer is
        armed for (or there is none and no timer), else what ended and what to arm."""
        held = self.protocol.waiting
        if held == self.stamp:
            return None
        ended, ended_first, waited = None, False, 0
        if self.stamp is not None:     # answered, timed out, or the sim moved on
            ended, ended_first, waited = self.stamp, self.first, now_ns - self._since_ns
            self.stamp = None
        arm = None
        if held is not None:
            self.stamp, self.first, self._since_ns = held, self.protocol.waiting_first, now_ns
            arm = self.timeout
        return WaitChange(ended, ended_first, waited, arm)

    def timed_out(self) -> int | None:
        """The armed timer fired: the protocol goes on without the held tick's plans
        (``ControllerProtocol.wait_timed_out``); the stamp to answer now, or None. ``sync``
        then reports the wait as ended."""
        return self.protocol.wait_timed_out(self.timeout)


class AnsweredTicks:
    """What the controller said for each tick, for the sim's republish of one: the estimate
    published (and the tick's state, until the tick or a later one is answered) and the last
    ``keep`` commands. The payloads are the caller's (e.g. serialized messages)."""

    def __init__(self, keep: int = KEEP_COMMANDS) -> None:
        self.keep = keep
        self.last_estimated: int | None = None   # ns
        self._states: dict[int, Any] = {}
        self._estimates: dict[int, Any] = {}
        self._commands: dict[int, Any] = {}

    def estimate(self, stamp: int) -> Any | None:
        """The estimate published for tick ``stamp`` (ns), if it is still kept."""
        return self._estimates.get(stamp)

    def is_new(self, stamp: int) -> bool:
        """Tick ``stamp`` is later than every tick estimated so far."""
        return self.last_estimated is None or stamp > self.last_estimated

    def estimated(self, stamp: int, state: Any, estimate: Any) -> None:
        """Tick ``stamp`` was estimated: its ``state`` (for the protocol) and the
        ``estimate`` published."""
        self.last_estimated = stamp
        self._estimates[stamp] = estimate
        self._states[stamp] = state

    def state(self, stamp: int) -> Any:
        """The state of an estimated tick that is not older than the last answered one."""
        return self._states[stamp]

    def command(self, stamp: int) -> Any | None:
        """The command answering tick ``stamp``, if it is still kept."""
        return self._commands.get(stamp)

    def answered(self, stamp: int, command: Any) -> None:
        """Tick ``stamp`` was answered with ``command``: keep it; older ticks can no longer be
        answered, so their states and estimates go."""
        commands = self._commands
        commands[stamp] = command
        while len(commands) > self.keep:
            del commands[min(commands)]
        for buffer in (self._states, self._estimates):
            for old in [s for s in buffer if s < stamp]:
                del buffer[old]
