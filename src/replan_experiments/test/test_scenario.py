"""Scenario files: every shipped one parses; broken ones get a message that says where."""

from pathlib import Path

import pytest

from replan_experiments.scenario import (
    ScenarioError,
    check_scenario,
    params_document,
    parse_scenario,
    summary,
)
from replan_ros.params import ConfigError

CONFIG = Path(__file__).resolve().parents[3] / 'config'
SCENARIOS = sorted((CONFIG / 'scenarios').glob('*.yaml'))


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
    ('duration: 5\nevents: [{t: 1, jump: 1}]\n', 'one of cmd_vel, push or gait'),
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


def test_the_summary_of_a_run_whose_node_died_shows_the_missing_figures_as_dashes():
    """A node killed mid-run: the run measured what its bag holds, and the figures it could
    not give are None; the summary shows them as '-' and names the dead node."""
    metrics = {'scenario': 'forward', 'fell': False, 'sim_time_s': None, 'wall_time_s': 12.0,
               'real_time_factor': None, 'distance_m': None, 'replans': 3,
               'estimator': {'xy_error_end_m': None, 'velocity_rmse_mps': 0.01},
               'dead_nodes': ['mpc']}
    text = summary(metrics, Path('runs/x'))
    assert text.startswith('[scenario] forward: no fall, - s sim in 12.0 s wall (real-time '
                           'factor -)\n  distance - m, re-plans 3,')
    assert 'xy error at the end - m, velocity RMSE 0.010 m/s' in text
    assert "  nodes that died: ['mpc']" in text


def test_the_summary_names_what_an_incomplete_bag_misses():
    metrics = {'scenario': 'forward', 'fell': False, 'bag_complete': False,
               'bag_gaps': 'incomplete: /odom misses 3 ticks'}
    assert '\n  bag incomplete: /odom misses 3 ticks\n' in summary(metrics, Path('runs/x'))
    metrics['bag_complete'] = True
    assert 'incomplete' not in summary(metrics, Path('runs/x'))


# ------------------------------------------------------------------ against the parameter tables
def _scenario_error(text: str, extra=()) -> str:
    scenario = parse_scenario(text, 'sc.yaml')
    with pytest.raises(ConfigError) as info:
        check_scenario(scenario, CONFIG, extra)
    return str(info.value)


def test_scenario_terrain_in_params_conflicts_with_the_top_level_terrain(tmp_path):
    message = _scenario_error('duration: 5\nparams:\n  sim: {terrain: step_down}\n')
    assert message.startswith("sc.yaml: params.sim.terrain = 'step_down' conflicts with the "
                              'top-level terrain (flat, the default')
    assert 'top-level terrain: key' in message
    message = _scenario_error('duration: 5\nterrain: rough\n'
                              'params:\n  sim: {terrain_step_height: 0.2}\n')
    assert 'params.sim.terrain_step_height = 0.2 conflicts with the top-level terrain (rough)' \
        in message
    extra = tmp_path / 'extra.yaml'
    extra.write_text('sim:\n  ros__parameters:\n    terrain: step_up\n')
    assert _scenario_error('duration: 5\n', [extra]).startswith(
        f"{extra}: sim.terrain = 'step_up' conflicts with the top-level terrain")


def test_scenario_params_and_terrain_are_checked():
    assert _scenario_error('duration: 5\nparams:\n  gait: {replan_window: 9}\n') == (
        'sc.yaml (params): gait.replan_window = 9 is out of range [1, 8]')
    assert 'sim.terrain_height = 0.05 is not a parameter of sim (did you mean ' in \
        _scenario_error('duration: 5\nterrain: {type: step_up, height: 0.05}\n')
    check_scenario(parse_scenario('duration: 5\nterrain: {type: step_up, step_height: 0.05}\n'
                                  'params:\n  gait: {replan_window: 2}\n', 'sc.yaml'), CONFIG)


@pytest.mark.parametrize('path', sorted((CONFIG / 'scenarios').glob('*.yaml')),
                         ids=lambda p: p.stem)
def test_shipped_scenarios_pass(path):
    check_scenario(parse_scenario(path.read_text(), str(path)), CONFIG)
