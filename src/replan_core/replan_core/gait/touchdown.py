"""StepTracker: the one touchdown rule, shared by the gait node and the whole-body controller.

Both feed it the same plan and, every control tick, the same (stamp, debounced contact flags);
the rule is plain float logic on those inputs, so both reach the same decisions on the same tick
however slow either process is.

Rule (docs/gait.md):
- Steps run one after the other in plan order. A step's swing starts (lift-off) at the first tick
  t >= max(its planned lift-off, the previous step's actual touchdown tick).
- A haptic step ends (touchdown) at the first tick t >= liftoff + min_swing_fraction *
  (touchdown_time - liftoff_time) whose contact flag is set (reason ``contact``), where
  ``liftoff`` is the actual lift-off tick and the duration the planned one; if no contact came,
  it is forced at the first tick t >= touchdown_time + max_extension (reason ``forced``).
- A non-haptic step ends at the first tick t >= touchdown_time (reason ``planned``).
- A step never ends at its own lift-off tick.
- Ticks at or before the last processed one (duplicates, and ``plan.start_time`` itself, whose
  tick triggered this plan) change nothing.
All comparisons use a 1e-9 s tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replan_core.common.types import FootholdPlan, Step

TIME_TOLERANCE = 1e-9   # s, float comparisons of stamps


@dataclass(frozen=True)
class StepEvent:
    """A lift-off or touchdown decided at tick ``time``."""

    kind: str          # 'liftoff' | 'touchdown'
    step: int          # index into plan.steps
    leg: int           # 0..3
    time: float        # s, the tick
    reason: str        # liftoff: 'planned'; touchdown: 'contact' | 'planned' | 'forced'
    replan: bool       # touchdown of a step with replan=True


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
        self.next_step = 0                      # index of the next step to lift off
        self.active: int | None = None          # index of the step in swing
        self.liftoff_tick: list[float | None] = [None] * len(plan.steps)
        self.touchdown_tick: list[float | None] = [None] * len(plan.steps)
        self.touchdown_reason: list[str | None] = [None] * len(plan.steps)
        self.last_time = plan.start_time        # its tick triggered the plan: done already
        self.replan_due = False                 # a replan=True step touched down this tick
        self.events: list[StepEvent] = []       # the events of the last processed tick

    # -- queries ------------------------------------------------------------------------------

    @property
    def in_swing(self) -> np.ndarray:
        """(4,) bool: legs in swing after the last processed tick."""
        swing = np.zeros(4, dtype=bool)
        if self.active is not None:
            swing[self.plan.steps[self.active].leg] = True
        return swing

    def active_step(self, leg: int) -> int | None:
        """Index of the step ``leg`` is swinging, or None if it is in stance."""
        if self.active is not None and self.plan.steps[self.active].leg == leg:
            return self.active
        return None

    def step(self, index: int) -> Step:
        return self.plan.steps[index]

    @property
    def done(self) -> bool:
        """All steps of the plan have touched down (the final stance holds)."""
        return self.active is None and self.next_step >= len(self.plan.steps)

    def swing_start(self, index: int) -> float:
        """Time the swing of step ``index`` starts: max(planned lift-off, previous touchdown).

        Before the previous step has touched down, its planned touchdown stands in for it.
        """
        step = self.plan.steps[index]
        if index == 0:
            return step.liftoff_time
        prev = self.touchdown_tick[index - 1]
        if prev is None:
            prev = self.plan.steps[index - 1].touchdown_time
        return max(step.liftoff_time, prev)

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
            if self.active is not None:
                index = self.active
                step = self.plan.steps[index]
                reason = self._touchdown_reason(index, t, bool(flags[step.leg]))
                if reason is None:
                    break
                self.touchdown_tick[index] = t
                self.touchdown_reason[index] = reason
                self.active = None
                self.replan_due = self.replan_due or step.replan
                events.append(StepEvent('touchdown', index, step.leg, t, reason, step.replan))
                if step.replan:
                    # The caller re-plans now: the rest of this plan is superseded.
                    break
            if self.next_step >= len(self.plan.steps):
                break
            index = self.next_step
            if t < self.swing_start(index) - TIME_TOLERANCE:
                break
            step = self.plan.steps[index]
            self.liftoff_tick[index] = t
            self.active = index
            self.next_step += 1
            events.append(StepEvent('liftoff', index, step.leg, t, 'planned', False))
        self.events = events
        return events
