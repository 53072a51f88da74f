"""The executor probe (replan_experiments/benchmarks/probe_executor.py) in real child processes
over DDS: rclpy's SingleThreadedExecutor runs every case under both spin modes and stops on
SIGINT, and the probe reports the EventsExecutor's stall instead of hanging. The last test pins
that finding to the rclpy of requirements.txt: when it fails after an upgrade, the
EventsExecutor is worth another trial (docs/ARCHITECTURE.md, "Per-tick budget")."""

from __future__ import annotations

import os

from replan_experiments.benchmarks import probe_executor


def test_single_threaded_executor_runs_every_case(ros_domain):
    assert os.environ['ROS_DOMAIN_ID'] == str(ros_domain)
    results = probe_executor.probe(('single',), duration=1.0)
    assert [(r['mode'], r['case']) for r in results] == [
        (mode, case) for mode in probe_executor.MODES for case in probe_executor.CASES]
    for result in results:
        assert result['verdict'] == 'ok', result
        assert result['calls'] >= 0.5 * result['expected'] > 0, result


def test_verdict_names_what_failed():
    base = {'calls': 40, 'expected': 50, 'stopped_by_sigint': True, 'error': ''}
    assert probe_executor.verdict(base) == 'ok'
    assert probe_executor.verdict({**base, 'calls': 3}) == '3 of 50 callbacks'
    assert probe_executor.verdict({**base, 'calls': 0, 'stopped_by_sigint': False}) == (
        '0 of 50 callbacks; SIGINT did not end the spin')
    assert probe_executor.verdict({**base, 'error': 'SystemError: x'}) == 'raised SystemError: x'


def test_events_executor_stalls_under_rclpy_spin_in_this_rclpy(ros_domain):
    topic = f'probe_executor_test_{os.getpid()}'
    stalled = probe_executor.run_case('events', 'spin', 'timer', topic, duration=1.0)
    assert probe_executor.verdict(stalled) == (
        f"0 of {stalled['expected']} callbacks; SIGINT did not end the spin"), (
        'rclpy.spin() with the EventsExecutor now runs timers and stops on SIGINT: '
        f'try it again in the sim and the controller ({stalled})')
    working = probe_executor.run_case('events', 'spin_once_timeout', 'timer', topic,
                                      duration=1.0)
    assert probe_executor.verdict(working) == 'ok', working
