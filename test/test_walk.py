"""End-to-end walks: the four nodes over DDS, lock-stepped, as a user runs them.

Each test runs a shipped scenario with ``scripts/scenario.sh`` (real processes, the session's
reserved ROS_DOMAIN_ID) and checks the issue's targets on ``metrics.json`` and on the bag.
The walks are run one after the other (one graph at a time on a 2-core machine).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from harness import REPO_ROOT, graph_env

from replan_core.evaluation.metrics import achieved_velocity, roll_pitch_yaw
from replan_ros.messages.odom import base_state_from_odom
from replan_ros.recording.bag_read import read_messages

SCENARIOS = REPO_ROOT / 'config' / 'scenarios'


def run_scenario(name: str, out: Path, domain: int, extra_args=()) -> dict:
    result = subprocess.run(
        [str(REPO_ROOT / 'scripts' / 'scenario.sh'), str(SCENARIOS / f'{name}.yaml'),
         '--out', str(out), *extra_args],
        env=graph_env(domain), capture_output=True, text=True, timeout=900)
    metrics_file = out / 'metrics.json'
    assert metrics_file.exists(), result.stdout + result.stderr
    metrics = json.loads(metrics_file.read_text())
    logs = '\n'.join(f'--- {p.name}\n' + p.read_text()[-3000:]
                     for p in sorted((out / 'logs').glob('*.log')))
    assert metrics['completed'], (result.stdout, logs)
    assert metrics['fell'] is False, (metrics['fall_reason'], result.stdout)
    assert not metrics['dead_nodes'], logs
    return metrics


def trajectory(out: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the robot did: the simulator's truth, not the estimate the controller used."""
    topic = '/ground_truth/odom'
    odom = sorted((base_state_from_odom(m) for _, m in
                   read_messages(out / 'bag', (topic,))[topic]), key=lambda b: b.stamp)
    times = np.array([b.stamp for b in odom])
    positions = np.array([b.position for b in odom])
    yaws = roll_pitch_yaw(np.array([b.quaternion for b in odom]))[:, 2]
    return times, positions, yaws


def segment(metrics: dict, start: float) -> dict:
    return next(s for s in metrics['velocity_tracking'] if abs(s['start_s'] - start) < 1e-6)


@pytest.fixture(scope='module')
def long_walk(ros_domain, tmp_path_factory) -> tuple[Path, dict]:
    """``long_walk``: 0.15 m/s for 40 s, run once for the two tests below (its first 22 s are
    ``forward``'s: the same inputs, and runs are bit-exact)."""
    out = tmp_path_factory.mktemp('walk') / 'long_walk'
    return out, run_scenario('long_walk', out, ros_domain)


def test_forward_crawl_keeps_the_commanded_speed(long_walk):
    """0.15 m/s: over 20 s no fall, distance within 10 % of the commanded one; the steady
    speed within 3 %."""
    out, metrics = long_walk
    times, positions, yaws = trajectory(out)
    window = (times >= 2.0) & (times <= 22.0)           # 20 s, from one s after the command
    travelled = np.linalg.norm(positions[window][-1, :2] - positions[window][0, :2])
    assert travelled == pytest.approx(0.15 * 20.0, rel=0.10), metrics['velocity_tracking']
    vx, vy, _ = segment(metrics, 1.0)['achieved']
    assert vx == pytest.approx(0.15, rel=0.10) and abs(vy) < 0.02
    # Target: the steady state (after the first cycle) within 3 % of the set-point
    # and sideways drift under 3 % of the speed, the body velocity integrated on the truth.
    steady = achieved_velocity(times, positions, yaws, 5.0, 22.0)
    assert steady[0] == pytest.approx(0.15, rel=0.03), steady
    assert abs(steady[1]) < 0.03 * 0.15, steady
    assert metrics['replans'] >= 50                     # one per touchdown (0.75 s steps)
    assert metrics['min_zmp_margin_m'] is not None and metrics['min_zmp_margin_m'] > 0.0
    # The default profile is the realistic robot: the walk above ran on estimated state.
    assert metrics['profile'] == 'realistic'
    assert metrics['cop_margin_p5_m'] is not None and metrics['touchdown_timing_error_s']


def test_estimator_drift_over_a_40_s_walk(long_walk):
    """The realistic profile's state estimator over 40 s of walking: xy drift at most 5 % of
    the distance walked, velocity RMSE at most 0.05 m/s, measured against the truth."""
    _, metrics = long_walk
    estimator = metrics['estimator']
    assert estimator['path_length_m'] > 5.0, estimator
    assert estimator['xy_drift_fraction'] <= 0.05, estimator
    assert estimator['velocity_rmse_mps'] <= 0.05, estimator
    vx, _, _ = segment(metrics, 1.0)['achieved']
    assert vx == pytest.approx(0.15, rel=0.10), metrics['velocity_tracking']


def test_lateral_walk_and_turn_within_3_percent(ros_domain, tmp_path):
    """Sideways 0.1 m/s, then turning in place at 0.2 rad/s: each steady state (the last two
    whole crawl cycles of the segment) within 3 %, no drift while turning: under
    1 cm/s over the last two whole crawl cycles (``achieved_steady``). A window that is not
    whole cycles keeps part of the sway into the support triangles (the MPC's position_sway):
    with the term on, 20-26 s read 1.2 cm/s where every whole cycle read under 0.6."""
    metrics = run_scenario('lateral_yaw', tmp_path / 'lateral_yaw', ros_domain)
    times, positions, yaws = trajectory(tmp_path / 'lateral_yaw')
    # Sideways the sway is along the motion: whole cycles only (a fixed 7-13 s window read
    # 0.0958 m/s where its whole cycles read 0.097-0.099).
    sideways = segment(metrics, 1.0)['achieved_steady']
    assert sideways[1] == pytest.approx(0.1, rel=0.03), (sideways, metrics['velocity_tracking'])
    turning = achieved_velocity(times, positions, yaws, 20.0, 26.0)
    assert turning[2] == pytest.approx(0.2, rel=0.03), (turning, metrics['velocity_tracking'])
    steady = segment(metrics, 13.0)['achieved_steady']
    assert steady[2] == pytest.approx(0.2, rel=0.03), metrics['velocity_tracking']
    assert np.hypot(steady[0], steady[1]) < 0.01, metrics['velocity_tracking']


def test_velocity_step_is_followed_within_two_steps(ros_domain, tmp_path):
    """0.1 -> 0.2 m/s at t = 10 s: two steps (1.5 s) later the walk is at the new speed."""
    metrics = run_scenario('velocity_step', tmp_path / 'velocity_step', ros_domain)
    times, positions, yaws = trajectory(tmp_path / 'velocity_step')
    step_period = 0.75
    before = achieved_velocity(times, positions, yaws, 10.0 - 3.0, 10.0)
    after = achieved_velocity(times, positions, yaws, 10.0 + 2 * step_period,
                              10.0 + 2 * step_period + 3.0)        # one crawl cycle
    assert before[0] == pytest.approx(0.1, rel=0.15), (before, after)
    assert after[0] == pytest.approx(0.2, rel=0.15), (before, after)
    assert metrics['mpc_solves'] >= metrics['replans'] - 1


def test_demo_script_walks_and_says_where_the_results_are(ros_domain, tmp_path):
    """The README's first command, headless: a crawl forward, sideways and turning, a trot,
    stop; summary printed."""
    out = tmp_path / 'demo'
    result = subprocess.run([str(REPO_ROOT / 'scripts' / 'demo.sh'), str(out)],
                            env=graph_env(ros_domain), capture_output=True, text=True,
                            timeout=900)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'no fall' in result.stdout and str(out / 'bag') in result.stdout, result.stdout
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics['completed'] and not metrics['fell']
    assert {Path(p).name for p in metrics['plots']} == {
        'top_view.png', 'velocity.png', 'trunk.png', 'solve_times.png', 'estimator.png',
        'cop_margin.png', 'gait.png', 'forces.png', 'torques.png'}
    assert list((out / 'bag').glob('*.mcap'))
    final_segment = metrics['velocity_tracking'][-1]
    assert final_segment['commanded'] == [0.0, 0.0, 0.0]
    trot = segment(metrics, 24.0)                       # the switch to the trot, 0.37 m/s
    assert trot['commanded'][0] == 0.37
    assert trot['achieved'][0] == pytest.approx(0.37, rel=0.15), metrics['velocity_tracking']
