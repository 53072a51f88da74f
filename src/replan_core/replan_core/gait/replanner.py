"""The gait side of the re-plan protocol: the touchdown rule on every contacts tick, when a
re-plan is due, and what it plans (docs/gait.md; docs/ARCHITECTURE.md, "Re-plan protocol").

ROS-free and clock-free: the gait node feeds it the contacts of every tick in stamp order
(``tick``), and, when ``pending`` names a due re-plan, the base state of that tick and the
set-point (``plan``); it publishes the plan and hands back the plan as the controller will
decode it (``adopt``), so that both trackers compare bit-identical times.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from replan_core.common.rotations import yaw_of
from replan_core.common.types import GRAVITY, LEGS, BaseState, ContactState, FootholdPlan
from replan_core.gait.crawl import (
    CrawlSchedule,
    GaitParams,
    IdleMonitor,
    clamp_velocity,
    compute_footholds,
    is_idle_trigger,
    is_stand_plan,
    stand_plan,
)
from replan_core.gait.speed_feedback import ReplanSample, SpeedFeedback, StepTiming, trunk_trend
from replan_core.gait.touchdown import StepTracker, step_groups

DEFAULT_TICK_NS = 4_000_000     # control period until the stamps have shown it (250 Hz)
# log(level, text): level 'info', 'warning' or 'error'; warn(key, text): a warning that may
# repeat every tick, which the caller rate-limits per key.
Log = Callable[[str, str], None]


def _ignore(*_args) -> None:
    return None


@dataclass
class Replan:
    """A due re-plan: the tick (ns) and its contacts; ``initial``: the first state seen."""

    stamp: int
    contacts: ContactState
    initial: bool


def check_setpoint(values, reject_above: float, gaits: Sequence[GaitParams]
                   ) -> tuple[np.ndarray | None, str]:
    """A commanded (vx, vy, wz): (None, why) if non-finite or any component above
    ``reject_above`` in magnitude; else (the value clamped to what the widest of ``gaits``
    (the run's) can step, '' or how it was clamped). Each re-plan clamps it again to its own
    gait's limits."""
    v = np.array(values, dtype=float)
    if not np.all(np.isfinite(v)) or np.any(np.abs(v) > reject_above):
        return None, (f'rejected (vx, vy, wz) = {v.tolist()}: non-finite or above '
                      f'{reject_above}; keeping the last good set-point')
    clamped = max((clamp_velocity(v, gait) for gait in gaits),
                  key=lambda c: float(np.linalg.norm(c)))
    if np.array_equal(clamped, v):
        return clamped, ''
    return clamped, f'(vx, vy, wz) = {v.tolist()} clamped to {clamped.tolist()}'


def capture_offset(base: BaseState, feet: np.ndarray, yaw: float) -> np.ndarray:
    """(2,) m, body frame: where a trunk moving at ``base``'s velocity comes to rest, from
    its position now: the capture point of the LIP, v / omega, omega = sqrt(g / h), h the
    base's height above the mean foot. A stopping plan (zero set-point) shifts its footholds
    by it: laid out about the base of the re-plan, the last feet were behind the trunk's rest
    by it (HyQ trotting at 0.37 m/s: 9 cm), and the position term pulled the trunk back over
    them and then crept for seconds (docs/gait.md, "Idle stance"). A base not above its
    feet (fallen, or a NaN in the estimate) has no capture point: zero, the footholds laid out
    about the base as without it; the fall itself is the estimator's and the graph's to report."""
    height = float(base.position[2] - np.mean(np.asarray(feet, dtype=float)[:, 2]))
    if not height > 0.0:                                   # also False for NaN
        return np.zeros(2)
    omega = math.sqrt(GRAVITY / height)                    # 1/s
    vx, vy = (float(v) for v in base.linear_velocity[:2])  # m/s, world
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * vx + s * vy, -s * vx + c * vy]) / omega


class GaitReplanner:
    """Touchdown rule, re-plan trigger and foothold planning of one run."""

    def __init__(self, params: GaitParams, min_swing_fraction: float, max_extension: float,
                 start_delay: float, log: Log = _ignore,
                 warn: Callable[[str, str], None] = _ignore, plan_latency: float = 0.0) -> None:
        self.params = params
        self.min_swing_fraction = min_swing_fraction     # travel with each plan (gait/touchdown.py)
        self.max_extension = max_extension               # s
        self.plan_latency = plan_latency                 # sim s, travels with each plan too
        self.start_delay = max(start_delay, 0.0)         # s, standing before the first step
        self.log = log
        self.warn = warn
        self.forced = 0                                  # forced touchdowns, over all runs
        # A gait to switch to at the next re-plan (a step boundary: every foot down), and the
        # leg that touched down last (the new gait's first step is the group after it).
        self.next_params: GaitParams | None = None
        self.last_touchdown_leg: int | None = None
        self.reset('start')

    def reset(self, why: str) -> None:
        """Forget the run (start, or sim time went backwards: a new run)."""
        if why != 'start':
            self.log('warning', f'gait: {why}; starting over with a new initial plan')
        self.schedule = CrawlSchedule(self.params.sequence, groups=self.params.groups)
        self.last_touchdown_leg = None
        self.plan: FootholdPlan | None = None
        self.tracker: StepTracker | None = None
        self.last_tick_ns: int | None = None
        self.tick_ns: int | None = None          # the control period, as seen in the stamps
        self.pending: Replan | None = None
        self.replans = 0
        # Half a step of slack: the zero run is timed from re-plan (touchdown) ticks, which
        # jitter by a few ms (crawl.IdleMonitor).
        self.idle = IdleMonitor(self.params.idle_after, self.params.idle_stance,
                                0.5 * self.params.step_period)
        self._cycle_measures()
        # The (vx, vy, wz) each leg's foot was placed for, and the plan's in force (zeros:
        # standing): a leg's first stride after a change starts along its old reference.
        # placed_until, placed_poses: the first re-plan that planned another twist (inf: none
        # yet) and its base (x, y, yaw).
        self.placed_twists = np.zeros((4, 3))
        self.placed_until = np.full(4, np.inf)
        self.placed_poses = np.full((4, 3), np.nan)
        self.plan_twist = np.zeros(3)
        self._planned_twist = np.zeros(3)

    def _cycle_measures(self) -> None:
        """What is measured over the gait's cycle, from nothing (a new run, a new gait)."""
        # Velocity feedback in foot placement, over one cycle (speed_feedback.py).
        self.speed = SpeedFeedback(self.params.velocity_feedback_gain,
                                   self.params.velocity_feedback_limit,
                                   self.params.cycle_duration,
                                   self.params.velocity_feedback_max_error)
        # The step period actually walked, for the strides (speed_feedback.StepTiming).
        self.timing = StepTiming(self.params.step_period, self.params.steps_per_cycle)
        # The base at the walking re-plans of the last cycle and a bit (speed_feedback.
        # trunk_trend): the sway-free trunk the foothold correction places the feet about.
        self.trend_samples: deque[ReplanSample] = deque(maxlen=2 * self.params.steps_per_cycle + 1)

    def switch_gait(self, params: GaitParams) -> None:
        """Walk ``params`` from the next re-plan on: at a touchdown that ends a step (or a
        standing re-plan), every foot down, never mid-swing. Its first step is the group
        after the leg that touched down last."""
        params.validate()
        self.next_params = None if params == self.params else params

    def _apply_gait(self, t: float) -> float:
        """Switch to ``next_params`` at this re-plan; the four-feet phase (s) before its first
        step: the longer of the two gaits'. The old gait's stance was laid out for its own
        supports (a crawl's feet are staggered): its four-feet phase is the time it gives the
        trunk to move between supports, and the new gait's first group needs it too. Without
        it a crawl-to-trot switch put the first diagonal 9 cm beside HyQ's CoM, and the ZMP
        held on it pushed the trunk 10 cm sideways (docs/gait.md, "Switching gaits")."""
        old, self.params, self.next_params = self.params, self.next_params, None
        self.schedule = CrawlSchedule(self.params.sequence, groups=self.params.groups)
        if self.last_touchdown_leg is not None:
            self.schedule.touched_down(self.last_touchdown_leg)
        self.idle.idle_after = self.params.idle_after
        self.idle.tolerance = 0.5 * self.params.step_period
        # The stride correction, the step period and the trunk's trend were measured over the
        # old gait's cycle, with its strides: measured again over the new one.
        self._cycle_measures()
        self.log('info', f'gait switched at t={t:.3f} s: {len(old.swing_groups[0])} to '
                         f'{len(self.params.swing_groups[0])} legs a step, '
                         f'{LEGS[self.schedule.next_leg]} first')
        return max(old.four_feet_duration, self.params.four_feet_duration)

    @property
    def standing(self) -> bool:
        """The plan in force is a stand plan (idle stance)."""
        return self.plan is not None and is_stand_plan(self.plan)

    def tick(self, contacts: ContactState) -> bool:
        """The contacts of the next tick, in stamp order: the touchdown rule; sets
        ``pending`` when a re-plan is due (and at the first state seen). True if the tick
        started a new run (sim time went back): the caller drops what it kept of the old."""
        ns = round(contacts.stamp * 1e9)
        new_run = self.last_tick_ns is not None and ns < self.last_tick_ns
        if new_run:
            self.reset(f'sim time went back from {self.last_tick_ns * 1e-9:.3f} s to '
                       f'{contacts.stamp:.3f} s')
        if self.last_tick_ns is not None and ns == self.last_tick_ns:
            return new_run                  # a republished state: already decided
        if self.last_tick_ns is not None:
            gap = ns - self.last_tick_ns
            self.tick_ns = min(self.tick_ns or gap, gap)
            if gap > 1.5 * self.tick_ns:    # the queue overflowed (the node was starved)
                self.warn('ticks lost',
                          f'contacts ticks lost between {self.last_tick_ns * 1e-9:.3f} s and '
                          f'{contacts.stamp:.3f} s: the touchdown rule may disagree with the '
                          'controller until the next plan')
        self.last_tick_ns = ns
        if self.tracker is None:
            self.pending = Replan(ns, contacts, True)   # the first state seen: the initial plan
            return new_run
        for event in self.tracker.update(contacts.stamp, contacts.contact):
            if event.kind != 'touchdown' or is_idle_trigger(self.plan.steps[event.step]):
                continue                    # a stand plan's trigger moves no leg
            self.schedule.touched_down(event.leg)
            self.last_touchdown_leg = event.leg
            if event.completes_group:           # one step of the gait: a trot's pair, both down
                self.timing.touchdown(event.time)
            self.placed_twists[event.leg] = self.plan_twist
            self.placed_until[event.leg] = np.inf
            if event.reason == 'forced':
                self.forced += 1
                self.log('warning', f'{LEGS[event.leg]} touchdown forced at t={event.time:.3f} '
                                    f's: no contact {self.max_extension} s after the planned '
                                    'touchdown')
        if self.tracker.replan_due:
            self.pending = Replan(ns, contacts, False)
        return new_run

    def plan_pending(self, base: BaseState, hips: np.ndarray | None, setpoint: np.ndarray,
                     source: str) -> FootholdPlan | None:
        """The footholds of the pending re-plan from the actual state of its tick (``base``,
        the hips in the world, None: the nominal offsets) and the set-point in force then
        (``source``: where it came from, for the log). None if they cannot be computed (the
        previous plan stays; logged). ``pending`` is cleared either way; the caller publishes
        the plan and calls ``adopt``."""
        request, self.pending = self.pending, None
        cs, initial = request.contacts, request.initial
        t = cs.stamp                       # the very float the controller gets from the stamp
        switch_delay = self._apply_gait(t) if self.next_params is not None else 0.0
        feet = cs.foot_position.copy()
        if self.plan is not None:
            # A foot whose touchdown was forced is still in the air: plan it at ground height.
            targets = {s.leg: s.target for s in self.plan.steps
                       if s.touchdown_time <= t + 1e-9}
            for leg in range(4):
                if not cs.contact[leg] and leg in targets:
                    feet[leg, 2] = targets[leg][2]
        yaw = yaw_of(base.quaternion)
        stand = self.idle.update(t, setpoint)
        was_standing = self.standing
        try:
            if stand:
                self.speed.reset()
                self.timing.restart()
                self.trend_samples.clear()
                plan = stand_plan(feet, yaw, t, self.schedule.next_leg, self._trigger_time(t))
                self._planned_twist = np.zeros(3)
            else:
                if was_standing:
                    self.speed.reset()
                    self.trend_samples.clear()
                twist = clamp_velocity(setpoint, self.params)
                changed = np.isinf(self.placed_until) & np.any(self.placed_twists != twist, axis=1)
                self.placed_until[changed] = t
                self.placed_poses[changed] = (base.position[0], base.position[1], yaw)
                correction = self.speed.update(t, base.position, yaw, twist)
                trend_shift = self._trend_shift(t, base, yaw, twist)
                # Walking off from a stand, as at the start: the reference trunk stands
                # through the four-feet phase, so the first strides are partial.
                delay = (self.start_delay if initial
                         else self.params.four_feet_duration if was_standing else switch_delay)
                plan = compute_footholds(setpoint, feet, base.position, yaw, hips,
                                         self.schedule.next_leg, t, self.params, delay=delay,
                                         stride_correction=correction,
                                         stride_time_scale=self.stride_time_scale,
                                         trend_shift=trend_shift,
                                         placed_twists=self.placed_twists,
                                         placed_until=self.placed_until,
                                         placed_poses=self.placed_poses,
                                         # stopping: the feet about where the trunk rests
                                         rest_offset=(None if np.any(twist)
                                                      else capture_offset(base, feet, yaw)))
                self._end_before_standing(plan)
                self._planned_twist = twist
        except ValueError as err:
            self.log('error', f'footholds at t={t:.3f} s failed ({err}); keeping the previous '
                              'plan')
            return None
        # The touchdown rule travels with the plan: the controller applies the same values.
        plan.min_swing_fraction = self.min_swing_fraction
        plan.max_extension = self.max_extension
        plan.latency = self.plan_latency
        if initial and stand:
            self.log('info', f'initial plan at t={t:.3f} s: standing still until a non-zero '
                             'set-point')
        elif initial:
            self.log('info', f'initial plan at t={t:.3f} s: stand {self.start_delay} s, then '
                             f'{LEGS[self.schedule.next_leg]} first')
        elif stand and not was_standing:
            self.log('info', f'idle stance at t={t:.3f} s: set-point zero since '
                             f'{self.idle.zero_since:.3f} s, all four feet down')
        elif was_standing and not stand:
            self.log('info', f'walking again at t={t:.3f} s ({source} {setpoint.tolist()}), '
                             f'{LEGS[self.schedule.next_leg]} first')
        return plan

    def _trend_shift(self, t: float, base: BaseState, yaw: float,
                     twist: np.ndarray) -> np.ndarray | None:
        """Keep this re-plan's base; with ``correction_hips`` 'sway_free', the trunk's trend
        over the last cycle minus the base (m, world; speed_feedback.trunk_trend), by which
        compute_footholds moves the hips the correction places the feet about. None with
        'actual', and until a cycle is walked at this set-point: the actual hips."""
        xy = np.asarray(base.position, dtype=float)[:2]
        self.trend_samples.append(ReplanSample(t, xy.copy(), yaw, np.asarray(twist, dtype=float)))
        if self.params.correction_hips != 'sway_free':
            return None
        trend = trunk_trend(list(self.trend_samples), self.params.cycle_duration)
        return None if trend is None else trend - xy

    def _end_before_standing(self, plan: FootholdPlan) -> None:
        """If the re-plan at this plan's trigger will stand still (the set-point zero long
        enough by then), drop the steps after the trigger: the plan then says the feet stay
        down from that touchdown on, so the CoM plan made now settles over the final stance
        during the last swing instead of swaying towards a swing that will not come and
        turning back after it (docs/gait.md, "Idle stance")."""
        trigger = next((j for j, st in enumerate(plan.steps) if st.replan), None)
        if trigger is not None and self.idle.stands_at(plan.steps[trigger].touchdown_time):
            # The trigger's whole group lands (a trot's pair: both legs); in a crawl the group
            # is the trigger alone.
            last = next(g for g in step_groups(plan.steps) if trigger in g)[-1]
            del plan.steps[last + 1:]

    @property
    def stride_time_scale(self) -> float:
        """Measured over planned step period for the next plan's strides (1.0 when
        ``measured_step_period`` is off or nothing is measured yet)."""
        return self.timing.scale if self.params.measured_step_period else 1.0

    def adopt(self, plan: FootholdPlan) -> None:
        """Track ``plan`` from now on: as the controller decodes it from the message."""
        self.plan = plan
        self.plan_twist = self._planned_twist
        self.tracker = StepTracker(plan)
        self.replans += 1

    def _trigger_time(self, t: float) -> float:
        """When a stand plan's trigger lifts off: ``idle_replan_period`` after ``t``, half a
        control tick early. The trackers lift it off at the next tick (on the tick grid) and
        end it one tick later; half a tick off the grid it is never an MPC sample, so the
        support stays four feet at every sample (crawl.stand_plan)."""
        tick = (self.tick_ns or DEFAULT_TICK_NS) * 1e-9
        return t + self.params.idle_replan_period - 0.5 * tick
