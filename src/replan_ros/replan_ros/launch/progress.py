"""The launcher's progress line: its text (``format_progress``), the real-time factors it
shows (``RunProgress``) and how it is printed (``ProgressLine``: in place on a terminal, plain
lines otherwise)."""

from __future__ import annotations

import os
import shutil
import sys
from collections import deque

PROGRESS_TTY_PERIOD = 1.0      # s, wall: refresh of the in-place progress line on a terminal
PROGRESS_PLAIN_PERIOD = 5.0    # s, wall: one progress line per period otherwise (CI logs)
PROGRESS_RTF_WINDOW = 5.0      # s, wall: window of the recent real-time factor


# Words of the launcher's event lines that tests and users grep for; a progress line must
# never contain them (test/test_launch.py, test/test_config_errors.py).
EVENT_WORDS = ('started', 'died', 'respawn', 'real-time factor', 'reached', 'stopping',
               'stopped', 'error', 'deviation')


def format_progress(sim_time: float, duration: float | None, rtf_recent: float | None,
                    rtf_total: float | None, distance: float | None, *,
                    estimated: bool = False, replans: int = 0,
                    events: tuple[int, int] | None = None) -> str:
    """One progress line: sim time (of ``duration``), real-time factor over the last few wall
    seconds and since the first tick, distance from the start, re-plans, and for scenarios the
    timed inputs whose time has come out of those sent (``events``: (due, sent))."""
    if duration:
        parts = [f'sim {sim_time:5.1f} / {duration:.1f} s '
                 f'({min(100.0, 100.0 * sim_time / duration):3.0f} %)']
    else:
        parts = [f'sim {sim_time:5.1f} s']
    if rtf_total is None:
        parts.append('waiting for the first tick')
    else:
        recent = f'{rtf_recent:.2f}' if rtf_recent is not None else '-'
        parts.append(f'RTF {recent} now, {rtf_total:.2f} overall')
    if distance is not None:
        parts.append(f'distance {distance:.2f} m' + (' (estimated)' if estimated else ''))
    parts.append(f're-plans {replans}')
    if events is not None:
        parts.append(f'events {events[0]}/{events[1]}')
    return '[progress] ' + ' | '.join(parts)


def is_terminal(stream) -> bool:
    """True if ``stream`` is an interactive terminal that understands \\r and ESC[K."""
    try:
        return bool(stream.isatty()) and os.environ.get('TERM', '') != 'dumb'
    except (AttributeError, ValueError):      # no isatty, or a closed stream
        return False


class ProgressLine:
    """Prints progress lines: refreshed in place on a terminal (every PROGRESS_TTY_PERIOD),
    else as plain lines every PROGRESS_PLAIN_PERIOD, so that logs stay readable."""

    def __init__(self, stream=None, *, in_place: bool | None = None,
                 period: float | None = None) -> None:
        self.stream = stream if stream is not None else sys.stdout
        self.in_place = is_terminal(self.stream) if in_place is None else in_place
        self.period = period if period is not None else (
            PROGRESS_TTY_PERIOD if self.in_place else PROGRESS_PLAIN_PERIOD)
        self._next: float | None = None
        self._shown = False

    def due(self, now: float) -> bool:
        """True when a new line should be shown (the first one a period after the first call)."""
        if self._next is None:
            self._next = now + self.period
        return now >= self._next

    def show(self, text: str, now: float) -> None:
        self._next = now + self.period
        if self.in_place:
            # A line longer than the terminal would wrap, and \r would then only rewrite its
            # last row.
            width = shutil.get_terminal_size((120, 24)).columns
            self.stream.write('\r' + text[:max(width - 1, 20)] + '\x1b[K')
            self._shown = True
        else:
            self.stream.write(text + '\n')
        self.stream.flush()

    def clear(self) -> None:
        """Erase the in-place line, before another line is printed or at the end."""
        if self._shown:
            self.stream.write('\r\x1b[K')
            self.stream.flush()
            self._shown = False


class RunProgress:
    """Real-time factors from (wall, sim) samples and the progress text of a run."""

    def __init__(self, duration: float | None, event_times=(),
                 window: float = PROGRESS_RTF_WINDOW) -> None:
        self.duration = duration
        self.event_times = sorted(event_times)
        self.window = window
        self._first: tuple[float, float] | None = None    # (wall, sim) when the sim moved
        self._recent: deque[tuple[float, float]] = deque()
        self.sim_time = 0.0

    def sample(self, wall: float, sim_time: float) -> None:
        self.sim_time = sim_time
        if sim_time <= 0.0:
            return
        if self._first is None:
            self._first = (wall, sim_time)
        self._recent.append((wall, sim_time))
        while len(self._recent) > 2 and wall - self._recent[1][0] >= self.window:
            self._recent.popleft()

    def real_time_factors(self) -> tuple[float | None, float | None]:
        """(over the last ``window`` wall seconds, since the first tick); None before the sim
        moved (or too soon to tell)."""
        if self._first is None:
            return None, None
        last_wall, last_sim = self._recent[-1]
        total = ((last_sim - self._first[1]) / (last_wall - self._first[0])
                 if last_wall > self._first[0] else 0.0)
        wall0, sim0 = self._recent[0]
        recent = (last_sim - sim0) / (last_wall - wall0) if last_wall > wall0 else None
        return recent, total

    def text(self, distance: float | None, *, estimated: bool = False,
             replans: int = 0) -> str:
        recent, total = self.real_time_factors()
        events = None
        if self.event_times:
            due = sum(1 for t in self.event_times if t <= self.sim_time + 1e-9)
            events = (due, len(self.event_times))
        return format_progress(self.sim_time, self.duration, recent, total, distance,
                               estimated=estimated, replans=replans, events=events)
