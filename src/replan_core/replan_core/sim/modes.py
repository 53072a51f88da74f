"""The simulator's mode machine: when it steps, holds, free-runs or damps (docs/sim.md;
docs/ARCHITECTURE.md, "Time and lock-step").

ROS-free: the sim node passes the sim time (ns), the command's stamp and its wall clock (s,
monotonic) in, and carries out what the machine decides (step the world, republish, start or
stop its free-run timer, log).

Modes: ``waiting_first_command`` (nothing steps before the first command), ``lock_step`` (one
tick per command stamped with the current tick), ``free_run`` (real time, the last command;
``lock_step`` off), ``damping`` (no command for ``command_timeout`` wall s: the controller is
dead, the robot sits down in real time; a command of an older stamp brings lock-step back). At
or after ``stop_time`` nothing steps any more (held), whatever the mode.
"""

from __future__ import annotations

from dataclasses import dataclass

WAITING, LOCK_STEP, FREE_RUN, DAMPING = 'waiting_first_command', 'lock_step', 'free_run', 'damping'
MAX_CATCH_UP_TICKS = 25     # free-run: ticks stepped at most per call before slipping

# What a command asks of the sim (SimModes.command).
APPLY = 'apply'      # free-run: it acts from now on
STEP = 'step'        # lock-step: step one tick with it
ALIVE = 'alive'      # held at stop_time: the controller is alive, nothing steps
RESYNC = 'resync'    # back from damping: lock-step at the current tick, republish it
IGNORE = 'ignore'    # a stamp that is not the current tick


@dataclass
class ModeChange:
    """A transition ``old`` -> ``new`` (the node reacts: timers, logs, who reads the truth)."""

    old: str
    new: str


class SimModes:
    """The mode machine of one sim."""

    def __init__(self, lock_step: bool, command_timeout: float, stop_ns: int | None,
                 wall: float) -> None:
        self.lock_step = lock_step
        self.command_timeout = command_timeout      # wall s without a command: damping
        self.stop_ns = stop_ns                      # hold at the first tick at or after it
        self.mode = WAITING
        self.last_command_wall = wall               # wall s (monotonic)
        self.free_ref = (wall, 0)                   # (wall s, tick) where free-running began
        self.damping_since = 0.0                    # sim s the last damping mode began
        # The command of the held tick came: nothing is waited for any more, so the tick is
        # not republished (the controller answers each republish again, so the last tick
        # would be recorded as many times as republish periods pass before the stop).
        self.held_answered = False

    def holding(self, now_ns: int) -> bool:
        """At or after ``stop_time``: no more steps."""
        return self.stop_ns is not None and now_ns >= self.stop_ns

    def set_mode(self, mode: str, wall: float, tick: int, sim_time: float) -> ModeChange | None:
        """Enter ``mode`` at the sim's ``tick`` (sim s ``sim_time``); the change, if any."""
        if mode == self.mode:
            return None
        if mode in (FREE_RUN, DAMPING):
            self.free_ref = (wall, tick)
        if mode == DAMPING:
            self.damping_since = sim_time
        change = ModeChange(self.mode, mode)
        self.mode = mode
        return change

    def command(self, stamp_ns: int, now_ns: int, wall: float, tick: int, sim_time: float
                ) -> tuple[str, ModeChange | None]:
        """A valid command stamped ``stamp_ns`` at sim time ``now_ns``: what to do with it
        (APPLY, STEP, ALIVE, RESYNC, IGNORE) and the mode change it made."""
        if not self.lock_step:
            self.last_command_wall = wall
            change = None
            if self.mode != FREE_RUN and not self.holding(now_ns):
                change = self.set_mode(FREE_RUN, wall, tick, sim_time)
            return APPLY, change
        if stamp_ns == now_ns:
            self.last_command_wall = wall        # alive: no damping mode
            if self.holding(now_ns):
                self.held_answered = True
                return ALIVE, None
            return STEP, self.set_mode(LOCK_STEP, wall, tick, sim_time)
        if self.mode == DAMPING and stamp_ns < now_ns:
            # The controller is alive again but answers an older state: stop here and wait
            # for its command of the current stamp (it gets command_timeout to send it).
            self.last_command_wall = wall
            return RESYNC, self.set_mode(LOCK_STEP, wall, tick, sim_time)
        return IGNORE, None

    def watchdog(self, now_ns: int, wall: float, tick: int, sim_time: float
                 ) -> ModeChange | None:
        """The periodic check: no command for ``command_timeout`` wall s while stepping (and
        not held) -> damping."""
        silent = wall - self.last_command_wall
        if (self.mode in (LOCK_STEP, FREE_RUN) and silent > self.command_timeout
                and not self.holding(now_ns)):
            return self.set_mode(DAMPING, wall, tick, sim_time)
        return None

    @property
    def waits_for_command(self) -> bool:
        """The sim waits at its current tick (republishing it) for a command; not once the
        held tick at ``stop_time`` has its command."""
        return self.mode in (WAITING, LOCK_STEP) and not self.held_answered

    @property
    def free_running(self) -> bool:
        return self.mode in (FREE_RUN, DAMPING)

    def free_run_ticks(self, now_ns: int, wall: float, tick: int, period: float,
                       real_time_factor: float) -> int:
        """Ticks due by the wall clock in free-run (at most MAX_CATCH_UP_TICKS: the caller
        then calls ``slip``); 0 when not free-running or held."""
        if not self.free_running or self.holding(now_ns):
            return 0
        wall0, tick0 = self.free_ref
        return max(tick0 + int((wall - wall0) * real_time_factor / period) - tick, 0)

    def slip(self, wall: float, tick: int) -> None:
        """Too slow for the target real-time factor: restart the reference, do not spiral."""
        self.free_ref = (wall, tick)
