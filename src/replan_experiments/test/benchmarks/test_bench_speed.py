"""bench_speed's verdicts from given figures (no graph is run here) and its reading of the mpc
node's shutdown line."""

from __future__ import annotations

import json

import pytest

from replan_experiments.benchmarks.bench_speed import (
    SETUPS,
    mpc_solve_times,
    render_page,
    summarise,
)
from replan_ros.nodes.mpc_node import SOLVE_TIMES_LOG


def _round(rtf: dict, physics: dict, mpc_median: float = 1.2, mpc_p99: float = 2.0) -> dict:
    return {'physics': physics,
            'graph': {s: {'real_time_factor': rtf[s], 'exit_code': 0,
                          'mpc': {'wall_median_ms': mpc_median, 'wall_p99_ms': mpc_p99,
                                  'cpu_median_ms': 1.0}} for s in SETUPS}}


def _verdicts(rows) -> dict[str, str]:
    return {target: verdict for target, _, verdict in rows}


def test_every_target_met():
    rtf = {'ideal': 2.0, 'realistic': 1.9, 'realistic+recorder': 1.8,
           'realistic+recorder+live': 1.7}
    rounds = [_round(rtf, {'ideal': 9.0, 'realistic': 8.0})] * 3
    idle = {'idle_s': 0.3, 'median_ms': 2.5, 'p99_ms': 4.0, 'cpu_median_ms': 2.4}
    rows, summary = summarise(rounds, {'median_ms': 1.0, 'p99_ms': 2.0}, idle)
    verdicts = _verdicts(rows)
    assert set(verdicts.values()) == {'met', 'n/a'}
    assert [t for t, v in verdicts.items() if v == 'n/a'] == [
        'live view + viewer cost (no target)',
        'MPC alone, 0.3 s idle before each re-plan (no target)']
    assert summary['recorder cost'] == pytest.approx(1.0 - 1.8 / 1.9, abs=1e-3)
    assert summary['ideal_over_physics'] == pytest.approx(2.0 / 9.0, abs=1e-3)


def test_misses_are_reported_per_target():
    rtf = {'ideal': 1.6, 'realistic': 1.4, 'realistic+recorder': 1.0,
           'realistic+recorder+live': 0.9}
    rounds = [_round(rtf, {'ideal': 13.0, 'realistic': 10.0}, mpc_median=2.0, mpc_p99=3.5)]
    verdicts = _verdicts(summarise(rounds, {'median_ms': 1.0, 'p99_ms': 2.0})[0])
    assert verdicts['real-time factor >= 1.5: ideal'] == 'met'
    assert verdicts['real-time factor >= 1.5: realistic'] == 'NOT met'
    assert verdicts['recorder costs <= 10% of the RTF'] == 'NOT met'          # 29 %
    assert all(v == 'NOT met' for t, v in verdicts.items() if t.startswith('graph >='))
    assert all(v == 'NOT met' for t, v in verdicts.items() if t.startswith('MPC in the graph'))
    assert verdicts['MPC alone: median <= 2.0 ms, p99 <= 5.0 ms'] == 'met'


def test_mpc_shutdown_line_read_back(tmp_path):
    summary = {'replans': 12, 'wall_median_ms': 1.5, 'wall_p99_ms': 4.0,
               'cpu_median_ms': 1.1, 'cpu_p99_ms': 2.0}
    log = tmp_path / 'mpc.log'
    log.write_text('[INFO] [1.0] [mpc]: mpc ready\n'
                   f'[INFO] [2.0] [mpc]: {SOLVE_TIMES_LOG} {json.dumps(summary)}\n')
    assert mpc_solve_times(log) == summary
    assert mpc_solve_times(tmp_path / 'missing.log') == {}


def test_replan_path_rows_for_the_recorded_setups():
    rtf = {'ideal': 2.0, 'realistic': 1.9, 'realistic+recorder': 1.8,
           'realistic+recorder+live': 1.7}
    rounds = []
    for median, peak in ((10.0, 20.0), (12.0, 30.0), (11.0, 25.0)):
        r = _round(rtf, {'ideal': 9.0, 'realistic': 8.0})
        r['graph']['realistic+recorder']['replan_wall'] = {'median': median, 'max': peak}
        r['graph']['realistic+recorder+live']['replan_wall'] = None      # no bag read
        rounds.append(r)
    rows, summary = summarise(rounds, {'median_ms': 1.0, 'p99_ms': 2.0})
    row = [(f, v) for t, f, v in rows if t.startswith('re-plan path')]
    assert row == [('median 11.00 (10.00-12.00), max 25.00 (20.00-30.00) ms', 'n/a')]
    assert summary['replan_wall_realistic+recorder'] == {'median_ms': 11.0, 'max_ms': 25.0}
    assert 'replan_wall_realistic+recorder+live' not in summary


def test_cpu_rows_per_setup_with_the_nodes_it_ran():
    rtf = {'ideal': 2.0, 'realistic': 1.9, 'realistic+recorder': 1.8,
           'realistic+recorder+live': 1.7}
    rounds = []
    for scale in (1.0, 1.2, 0.9):
        r = _round(rtf, {'ideal': 9.0, 'realistic': 8.0})
        for setup in SETUPS:
            cpu = {'sim': 250.0 * scale, 'wbc': 240.0 * scale, 'gait': 50.0, 'mpc': 40.0}
            if 'recorder' in setup:
                cpu['recorder'] = 100.0 * scale
            if 'live' in setup:
                cpu['live_view'] = 80.0
            r['graph'][setup]['cpu_ms_per_sim_s'] = cpu
        rounds.append(r)
    rows, summary = summarise(rounds, {'median_ms': 1.0, 'p99_ms': 2.0})
    cpu_rows = {t: f for t, f, v in rows if t.startswith('CPU time per sim s')}
    assert cpu_rows['CPU time per sim s (no target): realistic'] == (
        'all 580.00 (531.00-678.00) ms: sim 250, wbc 240, gait 50, mpc 40')
    assert cpu_rows['CPU time per sim s (no target): realistic+recorder+live'].endswith(
        'recorder 100, live_view 80')
    assert summary['cpu_ms_per_sim_s_realistic+recorder']['recorder'] == 100.0
    # A run without the figures (an older result file): no row, no error.
    assert not any(t.startswith('CPU') for t, _, _ in summarise(
        [_round(rtf, {'ideal': 9.0, 'realistic': 8.0})], {'median_ms': 1.0, 'p99_ms': 2.0})[0])


def test_page_of_a_run_holds_every_round_and_the_verdicts():
    rtf = {'ideal': 2.5, 'realistic': 2.0, 'realistic+recorder': 1.8,
           'realistic+recorder+live': 1.6}
    rounds = []
    for k, scale in enumerate((1.0, 0.9)):
        r = _round({s: v * scale for s, v in rtf.items()},
                   {'ideal': 15.0 + k, 'realistic': 12.0 + k})
        for setup in SETUPS:
            r['graph'][setup]['tick_ms_mean'] = 4.0 / r['graph'][setup]['real_time_factor']
            r['graph'][setup]['cpu_ms_per_sim_s'] = {'sim': 200.0, 'wbc': 250.0 * scale}
        rounds.append(r)
    rounds[1]['graph']['realistic+recorder+live']['exit_code'] = 1
    mpc_bench = {'median_ms': 0.9, 'p99_ms': 1.5, 'cpu_median_ms': 0.88}
    idle = {'idle_s': 0.3, 'median_ms': 2.0, 'p99_ms': 3.0, 'cpu_median_ms': 1.9}
    rows, summary = summarise(rounds, mpc_bench, idle)
    meta = {'command': 'scripts/bench_speed.sh --runs 2 --page docs/speed.md',
            'date': '2026-11-25 08:00 UTC', 'machine': '2 cores, test CPU',
            'revision': 'abc1234', 'duration': 22.0, 'robot': 'go1'}
    page = render_page(rows, summary, rounds, mpc_bench, idle, meta)
    lines = page.splitlines()
    assert lines[0] == '# Speed of the lock-step graph'
    assert lines[2].startswith('Robot **go1**. Generated by ')          # the robot it ran
    assert "then the MPC benchmark on go1's crawl" in page
    assert 'scripts/bench_speed.sh --runs 2 --page docs/speed.md' in page
    assert 'physics alone ran at 12.0 to 16.0 x real time' in page
    # Every target row of the printed table, with its verdict.
    for target, figure, verdict in rows:
        assert f'| {target} | {figure} | {verdict} |' in lines
    # One line per round: both physics figures, each set-up's RTF and tick, the recorder cost.
    assert '| 1 | 15.0 / 12.0 | 2.50 (1.60) | 2.00 (2.00) | 1.80 (2.22) | 1.60 (2.50) | 10% |' \
        in lines
    assert any(line.startswith('| 2 | 16.0 / 13.0 |') and '1.44 (2.78) exit 1' in line
               for line in lines)
    assert '| realistic | 200 | 238 | 438 |' in lines          # median of 250 and 225
    assert '| benchmark, back to back | 0.90 | 1.50 | 0.88 |' in lines
    assert '| benchmark, 0.3 s idle before each re-plan | 2.00 | 3.00 | 1.90 |' in lines
    assert '| graph: ideal | 1.20 | 2.00 | 1.00 |' in lines
