"""The external wrench acting at a tick, decided in sim time. The sim node receives the
messages and calls this.

Wrenches are stamped with the sim time they start at (0: now) and kept in stamp order (ties in
arrival order); at each tick the latest one due replaces the one acting.
"""

from __future__ import annotations

import bisect

import numpy as np


class WrenchSchedule:
    """External wrenches on the trunk (world axes), each acting from its stamp on."""

    def __init__(self) -> None:
        self._queue: list[tuple[int, int, np.ndarray, np.ndarray]] = []  # (ns, seq, f, tau)
        self._seq = 0

    def add(self, stamp_ns: int, force: np.ndarray, torque: np.ndarray) -> None:
        """A wrench (N, N m) from ``stamp_ns`` on."""
        entry = (stamp_ns, self._seq, np.asarray(force, float), np.asarray(torque, float))
        self._seq += 1
        bisect.insort(self._queue, entry, key=lambda e: (e[0], e[1]))

    def due(self, now_ns: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The wrench that takes effect at tick ``now_ns``: the latest stamped at or before it
        (the earlier ones due meanwhile never act), or None if none is due."""
        due = None
        while self._queue and self._queue[0][0] <= now_ns:
            due = self._queue.pop(0)
        return None if due is None else (due[2], due[3])

    def __len__(self) -> int:
        return len(self._queue)
