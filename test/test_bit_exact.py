"""Bit-exact runs: one scenario run twice gives the same bytes on every topic of the
run's state and decisions, and both runs end at the scenario's duration, in both profiles.
``scripts/scenario.sh --repeat N`` is the check a user runs (docs/ARCHITECTURE.md, "Bit-exact
runs"); the core's share (no result depends on where the heap put an array) is tested without
processes in src/replan_core/test/common/test_proxqp.py."""

from __future__ import annotations

import re
import subprocess

import pytest
from harness import REPO_ROOT, graph_env

# A stand, a walk and a push: lift-offs, haptic touchdowns, re-plans, a wrench.
SCENARIO = """name: bit_exact
duration: 4.0
events:
  - {t: 0.5, cmd_vel: [0.15, 0.05, 0.1]}
  - {t: 2.5, push: {force: [0.0, 120.0, 0.0], duration: 0.2}}
"""


@pytest.mark.parametrize('profile', ['realistic', 'ideal'])
def test_two_runs_of_a_scenario_are_bit_identical(profile, ros_domain, tmp_path):
    scenario = tmp_path / 'bit_exact.yaml'
    scenario.write_text(SCENARIO)
    done = subprocess.run(
        [str(REPO_ROOT / 'scripts' / 'scenario.sh'), str(scenario), '--profile', profile,
         '--repeat', '2', '--no-plots', '--quiet', '--out', str(tmp_path / 'runs')],
        env=graph_env(ros_domain), capture_output=True, text=True, timeout=600)
    out = done.stdout + done.stderr
    assert done.returncode == 0, out
    assert re.search(r'\[repeat\] bit_exact: 2 runs, largest base position difference 0 m; '
                     r'every run bit-identical to run 1', out), out
    line = next(x for x in out.splitlines() if x.startswith('[repeat] run 2 against run 1'))
    assert '0 missing' in line and 'both end at t = 4.000 s' in line, line
    # Every per-tick and per-re-plan topic took part (a topic missing from both bags would
    # pass the comparison unnoticed).
    topics = int(re.search(r'messages of (\d+) topics', line).group(1))
    assert topics >= 13, line
