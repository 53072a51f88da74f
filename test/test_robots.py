"""Any quadruped: another robot walks with the same re-planner, from its robot file
alone (config/robots/<name>.yaml and the scaling rules; docs/robot_files.md).

Each test runs the robot's forward scenario (`config/scenarios/<name>_forward.yaml`: its
`robot:` key, a robot-appropriate set-point, the realistic profile) end to end, as
test_walk.py runs HyQ's, and checks on the simulator's truth that it did not fall and walked
within 5 % of its set-point (runs are bit-exact, so a run gives the same figures every
time; each robot's measured walks are on docs/robots.md).
"""

from __future__ import annotations

import pytest
from test_walk import run_scenario, segment

# robot -> (set-point m/s, relative tolerance on the achieved forward speed: the target's 5 %).
WALKS = {'anymal_c': (0.10, 0.05), 'b1': (0.10, 0.05), 'go1': (0.05, 0.05),
         'anymal_b': (0.10, 0.05), 'a1': (0.05, 0.05),
         'go2': (0.05, 0.05)}


@pytest.mark.parametrize('robot', sorted(WALKS))
def test_another_robot_walks_forward(robot, ros_domain, tmp_path):
    setpoint, tolerance = WALKS[robot]
    metrics = run_scenario(f'{robot}_forward', tmp_path / robot, ros_domain)
    assert metrics['robot'] == robot and metrics['profile'] == 'realistic'
    vx, vy, _ = segment(metrics, 1.0)['achieved']
    assert vx == pytest.approx(setpoint, rel=tolerance), metrics['velocity_tracking']
    assert abs(vy) < 0.3 * setpoint, metrics['velocity_tracking']
