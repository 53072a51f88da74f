"""Scenario files: every shipped one parses; broken ones get a message that says where."""

from pathlib import Path

import pytest

from replan_ros.experiments.scenario import (
    ScenarioError,
    params_document,
    parse_scenario,
    summary,
)

SCENARIOS = sorted((Path(__file__).resolve().parents[4] / 'config' / 'scenarios').glob('*.yaml'))


@pytest.mark.parametrize('path', SCENARIOS, ids=lambda p: p.stem)
def test_shipped_scenarios_parse(path):
    scenario = parse_scenario(path.read_text(), str(path))
    assert scenario.duration > 0
    assert all(0 <= t <= scenario.duration for t, _ in scenario.cmd_vel_events)


def test_demo_walks_forward_sideways_turns_and_stops():
    demo = next(p for p in SCENARIOS if p.stem == 'demo')
    commands = [c for _, c in parse_scenario(demo.read_text()).cmd_vel_events]
    assert any(c[0] > 0 for c in commands) and any(c[1] != 0 for c in commands)
    assert any(c[2] != 0 for c in commands) and commands[-1] == (0.0, 0.0, 0.0)


def test_params_document_carries_terrain_and_overrides():
    scenario = parse_scenario('duration: 5\nterrain: {type: step_up, height: 0.05}\n'
                              'params: {gait: {haptic: false}}\n')
    doc = params_document(scenario)
    assert doc['gait']['ros__parameters'] == {'haptic': False}
    assert doc['sim']['ros__parameters'] == {'terrain': 'step_up', 'terrain_height': 0.05}


def test_a_scenario_names_its_robot_default_hyq():
    assert parse_scenario('duration: 5\n').robot == 'hyq'
    assert parse_scenario('duration: 5\nrobot: go1\n').robot == 'go1'


@pytest.mark.parametrize('text, message', [
    ('duration: [1, 2', 'not valid YAML'),
    ('duration: 5\nrobot: [go1]\n', 'robot must be a robot name or a robot file'),
    ('- 1\n- 2\n', 'top level must be a mapping'),
    ('duration: 5\nspeed: 3\n', 'unknown keys'),
    ('duration: -1\n', 'duration'),
    ('duration: 5\nevents: [{t: 1, cmd_vel: [.nan, 0, 0]}]\n', 'non-finite'),
    ('duration: 5\nevents: [{t: 1, cmd_vel: [1, 0]}]\n', 'list of 3 numbers'),
    ('duration: 5\nevents: [{t: 9, cmd_vel: [0, 0, 0]}]\n', 'within [0, duration]'),
    ('duration: 5\nevents: [{t: 1, push: {force: [0, 1, 0]}}]\n', 'force and duration'),
    ('duration: 5\nevents: [{t: 1, jump: 1}]\n', 'either cmd_vel or push'),
    ('duration: 5\nparams: {planner: {a: 1}}\n', 'unknown nodes'),
])
def test_broken_scenarios_are_rejected_with_a_reason(text, message):
    with pytest.raises(ScenarioError, match=message.replace('[', r'\[')):
        parse_scenario(text, 'broken.yaml')


def test_the_summary_of_a_run_that_did_not_run_says_it_failed():
    """A recorder that refused its robot stops the graph before the sim moves: the summary
    says the run failed and why, not "no fall"."""
    metrics = {'scenario': 'forward', 'launch_exit_code': 2, 'dead_nodes': ['recorder'],
               'completed': False, 'fell': None,
               'error': 'the bag holds no odometry or clock: the graph did not run'}
    text = summary(metrics, Path('runs/x'))
    assert text == ('[scenario] forward: FAILED: the bag holds no odometry or clock: the graph '
                    "did not run (launcher exit code 2; nodes that died: ['recorder']); logs: "
                    'runs/x/logs')
