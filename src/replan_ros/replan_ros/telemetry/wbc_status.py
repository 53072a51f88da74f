"""The wbc's /diagnostics status: the answered ticks' figures over one period and the state of
its protocol (replan_core.wbc.tick_protocol); docs/usage.md lists the keys."""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from replan_ros.telemetry import diagnostics

_NS = 1_000_000_000


class ControllerStats:
    """Figures of the answered ticks, gathered over a diagnostics period."""

    def __init__(self) -> None:
        self.ticks = 0
        self.fallbacks = 0
        self._times: deque[float] = deque(maxlen=2000)      # s, compute time per tick
        self._com_errors: deque[float] = deque(maxlen=2000)   # m
        self._last = None                                     # the last WbcResult
        self._period_timeouts = 0
        self._period_fallbacks = 0

    def answered(self, result) -> None:
        """One answered tick's ``WbcResult``."""
        self.ticks += 1
        self._times.append(result.compute_time)
        self._com_errors.append(float(np.linalg.norm(result.com_error)))
        self._last = result
        if result.fallback:
            self.fallbacks += 1
            self._period_fallbacks += 1

    def timed_out(self) -> None:
        """A held tick was answered without its plans (plan_timeout)."""
        self._period_timeouts += 1

    def status(self, protocol, values: dict) -> tuple[int, str, dict]:
        """(level, message, values) of the period that ends now, with ``values`` (the node's
        own keys) merged in; starts the next period."""
        result = self._last
        if result is None:
            # Which side is silent: no joint_states at all (the sim, or DDS delivery to this
            # process), or states that were not answered (waiting for plans or listeners).
            received = values.get('joint_states_received', 0)
            message = (f'no state answered yet ({received} joint_states received)' if received
                       else 'no state answered yet: no joint_states received')
            return (diagnostics.WARN, message,
                    {'waiting_for_plans': protocol.waiting is not None, **values})
        # Figures over the period; a period without ticks (waiting) repeats the last one.
        times = np.array(self._times or [result.compute_time]) * 1e3
        errors = np.array(self._com_errors or [float(np.linalg.norm(result.com_error))])
        fallen, standing = protocol.fallen, protocol.stand is not None
        values = {
            'mode': protocol.mode,
            'trunk_tilt_deg': math.degrees(protocol.tilt),
            'fallen_at_s': fallen[0] if fallen is not None else '',
            'stand_reason': protocol.stand_reason if standing else '',
            'stand_since_s': protocol.stand_since if standing else '',
            'compute_time_ms': times[-1],
            'compute_time_median_ms': float(np.median(times)),
            'compute_time_max_ms': float(times.max()),
            'com_error_m': errors[-1],
            'com_error_max_m': float(errors.max()),
            'active_contacts': ''.join(str(int(c)) for c in result.active_contacts),
            'stance_legs': ''.join(str(int(c)) for c in result.stance),
            'qp_status': result.qp_status,
            'qp_iterations': result.qp_iterations,
            'saturated_joints': result.saturated,
            'plan_stamp': protocol.plan_stamp / _NS if protocol.plan_stamp is not None else '',
            'last_tick': protocol.last_answered / _NS,
            'ticks': self.ticks,
            'plan_timeouts': protocol.plan_timeouts,
            'missed_replans': protocol.missed_replans,
            'missing_plans': protocol.missing,
            'plan_latency_s': protocol.latency_ns / _NS,
            'plan_pending': protocol.pending is not None,
            'fallbacks': self.fallbacks,
            'waiting_for_plans': protocol.waiting is not None,
            **values,
        }
        if fallen is not None:
            level, message = diagnostics.ERROR, (
                f'fallen at t = {fallen[0]:.3f} s (trunk tilted '
                f'{math.degrees(fallen[1]):.0f} deg): joints damped, plans ignored; '
                'restart the wbc once the robot is upright')
        elif self._period_fallbacks:
            level, message = diagnostics.ERROR, f'{self._period_fallbacks} fallback ticks'
        elif standing and protocol.missed_replans:
            level, message = diagnostics.ERROR, f'standing: {protocol.stand_reason}'
        elif self._period_timeouts:
            level, message = (diagnostics.WARN, f'plan timeout: no '
                              f'{protocol.missing or "footholds/com_plan"} in time, went on '
                              'with the old plans')
        elif standing:
            level, message = diagnostics.WARN, f'standing: {protocol.stand_reason}'
        else:
            level, message = diagnostics.OK, 'tracking the plan'
        self._times.clear()
        self._com_errors.clear()
        self._period_timeouts = 0
        self._period_fallbacks = 0
        return level, message, values
