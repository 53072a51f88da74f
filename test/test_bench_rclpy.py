"""The rclpy benchmarks run over real DDS in processes of their own and print every figure
(docs/performance.md; no figure is asserted against a time)."""

from __future__ import annotations

import json
import subprocess
import sys

from harness import graph_env


def test_bench_rclpy_prints_every_round_trip_and_each_side_cpu(ros_domain):
    result = subprocess.run(
        [sys.executable, '-m', 'replan_experiments.benchmarks.bench_rclpy', '--rounds', '200'],
        env=graph_env(ros_domain), capture_output=True, text=True, timeout=180)
    assert result.returncode == 0, result.stderr[-2000:]
    figures = json.loads(result.stdout.strip().splitlines()[-1])
    round_trips = ('round_trip_ms_no_bystander', 'lean_round_trip_ms',
                   'round_trip_ms_2_spun_bystanders', 'round_trip_ms_2_on_demand_bystanders')
    cpus = ('round_trip_cpu_ms_sim_side', 'round_trip_cpu_ms_controller_side',
            'lean_round_trip_cpu_ms_sim_side', 'lean_round_trip_cpu_ms_controller_side')
    # CPU time comes in clock ticks (10 ms): 200 rounds take each side several of them.
    assert all(figures[key] > 0.0 for key in round_trips + cpus), figures
    assert figures['executor_us_per_message_no_event_handlers'] > 0.0


def test_a_late_plan_reader_always_ends_on_the_newest_plan(ros_domain):
    """The late-reader benchmark (docs/recording.md, "No loss"): whatever it took of a plan
    writer's history, the graph's depth-1 reader took it in order and ended on the newest;
    the reader that keeps all got all (checked inside, a RuntimeError otherwise)."""
    result = subprocess.run(
        [sys.executable, '-m', 'replan_experiments.benchmarks.late_reader', '--trials', '5'],
        env=graph_env(ros_domain), capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    figures = json.loads(result.stdout.strip().splitlines()[-1])
    assert sum(figures['trials_by_plans_taken'].values()) == 5
    assert figures['every_trial_in_order_ending_on_the_newest'] is True
