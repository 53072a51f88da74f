"""The tick_budget tool's table: the shares of a tick's phases add up."""

from __future__ import annotations

import math

import pytest

from replan_experiments.benchmarks.tick_table import (
    OVERLAPPED,
    OVERLAPPED_PREFIX,
    ROUND_TRIP,
    SIM_OWN,
    table,
)


def test_table_shares_add_up_to_the_tick():
    def stats(mean):
        return {'median_ms': mean, 'mean_ms': mean}
    sim = {'ticks': 100, 'phases': {key: stats(0.1) for key, _ in SIM_OWN + OVERLAPPED
                                    if key.startswith('sim_')}}
    sim['phases'].update({'sim_wait': stats(2.0), 'sim_tick': stats(3.0),
                          'sim_transport_cmd': stats(0.1), 'sim_wake': stats(0.1)})
    wbc = {'ticks': 100, 'phases': {key: stats(0.1) for key, _ in ROUND_TRIP + OVERLAPPED
                                    if key.startswith('wbc_')}}
    rows, totals = table(sim, wbc)
    top_level = [share for label, _, _, share in rows
                 if not label.startswith('  ') and share == share]     # not the headings
    assert math.fsum(top_level) == pytest.approx(1.0)
    overlapped = [mean for label, _, mean, _ in rows if label.startswith(OVERLAPPED_PREFIX)]
    assert math.fsum(overlapped) == pytest.approx(0.1 * len(OVERLAPPED))
    assert totals['overlapped_ms'] == pytest.approx(0.1 * len(OVERLAPPED))
    inside_wait = [mean for label, _, mean, _ in rows
                   if label.startswith('  ') and not label.startswith(OVERLAPPED_PREFIX)]
    assert math.fsum(inside_wait) == pytest.approx(totals['round_trip_ms'])
    assert totals['tick_ms_mean'] == 3.0
