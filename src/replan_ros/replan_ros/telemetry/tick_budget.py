"""Per-tick cost budget of the lock-step loop: wall time of each phase of a control tick.

Always on (docs/ARCHITECTURE.md, "Per-tick budget"): a phase costs two
``time.perf_counter_ns`` calls and an integer addition, a tick one row copied into a ring of
the last ``capacity`` ticks, together a few microseconds in a tick of about 4 ms (the cost is
measured by ``python -m replan_ros.telemetry.tick_budget``), so there is no parameter to switch it
off
and the figures are there whenever someone asks why a run is slow.

A node names its phases once; during a tick it adds the nanoseconds spent in each (a phase
met twice in a tick, e.g. a publish repeated, adds up; one not met counts 0) and closes the
tick with ``end_tick``. ``period_values`` gives the median and mean (ms per tick) of every
phase over the ticks since its last call, for the node's /diagnostics; ``summary`` the same
over the last ``capacity`` ticks, for the log line at shutdown. Ticks whose phase ``skip``
is set (e.g. the first command, which waits for the first plans) are left out.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable

import numpy as np

_NS_PER_MS = 1e6
DIAGNOSTIC_PREFIX = 'tick_'
LOG_PREFIX = 'tick budget: '

# The sim node's phases of a lock-step tick, from the command's arrival to the next one.
SIM_PHASES = (
    'sim_transport_cmd',          # joint_torque_cmd: wbc's DDS write -> our DDS reader
    'sim_wake',                   # our DDS reader -> _on_command (executor, take, deserialize)
    'sim_decode',                 # the command to torques
    'sim_physics',                # the physics steps of one control period after the lead ones
    'sim_sensing',                # IMU and joint sensor models
    'sim_conversion',             # imu and joint_states messages built
    'sim_publish_imu',
    'sim_publish_joint_states',
    'sim_truth_first',            # truth_first: the truth sensed, built and published first
    'sim_wait',                   # joint_states published -> the next command's callback
    # While the controller works (after joint_states, inside sim_wait):
    'sim_truth_sensing',          # the simulator's exact base state and contact forces
    'sim_truth_conversion',       # their messages built
    'sim_publish_truth_odom',
    'sim_publish_truth_contacts',
    'sim_publish_clock',
    'sim_lead_physics',           # due wrenches, the next period's lead physics steps
    'sim_tick',                   # wall time between two commands' callbacks
)

# The wbc node's phases of an answered tick, from the sim's joint_states write to its command's
# publish.
WBC_PHASES = (
    'wbc_transport_in',      # joint_states: the sim's DDS write -> our DDS reader
    'wbc_wake',              # our DDS reader -> _on_joint_states (executor, take, deserialize)
    'wbc_decode',            # joint_states to the core joint state
    'wbc_take',              # the tick's queued imu / ground truth taken and decoded
    'wbc_estimator',         # state estimator update
    'wbc_state_msgs',        # odom, contacts and contact_events messages built
    'wbc_logic',             # the protocol's decisions: plan following, adoption, stand
    'wbc_plan_wait',         # a re-plan tick held until its plans arrived
    'wbc_controller',        # references and controller maths (pinocchio, proxsuite)
    'wbc_command',           # joint_torque_cmd built and published
    'wbc_publish_state',     # then odom, contacts (and contact_events) published
    'wbc_estimator_next',    # then the estimator's next covariance step (prepare_next)
)


class TickBudget:
    """Nanoseconds per phase of each tick, the last ``capacity`` ticks kept."""

    def __init__(self, phases: Iterable[str], capacity: int = 10_000) -> None:
        self.phases = tuple(phases)
        self._index = {name: i for i, name in enumerate(self.phases)}
        self._current = [0] * len(self.phases)
        self._ring = np.zeros((capacity, len(self.phases)), dtype=np.int64)
        self._ticks = 0               # ticks closed so far
        self._period_start = 0        # tick count at the last period_values call

    @property
    def ticks(self) -> int:
        return self._ticks

    def add(self, phase: str, ns: int) -> None:
        """``ns`` nanoseconds spent in ``phase`` during the current tick."""
        self._current[self._index[phase]] += ns

    def add_delivery(self, info: dict | None, callback_wall_ns: int, transport: str,
                     wake: str) -> None:
        """A message's DDS transport (writer's write -> our reception) into ``transport`` and
        its wake-up (reception -> the callback, started at ``callback_wall_ns``, time.time_ns)
        into ``wake``, from the message info rclpy gives a two-argument callback; nothing if
        the info lacks the timestamps or they are out of order (clock steps)."""
        if not info:
            return
        sent, received = info.get('source_timestamp', 0), info.get('received_timestamp', 0)
        if 0 < sent <= received <= callback_wall_ns:
            self.add(transport, received - sent)
            self.add(wake, callback_wall_ns - received)

    def discard_tick(self) -> None:
        """Forget what the current tick has gathered (a tick not to be counted)."""
        self._current = [0] * len(self.phases)

    def end_tick(self) -> None:
        self._ring[self._ticks % len(self._ring)] = self._current
        self._current = [0] * len(self.phases)
        self._ticks += 1

    def _rows(self, since: int) -> np.ndarray:
        capacity = len(self._ring)
        count = min(self._ticks - since, capacity)
        if count <= 0:
            return self._ring[:0]
        end = self._ticks % capacity
        if count <= end:
            return self._ring[end - count:end]
        return np.concatenate((self._ring[capacity - (count - end):], self._ring[:end]))

    @staticmethod
    def _stats(rows: np.ndarray, phases: tuple[str, ...]) -> dict[str, tuple[float, float]]:
        medians = np.median(rows, axis=0) / _NS_PER_MS
        means = rows.mean(axis=0) / _NS_PER_MS
        return {name: (float(medians[i]), float(means[i])) for i, name in enumerate(phases)}

    def period_values(self) -> dict[str, float]:
        """/diagnostics values over the ticks since the last call: ``tick_<phase>_median_ms``,
        ``tick_<phase>_mean_ms`` and ``tick_budget_ticks``; empty if there was no tick."""
        rows = self._rows(self._period_start)
        self._period_start = self._ticks
        if not len(rows):
            return {}
        values: dict[str, float] = {f'{DIAGNOSTIC_PREFIX}budget_ticks': len(rows)}
        for name, (median, mean) in self._stats(rows, self.phases).items():
            values[f'{DIAGNOSTIC_PREFIX}{name}_median_ms'] = median
            values[f'{DIAGNOSTIC_PREFIX}{name}_mean_ms'] = mean
        return values

    def summary(self) -> dict:
        """Median and mean (ms per tick) of every phase over the last ``capacity`` ticks."""
        rows = self._rows(0)
        stats = self._stats(rows, self.phases) if len(rows) else {}
        return {'ticks': len(rows),
                'phases': {name: {'median_ms': round(median, 5), 'mean_ms': round(mean, 5)}
                           for name, (median, mean) in stats.items()}}

    def log_line(self, node: str) -> str:
        """One line for the node's log at shutdown (``scripts/tick_budget.sh`` reads it)."""
        return LOG_PREFIX + json.dumps({'node': node, **self.summary()})


class PhaseTimer:
    """A node's phases as laps of one clock, for a tick that spans callbacks (the wbc's, held
    for its plans, is answered from a plan's callback or a timer): which tick the budget
    gathers (``open``, ``counts``, ``close``), where the current phase began (``mark``) and
    each phase's end (``lap``: the time since the mark, then a new mark)."""

    def __init__(self, budget: TickBudget, clock=time.perf_counter_ns) -> None:
        self.budget = budget
        self.clock = clock
        self.tick: int | None = None       # the stamp whose phases the budget gathers
        self.mark_ns: int | None = None    # when the current phase began; None: no phase

    def open(self, stamp: int) -> None:
        """Gather the phases of tick ``stamp``, anything gathered before forgotten (a tick
        never answered is not counted)."""
        self.budget.discard_tick()
        self.tick = stamp

    def counts(self, stamp: int) -> bool:
        return self.tick == stamp

    def close(self) -> None:
        """The counted tick is complete: into the budget."""
        self.budget.end_tick()
        self.tick = None

    def drop(self) -> None:
        """The gathered tick is not to be counted (e.g. the first, held for the planners)."""
        self.tick = None

    def mark(self) -> int:
        self.mark_ns = self.clock()
        return self.mark_ns

    def unmark(self) -> None:
        self.mark_ns = None

    def lap(self, phase: str) -> int:
        """The time since the mark into ``phase``; the mark moves to now (returned)."""
        now = self.clock()
        self.budget.add(phase, now - self.mark_ns)
        self.mark_ns = now
        return now

    def add_since(self, phase: str, start_ns: int) -> None:
        """The time since ``start_ns`` (this clock) into ``phase``; the mark stays."""
        self.budget.add(phase, self.clock() - start_ns)


def parse_log_line(line: str) -> dict | None:
    """The summary of a ``log_line`` found in ``line`` (a node log line), or None."""
    at = line.find(LOG_PREFIX)
    if at < 0:
        return None
    try:
        return json.loads(line[at + len(LOG_PREFIX):])
    except ValueError:
        return None


def parse_diagnostic_values(values: dict[str, str]) -> dict[str, dict[str, float]]:
    """phase -> {'median_ms', 'mean_ms'} from a /diagnostics status's key/value pairs."""
    phases: dict[str, dict[str, float]] = {}
    for key, value in values.items():
        if not key.startswith(DIAGNOSTIC_PREFIX):
            continue
        for stat in ('median_ms', 'mean_ms'):
            if key.endswith('_' + stat):
                name = key[len(DIAGNOSTIC_PREFIX):-len(stat) - 1]
                phases.setdefault(name, {})[stat] = float(value)
    return phases


def _self_cost(ticks: int = 20_000, phases: int = 16) -> float:
    """Wall µs per tick of the instrumentation itself (``phases`` phases timed per tick)."""
    budget = TickBudget([f'p{i}' for i in range(phases)])
    names = budget.phases
    clock = time.perf_counter_ns
    start = clock()
    for _ in range(ticks):
        for name in names:
            t0 = clock()
            budget.add(name, clock() - t0)
        budget.end_tick()
    return (clock() - start) / ticks / 1e3


if __name__ == '__main__':
    print(f'tick budget instrumentation: {_self_cost():.2f} µs per tick with 16 phases')
