"""A robot that falls (config/scenarios/knock_over.yaml: a push rolls it over while walking):
the controller detects the fall from the trunk tilt, reports it (log, /diagnostics ERROR) and
from then on only damps the joints, so the legs come to rest instead of swinging at their
torque limits. Real nodes over DDS, checked on the bag."""

from __future__ import annotations

import json
import re
import subprocess

import numpy as np
from harness import REPO_ROOT, graph_env

from replan_ros.messages.stamps import stamp_to_sec
from replan_ros.recording.bag_read import read_messages
from replan_ros.telemetry import diagnostics

SCENARIO = REPO_ROOT / 'config' / 'scenarios' / 'knock_over.yaml'


def test_a_fallen_robot_is_detected_reported_and_its_joints_damped(ros_domain, tmp_path):
    out = tmp_path / 'knock_over'
    result = subprocess.run([str(REPO_ROOT / 'scripts' / 'scenario.sh'), str(SCENARIO),
                             '--out', str(out), '--quiet'],
                            env=graph_env(ros_domain), capture_output=True, text=True,
                            timeout=600)
    metrics = json.loads((out / 'metrics.json').read_text())
    wbc_log = (out / 'logs' / 'wbc.log').read_text()
    assert metrics['completed'] and metrics['fell'], result.stdout + result.stderr
    assert not metrics['dead_nodes'], wbc_log[-3000:]
    found = re.search(r'fallen at t = ([0-9.]+) s: the trunk is tilted (\d+) deg', wbc_log)
    assert found, wbc_log[-3000:]
    fall_time, tilt_deg = float(found.group(1)), int(found.group(2))
    assert 3.0 < fall_time < 5.0 and tilt_deg >= 57
    assert wbc_log.count('fallen at t =') == 1            # latched: said once

    topics = ('/joint_torque_cmd', '/joint_states', '/diagnostics')
    messages = read_messages(out / 'bag', topics)
    statuses = [(stamp_to_sec(array.header.stamp), status) for _, array in
                messages['/diagnostics'] for status in array.status if status.name == 'wbc']
    fallen = [(t, s) for t, s in statuses if diagnostics.values_of(s).get('mode') == 'fallen']
    assert fallen and all(s.level == diagnostics.ERROR for _, s in fallen)
    assert float(diagnostics.values_of(fallen[0][1])['fallen_at_s']) == fall_time
    assert all(t >= fall_time for t, _ in fallen)

    # The commands after the fall: damping only (-fall_damping qd, 2 N m s/rad), far from the
    # 150 N m limits the legs hit while the controller still tracked its plans.
    commands = [(stamp_to_sec(m.header.stamp), np.array(m.effort))
                for _, m in messages['/joint_torque_cmd']]
    before = max(np.abs(e).max() for t, e in commands if 3.0 <= t < fall_time)
    after = [np.abs(e).max() for t, e in commands if t >= fall_time + 0.5]
    assert before > 100.0                              # it fought the push at its limits
    assert len(after) > 200 and max(after) < 30.0, max(after)
    # And the legs come to rest.
    speeds = [np.abs(np.array(m.velocity)).max() for _, m in messages['/joint_states']
              if stamp_to_sec(m.header.stamp) >= metrics['sim_time_s'] - 0.5]
    assert speeds and np.median(speeds) < 1.0, np.median(speeds)
