"""Any quadruped (issue 30): another robot walks with the same re-planner, from its robot file
alone (config/robots/<name>.yaml and the scaling rules; docs/robot_files.md).

Each test runs the robot's forward scenario (`config/scenarios/<name>_forward.yaml`: its
`robot:` key, a robot-appropriate set-point, the realistic profile) end to end, as
test_walk.py runs HyQ's, and checks on the simulator's truth that it did not fall and walked
near its set-point. The tolerance is what the robot holds today (docs/robot_files.md, "State
today"), not yet the issue's 5 %.
"""

from __future__ import annotations

import pytest
from test_walk import run_scenario, segment

# robot -> (set-point m/s, relative tolerance on the achieved forward speed). ANYmal C is not
# here: it walks in the ideal world but falls on the realistic profile (docs/robot_files.md).
WALKS = {'go1': (0.05, 0.10), 'b1': (0.10, 0.10)}


@pytest.mark.parametrize('robot', sorted(WALKS))
def test_another_robot_walks_forward(robot, ros_domain, tmp_path):
    setpoint, tolerance = WALKS[robot]
    metrics = run_scenario(f'{robot}_forward', tmp_path / robot, ros_domain)
    assert metrics['robot'] == robot and metrics['profile'] == 'realistic'
    vx, vy, _ = segment(metrics, 1.0)['achieved']
    assert vx == pytest.approx(setpoint, rel=tolerance), metrics['velocity_tracking']
    assert abs(vy) < 0.3 * setpoint, metrics['velocity_tracking']
