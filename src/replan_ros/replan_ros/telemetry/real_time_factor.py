"""The real-time factor of a simulation over the last wall second, for /diagnostics."""

from __future__ import annotations

from collections import deque


class RealTimeFactor:
    """Sim seconds per wall second over about the last wall second (0 when nothing stepped
    in it). Wall times are the caller's (time.monotonic())."""

    def __init__(self) -> None:
        self._samples: deque[tuple[float, float]] = deque()   # (wall s, sim s)

    def stepped(self, wall: float, sim_time: float) -> None:
        """The sim reached ``sim_time`` at ``wall``."""
        self._samples.append((wall, sim_time))
        while len(self._samples) > 2 and wall - self._samples[1][0] >= 1.0:
            self._samples.popleft()

    def value(self, wall: float, sim_time: float) -> float:
        if len(self._samples) < 2:
            return 0.0
        wall0, sim0 = self._samples[0]
        if wall - self._samples[-1][0] > 1.0:      # nothing stepped in the last second
            return 0.0
        return (sim_time - sim0) / max(wall - wall0, 1e-9)
