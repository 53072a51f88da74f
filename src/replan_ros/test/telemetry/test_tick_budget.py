"""TickBudget: phases add up within a tick, ticks are kept in a ring, figures per period and
for the run, the log line and the /diagnostics keys read back (the tick_budget tool's table:
replan_experiments' test_tick_table.py); PhaseTimer's laps on a clock of fixed times."""

from __future__ import annotations

import pytest

from replan_ros.telemetry.tick_budget import (
    PhaseTimer,
    TickBudget,
    parse_diagnostic_values,
    parse_log_line,
)


def test_phases_add_up_within_a_tick_and_missing_ones_count_zero():
    budget = TickBudget(['a', 'b'])
    budget.add('a', 1_000_000)
    budget.add('a', 2_000_000)            # met twice in the tick: added
    budget.end_tick()
    budget.add('b', 4_000_000)
    budget.end_tick()
    values = budget.period_values()
    assert values['tick_budget_ticks'] == 2
    assert values['tick_a_mean_ms'] == pytest.approx(1.5)
    assert values['tick_b_mean_ms'] == pytest.approx(2.0)
    assert values['tick_a_median_ms'] == pytest.approx(1.5)
    assert budget.period_values() == {}   # a period without ticks: nothing to report


def test_discarded_tick_is_not_counted():
    budget = TickBudget(['a'])
    budget.add('a', 9_000_000)
    budget.discard_tick()
    budget.add('a', 1_000_000)
    budget.end_tick()
    assert budget.summary()['phases']['a']['mean_ms'] == pytest.approx(1.0)


def test_ring_keeps_the_last_ticks_and_periods_follow_it():
    budget = TickBudget(['a'], capacity=4)
    for k in range(10):
        budget.add('a', k * 1_000_000)
        budget.end_tick()
        if k == 6:
            assert budget.period_values()['tick_budget_ticks'] == 4   # ring capacity
    assert budget.period_values()['tick_a_mean_ms'] == pytest.approx(8.0)   # ticks 7, 8, 9
    summary = budget.summary()
    assert summary['ticks'] == 4
    assert summary['phases']['a']['mean_ms'] == pytest.approx(7.5)         # ticks 6..9
    assert budget.ticks == 10


def test_log_line_and_diagnostic_values_read_back():
    budget = TickBudget(['sim_x', 'sim_y'])
    budget.add('sim_x', 250_000)
    budget.end_tick()
    parsed = parse_log_line('[INFO] [1.0] [sim]: ' + budget.log_line('sim'))
    assert parsed['node'] == 'sim' and parsed['ticks'] == 1
    assert parsed['phases']['sim_x'] == {'median_ms': 0.25, 'mean_ms': 0.25}
    assert parse_log_line('[INFO] nothing here') is None
    values = {k: str(v) for k, v in budget.period_values().items()}
    values['mode'] = 'lock_step'
    assert parse_diagnostic_values(values) == {
        'sim_x': {'median_ms': 0.25, 'mean_ms': 0.25},
        'sim_y': {'median_ms': 0.0, 'mean_ms': 0.0}}


def test_delivery_from_the_message_info():
    budget = TickBudget(('transport', 'wake'))
    budget.add_delivery({'source_timestamp': 1_000, 'received_timestamp': 1_300}, 2_000,
                        'transport', 'wake')
    budget.add_delivery({'source_timestamp': 5_000, 'received_timestamp': 1_300}, 2_000,
                        'transport', 'wake')             # out of order: not counted
    budget.add_delivery({}, 2_000, 'transport', 'wake')  # no info: not counted
    budget.end_tick()
    values = budget.period_values()
    assert values['tick_transport_mean_ms'] == pytest.approx(300e-6)   # ns -> ms
    assert values['tick_wake_mean_ms'] == pytest.approx(700e-6)


class FixedClock:
    """perf_counter_ns stand-in: each call returns the next of the given times."""

    def __init__(self, *times: int) -> None:
        self.times = list(times)

    def __call__(self) -> int:
        return self.times.pop(0)


def test_phase_timer_laps_a_counted_tick_across_callbacks():
    budget = TickBudget(['a', 'b', 'c', 'd'])
    timer = PhaseTimer(budget, clock=FixedClock(100, 300, 600, 1_000, 1_500, 2_100))
    budget.add('a', 9_000_000)            # gathered before the tick opens: forgotten
    assert timer.mark() == 100
    timer.open(7)
    assert timer.counts(7) and not timer.counts(8)
    assert timer.lap('a') == 300          # 200 ns, the mark moves on
    timer.lap('b')                        # 300 ns
    timer.unmark()                        # a wait: no phase runs
    assert timer.mark_ns is None
    timer.mark()                          # 1 000: the wait ended
    timer.add_since('d', 900)             # 600 ns, the mark stays
    timer.lap('c')                        # 2 100 - 1 000
    timer.close()
    assert timer.tick is None and budget.ticks == 1
    phases = budget.summary()['phases']
    assert [phases[name]['mean_ms'] * 1e6 for name in 'abcd'] == \
        pytest.approx([200, 300, 1_100, 600])


def test_phase_timer_drops_a_tick_not_to_be_counted():
    budget = TickBudget(['a'])
    timer = PhaseTimer(budget, clock=FixedClock(0, 10))
    timer.open(0)
    timer.mark()
    timer.lap('a')
    timer.drop()
    assert not timer.counts(0) and budget.ticks == 0
