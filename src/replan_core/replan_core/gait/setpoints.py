"""The velocity set-point of a re-plan, decided in sim time. The gait node receives the
messages and calls this.

Set-points come stamped (``cmd_vel_stamped``: from their stamp on, as a scenario or a re-run
sends them) or live (``cmd_vel``: from the sim time of their arrival, and only for ``timeout``
s of sim time after it). A re-plan at ``t`` takes the newer of the stamped one in force at
``t`` and the live one; with neither, zero. The gait works the same way (``GaitArbiter``).
"""

from __future__ import annotations

import bisect
import math

import numpy as np


class SetpointArbiter:
    """The set-point (vx, vy, wz) of a re-plan from stamped and live set-points."""

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout                     # s of sim time a live set-point holds
        self._stamped: list[tuple[int, np.ndarray]] = []     # (stamp ns, value), by stamp
        self._live: np.ndarray | None = None
        self._live_time = -math.inf                # s, sim time the live one arrived at

    def add_stamped(self, stamp_ns: int, value: np.ndarray) -> None:
        """A stamped set-point, in force from ``stamp_ns`` on (after any with the same
        stamp that came before it)."""
        index = bisect.bisect_right([s for s, _ in self._stamped], stamp_ns)
        self._stamped.insert(index, (stamp_ns, np.asarray(value, dtype=float)))

    def set_live(self, value: np.ndarray, t: float) -> None:
        """A live set-point that arrived at sim time ``t`` (s)."""
        self._live = np.asarray(value, dtype=float)
        self._live_time = t

    def at(self, t_ns: int) -> tuple[np.ndarray, str]:
        """The set-point for a re-plan at ``t_ns`` and where it came from: ``cmd_vel``,
        ``cmd_vel timed out``, ``cmd_vel_stamped`` or ``none``. Stamped set-points older than
        the one in force are dropped: re-plans come in time order."""
        index = bisect.bisect_right([s for s, _ in self._stamped], t_ns)
        if index > 1:
            del self._stamped[:index - 1]
            index = 1
        stamped = self._stamped[index - 1] if index else None
        t = t_ns * 1e-9
        if self._live is not None and (stamped is None
                                       or self._live_time >= stamped[0] * 1e-9):
            if t - self._live_time > self.timeout:
                return np.zeros(3), 'cmd_vel timed out'
            return self._live.copy(), 'cmd_vel'
        if stamped is not None:
            return stamped[1].copy(), 'cmd_vel_stamped'
        return np.zeros(3), 'none'


class GaitArbiter:
    """The gait a re-plan walks, from stamped requests (in force from their stamp) and live
    ones (stamped by the caller with the sim time they arrived at)."""

    def __init__(self, start: str) -> None:
        self._requests: list[tuple[int, int, str]] = [(-1, 0, start)]   # (stamp ns, order, name)
        self._count = 0

    def add(self, stamp_ns: int, name: str) -> None:
        """A request for gait ``name`` from ``stamp_ns`` on (after any with the same stamp
        that came before it)."""
        self._count += 1
        bisect.insort(self._requests, (stamp_ns, self._count, name))

    def at(self, t_ns: int) -> str:
        """The gait requested last at or before ``t_ns``; older requests are dropped:
        re-plans come in time order."""
        index = bisect.bisect_right(self._requests, (t_ns, math.inf, ''))
        if index > 1:
            del self._requests[:index - 1]
        return self._requests[0][2]
