"""StepTracker: the one touchdown rule, shared by the gait node and the whole-body controller.

Both feed it the same plan and, every control tick, the same (stamp, debounced contact flags);
the rule is plain float logic on those inputs, so both reach the same decisions on the same tick
however slow either process is.

Rule (docs/gait.md):
- Steps run one after the other in plan order; consecutive steps of different legs with the
  same planned times form a group that swings together (a trot's diagonal pair,
  ``step_groups``; in a crawl every group is one step). A group's swing starts (lift-off, all
  its legs on one tick) at the first tick t >= max(its planned lift-off, the previous group's
  actual touchdown tick, i.e. that of its last foot down, the plan's start_time + latency:
  the tick its plans take effect in the controller).
- A haptic step ends (touchdown) at the first tick t >= liftoff + min_swing_fraction *
  (touchdown_time - liftoff_time) whose contact flag is set (reason ``contact``), where
  ``liftoff`` is the actual lift-off tick and the duration the planned one; if no contact came,
  it is forced at the first tick t >= touchdown_time + max_extension (reason ``forced``).
- A non-haptic step ends at the first tick t >= touchdown_time (reason ``planned``).
- A step never ends at its own lift-off tick. Each foot of a group touches down by itself.
- Re-plan trigger: the touchdown that completes a group (its last foot down) whose steps carry
  ``replan``; all four feet are then in stance, as ``crawl.compute_footholds`` requires. The
  earlier touchdowns of the group are events without ``replan``.
- Ticks at or before the last processed one (duplicates, and ``plan.start_time`` itself, whose
  tick triggered this plan) change nothing.
All comparisons use a 1e-9 s tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replan_core.common.types import FootholdPlan, Step

TIME_TOLERANCE = 1e-9   # s, float comparisons of stamps


def step_groups(steps: list[Step]) -> list[list[int]]:
    """Indices of ``steps`` grouped into the gait's steps: consecutive steps of different legs
    with the same lift-off and touchdown times (within 1e-9 s) swing together (a trot's
    pair); every other step is a group of its own (the crawl)."""
    groups: list[list[int]] = []
    for i, st in enumerate(steps):
        if groups:
            first = steps[groups[-1][0]]
            if (abs(st.liftoff_time - first.liftoff_time) <= TIME_TOLERANCE
                    and abs(st.touchdown_time - first.touchdown_time) <= TIME_TOLERANCE
                    and all(steps[j].leg != st.leg for j in groups[-1])):
                groups[-1].append(i)
                continue
        groups.append([i])
    return groups


@dataclass(frozen=True)
class StepEvent:
    """A lift-off or touchdown decided at tick ``time``."""

    kind: str          # 'liftoff' | 'touchdown'
    step: int          # index into plan.steps
    leg: int           # 0..3
    time: float        # s, the tick
    reason: str        # liftoff: 'planned'; touchdown: 'contact' | 'planned' | 'forced'
    replan: bool       # the touchdown completing a group whose steps have replan=True
    # touchdown: the last foot of its group down (always so in a crawl); lift-off: True
    completes_group: bool = True


class StepTracker:
    """Follows a FootholdPlan tick by tick and decides lift-offs and touchdowns."""

    def __init__(self, plan: FootholdPlan, min_swing_fraction: float | None = None,
                 max_extension: float | None = None) -> None:
        """The rule's two values come with the plan; the arguments override them (tests)."""
        if min_swing_fraction is None:
            min_swing_fraction = plan.min_swing_fraction
        if max_extension is None:
            max_extension = plan.max_extension
        if not 0.0 <= min_swing_fraction <= 1.0:
            raise ValueError('min_swing_fraction must be within [0, 1]')
        if max_extension < 0.0:
            raise ValueError('max_extension must be >= 0')
        self.plan = plan
        self.min_swing_fraction = float(min_swing_fraction)
        self.max_extension = float(max_extension)
        self.groups = step_groups(plan.steps)   # the steps that swing together
        self.group_of = [0] * len(plan.steps)   # per step, the index of its group
        for g, group in enumerate(self.groups):
            for i in group:
                self.group_of[i] = g
        self.next_group = 0                     # index of the next group to lift off
        self.active_steps: list[int] = []       # indices of the steps in swing
        self.liftoff_tick: list[float | None] = [None] * len(plan.steps)
        self.touchdown_tick: list[float | None] = [None] * len(plan.steps)
        self.touchdown_reason: list[str | None] = [None] * len(plan.steps)
        self.last_time = plan.start_time        # its tick triggered the plan: done already
        # The controller tracks the old plan until this tick: nothing of this one lifts off
        # before it, so the gait node's tracker and the controller's agree on every lift-off.
        self.effective_from = plan.start_time + plan.latency     # s
        self.replan_due = False                 # a replan=True step touched down this tick
        self.events: list[StepEvent] = []       # the events of the last processed tick

    # -- queries ------------------------------------------------------------------------------

    @property
    def next_step(self) -> int:
        """Index of the next step to lift off (the first of the next group)."""
        if self.next_group >= len(self.groups):
            return len(self.plan.steps)
        return self.groups[self.next_group][0]

    @property
    def active(self) -> int | None:
        """Index of the first step in swing, or None (in a crawl: the one step in swing)."""
        return self.active_steps[0] if self.active_steps else None

    @property
    def in_swing(self) -> np.ndarray:
        """(4,) bool: legs in swing after the last processed tick."""
        swing = np.zeros(4, dtype=bool)
        for index in self.active_steps:
            swing[self.plan.steps[index].leg] = True
        return swing

    def active_step(self, leg: int) -> int | None:
        """Index of the step ``leg`` is swinging, or None if it is in stance."""
        for index in self.active_steps:
            if self.plan.steps[index].leg == leg:
                return index
        return None

    def step(self, index: int) -> Step:
        return self.plan.steps[index]

    @property
    def done(self) -> bool:
        """All steps of the plan have touched down (the final stance holds)."""
        return not self.active_steps and self.next_group >= len(self.groups)

    def swing_start(self, index: int) -> float:
        """Time the swing of step ``index`` may start by the plan's steps: max(its group's
        planned lift-off, the previous group's touchdown, i.e. its last foot's); a first
        group also waits for ``effective_from``.

        Before a foot of the previous group has touched down, its planned touchdown stands in.
        """
        g = self.group_of[index]
        start = self.plan.steps[self.groups[g][0]].liftoff_time
        if g == 0:
            return start
        for i in self.groups[g - 1]:
            prev = self.touchdown_tick[i]
            start = max(start, self.plan.steps[i].touchdown_time if prev is None else prev)
        return start

    # -- the rule -----------------------------------------------------------------------------

    def _touchdown_reason(self, index: int, t: float, contact: bool) -> str | None:
        step = self.plan.steps[index]
        liftoff = self.liftoff_tick[index]
        if t <= liftoff + TIME_TOLERANCE:
            return None                          # never at the lift-off tick itself
        if not step.haptic:
            return 'planned' if t >= step.touchdown_time - TIME_TOLERANCE else None
        duration = step.touchdown_time - step.liftoff_time
        earliest = liftoff + self.min_swing_fraction * duration
        if contact and t >= earliest - TIME_TOLERANCE:
            return 'contact'
        if t >= step.touchdown_time + self.max_extension - TIME_TOLERANCE:
            return 'forced'
        return None

    def update(self, t: float, contact_flags) -> list[StepEvent]:
        """Process the tick at sim time ``t`` with the debounced contact flags (4,) bool.

        Returns the lift-off/touchdown events of this tick in order (also in ``events``); sets
        ``replan_due``. A tick at or before the last processed one returns [] and changes
        nothing.
        """
        if t <= self.last_time + TIME_TOLERANCE:
            return []
        self.last_time = t
        flags = np.asarray(contact_flags, dtype=bool).reshape(4)
        events: list[StepEvent] = []
        self.replan_due = False
        while True:
            if self.active_steps:
                landed = []
                for index in self.active_steps:
                    step = self.plan.steps[index]
                    reason = self._touchdown_reason(index, t, bool(flags[step.leg]))
                    if reason is not None:
                        landed.append((index, reason))
                for index, reason in landed:
                    self.active_steps.remove(index)
                    self.touchdown_tick[index] = t
                    self.touchdown_reason[index] = reason
                    step = self.plan.steps[index]
                    # The group's last foot down triggers its re-plan: all feet in stance.
                    replan = step.replan and not self.active_steps
                    self.replan_due = self.replan_due or replan
                    events.append(StepEvent('touchdown', index, step.leg, t, reason, replan,
                                            not self.active_steps))
                if self.active_steps:
                    break                        # a foot of the group still swings
                if self.replan_due:
                    # The caller re-plans now: the rest of this plan is superseded.
                    break
            if self.next_group >= len(self.groups):
                break
            group = self.groups[self.next_group]
            if t < max(self.swing_start(group[0]), self.effective_from) - TIME_TOLERANCE:
                break
            for index in group:
                self.liftoff_tick[index] = t
                self.active_steps.append(index)
                events.append(StepEvent('liftoff', index, self.plan.steps[index].leg, t,
                                        'planned', False))
            self.next_group += 1
        self.events = events
        return events
