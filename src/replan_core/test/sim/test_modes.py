"""The simulator's mode machine (modes.SimModes) with fixed sim and wall times: the first
command, lock-step, stale stamps, stop_time, the dead controller's damping and its return,
free-run and its catch-up."""

from replan_core.sim.modes import (
    ALIVE,
    APPLY,
    DAMPING,
    FREE_RUN,
    IGNORE,
    LOCK_STEP,
    MAX_CATCH_UP_TICKS,
    RESYNC,
    STEP,
    WAITING,
    ModeChange,
    SimModes,
)

TICK = 4_000_000       # ns


def lock_step(stop_ns=None) -> SimModes:
    return SimModes(lock_step=True, command_timeout=3.0, stop_ns=stop_ns, wall=100.0)


def test_nothing_moves_before_the_first_command_then_one_tick_per_command():
    modes = lock_step()
    assert modes.mode == WAITING and modes.waits_for_command and not modes.free_running
    assert modes.watchdog(0, 200.0, 0, 0.0) is None          # waiting never damps
    action, change = modes.command(0, 0, 100.5, 0, 0.0)
    assert action == STEP and change == ModeChange(WAITING, LOCK_STEP)
    assert modes.last_command_wall == 100.5
    assert modes.command(TICK, TICK, 100.6, 1, 0.004) == (STEP, None)
    # A stamp that is not the current tick: ignored (a duplicate, or one from the future).
    assert modes.command(0, 2 * TICK, 100.7, 2, 0.008) == (IGNORE, None)
    assert modes.command(3 * TICK, 2 * TICK, 100.7, 2, 0.008) == (IGNORE, None)
    assert modes.last_command_wall == 100.6


def test_a_silent_controller_damps_and_its_answer_to_an_older_tick_resyncs():
    modes = lock_step()
    modes.command(0, 0, 100.0, 0, 0.0)
    assert modes.watchdog(0, 103.0, 0, 0.0) is None              # 3.0 s: not yet
    change = modes.watchdog(0, 103.5, 0, 0.0)
    assert change == ModeChange(LOCK_STEP, DAMPING) and modes.free_running
    assert modes.free_ref == (103.5, 0)
    # Real time: 0.125 wall s at a real-time factor of 1 is 31.25 ticks of 4 ms.
    assert modes.free_run_ticks(0, 103.625, 0, 0.004, 1.0) == 31
    assert modes.damping_since == 0.0
    # The controller answers the tick it last saw: back to lock-step at the current tick.
    action, change = modes.command(0, 30 * TICK, 103.2, 30, 0.12)
    assert action == RESYNC and change == ModeChange(DAMPING, LOCK_STEP)
    assert modes.waits_for_command and modes.free_run_ticks(0, 104.0, 30, 0.004, 1.0) == 0
    assert modes.command(30 * TICK, 30 * TICK, 103.3, 30, 0.12) == (STEP, None)


def test_damping_records_when_it_began():
    modes = lock_step()
    modes.command(0, 0, 100.0, 0, 0.0)
    modes.command(TICK, TICK, 100.0, 250, 1.0)
    modes.watchdog(TICK, 104.0, 250, 1.0)
    assert modes.mode == DAMPING and modes.damping_since == 1.0
    # A newer stamp than the current tick does not bring it back.
    assert modes.command(300 * TICK, 260 * TICK, 104.1, 260, 1.04) == (IGNORE, None)
    assert modes.mode == DAMPING


def test_at_stop_time_it_holds_and_never_damps():
    modes = lock_step(stop_ns=2 * TICK)
    modes.command(0, 0, 100.0, 0, 0.0)
    assert modes.command(TICK, TICK, 100.1, 1, 0.004) == (STEP, None)
    assert not modes.holding(TICK) and modes.holding(2 * TICK) and modes.holding(3 * TICK)
    assert modes.waits_for_command                               # held, not answered yet
    assert modes.command(2 * TICK, 2 * TICK, 100.2, 2, 0.008) == (ALIVE, None)
    assert modes.last_command_wall == 100.2                      # alive
    # Answered: nothing to heal, so no republish (the controller would answer it again).
    assert not modes.waits_for_command
    assert modes.watchdog(2 * TICK, 200.0, 2, 0.008) is None      # held: no damping
    assert modes.mode == LOCK_STEP


def test_free_run_applies_every_command_and_catches_up_within_a_bound():
    modes = SimModes(lock_step=False, command_timeout=3.0, stop_ns=None, wall=0.0)
    assert modes.free_run_ticks(0, 5.0, 0, 0.004, 1.0) == 0       # not started
    action, change = modes.command(123, 0, 10.0, 0, 0.0)          # any stamp
    assert action == APPLY and change == ModeChange(WAITING, FREE_RUN)
    assert modes.command(456, 0, 10.01, 0, 0.0) == (APPLY, None)
    assert modes.free_run_ticks(0, 10.022, 0, 0.004, 1.0) == 5
    assert modes.free_run_ticks(0, 10.022, 0, 0.004, 2.0) == 11    # twice real time
    assert modes.free_run_ticks(0, 10.022, 7, 0.004, 1.0) == 0     # ahead: none
    behind = modes.free_run_ticks(0, 11.002, 5, 0.004, 1.0)
    assert behind == 245 > MAX_CATCH_UP_TICKS
    modes.slip(11.0, 5 + MAX_CATCH_UP_TICKS)
    assert modes.free_run_ticks(0, 11.006, 30, 0.004, 1.0) == 1
    # Silent for command_timeout: damping; a command then brings free-run back.
    assert modes.watchdog(0, 13.02, 30, 0.12) == ModeChange(FREE_RUN, DAMPING)
    assert modes.command(0, 0, 13.1, 31, 0.124) == (APPLY, ModeChange(DAMPING, FREE_RUN))


def test_free_run_stops_at_stop_time():
    modes = SimModes(lock_step=False, command_timeout=3.0, stop_ns=TICK, wall=0.0)
    modes.command(0, 0, 0.0, 0, 0.0)
    assert modes.free_run_ticks(0, 1.002, 0, 0.004, 1.0) == 250
    assert modes.free_run_ticks(TICK, 1.0, 1, 0.004, 1.0) == 0
    # A command after stop_time does not enter free-run again.
    modes.set_mode(WAITING, 1.0, 1, 0.004)
    assert modes.command(0, TICK, 1.1, 1, 0.004) == (APPLY, None)
    assert modes.mode == WAITING
