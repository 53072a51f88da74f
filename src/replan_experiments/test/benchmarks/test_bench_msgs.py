"""The message benchmark runs and times every operation (no figure is asserted)."""

from __future__ import annotations


def test_bench_msgs_times_every_operation(capsys):
    from replan_experiments.benchmarks import bench_msgs

    results = bench_msgs.measure(repeats=3)
    assert len(results) == 6 + 20 + 2      # plans; ticks: 10 operations, two ways each; view
    assert all(0.0 < median <= p90 for median, p90 in results.values())
    assert bench_msgs.main(['--repeats', '2', '--json']) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith('operation') and len(out) == 2 + len(results)
