"""Bad configuration stops the start: the launcher and the scenario runner check
every parameter file before anything starts (exit 2, one line), a node started by hand with a
bad value exits non-zero, read-only parameters refuse run-time changes, and a node that keeps
dying stops the graph (exit 4)."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest
from conftest import CONFIG_DIR
from harness import REPO_ROOT, graph_env
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

BAD_FILES = {
    'out_of_range': ('gait:\n  ros__parameters:\n    replan_window: 0\n',
                     'gait.replan_window = 0 is out of range [1, 8]'),
    'misspelt_key': ('gait:\n  ros__parameters:\n    replan_windw: 2\n',
                     'gait.replan_windw = 2 is not a parameter of gait '
                     '(did you mean replan_window?)'),
    'wrong_type': ('mpc:\n  ros__parameters:\n    horizon: "eight"\n',
                   "mpc.horizon = 'eight' has the wrong type: expected a float"),
}


def _run_tool(module: str, args: list[str], domain: int, timeout: float):
    start = time.monotonic()
    result = subprocess.run([sys.executable, '-m', module, *args], env=graph_env(domain),
                            cwd=REPO_ROOT, capture_output=True, text=True, timeout=timeout)
    return result, time.monotonic() - start


@pytest.mark.parametrize('case', sorted(BAD_FILES))
def test_launcher_refuses_a_bad_parameter_file(case, ros_domain, tmp_path):
    text, expected = BAD_FILES[case]
    bad = tmp_path / 'bad.yaml'
    bad.write_text(text)
    run_dir = tmp_path / 'run'
    result, wall = _run_tool('replan_ros.launch.launch_graph',
                             ['--params', str(bad), '--duration', '1', '--run-dir', str(run_dir)],
                             ros_domain, timeout=60)
    assert result.returncode == 2, result.stdout + result.stderr
    lines = (result.stdout + result.stderr).strip().splitlines()
    assert lines == [f'config error: {bad}: {expected}'] or (
        len(lines) == 1 and lines[0].startswith(f'config error: {bad}: {expected}')), lines
    assert not run_dir.exists(), 'no run folder, no logs: nothing was started'
    assert wall < 15.0


def _wrong_go1(tmp_path):
    """Go1's robot file with a misspelt joint: its names no longer match its URDF."""
    text = (CONFIG_DIR / 'robots' / 'go1.yaml').read_text()
    bad = tmp_path / 'my_go1.yaml'
    bad.write_text(text.replace('[FL_hip_joint,', '[FL_hip_jont,'))
    return bad, f"robot file {bad}: legs.lf.joints[0]: no joint 'FL_hip_jont' in go1.urdf"


def assert_refused_in_one_line(module: str, args: list, domain: int, out, expected: str) -> None:
    """The tool exits 2 with the one line ``config error: expected`` and starts nothing."""
    result, wall = _run_tool(module, args, domain, timeout=60)
    assert result.returncode == 2, result.stdout + result.stderr
    lines = (result.stdout + result.stderr).strip().splitlines()
    assert lines == [f'config error: {expected}'], lines
    assert not out.exists(), 'no run folder, no logs: nothing was started'
    assert wall < 15.0


@pytest.mark.parametrize('tool', ['launch', 'scenario'])
@pytest.mark.parametrize('case', ['unknown_name', 'wrong_joint_name'])
def test_a_wrong_robot_is_refused_in_one_line(tool, case, ros_domain, tmp_path):
    """``--robot solo12`` (no such robot file) or a robot file whose names do not match its
    URDF:
    one line, exit 2, nothing started."""
    if case == 'unknown_name':
        robot, expected = 'solo12', ("unknown robot 'solo12' (known: a1, anymal_b, anymal_c, "
                                     'b1, go1, go2, hyq; or a robot file, docs/robot_files.md)')
    else:
        path, expected = _wrong_go1(tmp_path)
        robot = str(path)
    out = tmp_path / 'run'
    if tool == 'launch':
        module, args = 'replan_ros.launch.launch_graph', ['--robot', robot, '--duration', '1',
                                                           '--run-dir', str(out)]
    else:
        scenario = tmp_path / 'walk.yaml'
        scenario.write_text(f'duration: 2\nrobot: {robot}\n')
        module, args = 'replan_experiments.scenario', [str(scenario), '--out', str(out)]
    assert_refused_in_one_line(module, args, ros_domain, out, expected)


@pytest.mark.parametrize('tool', ['launch', 'scenario', 'scenario_event'])
def test_an_unknown_gait_is_refused_in_one_line(tool, ros_domain, tmp_path):
    """``--gait pace`` (no such gait file), a scenario's ``gait: pace`` or a switch to it:
    one line naming the gaits there are, exit 2, nothing started."""
    expected = (f"unknown gait 'pace': no {CONFIG_DIR / 'gaits' / 'pace.yaml'}; gaits: crawl, "
                'trot, walking_trot')
    out = tmp_path / 'run'
    if tool == 'launch':
        module, args = 'replan_ros.launch.launch_graph', ['--gait', 'pace', '--duration', '1',
                                                           '--run-dir', str(out)]
    else:
        scenario = tmp_path / 'walk.yaml'
        scenario.write_text('duration: 2\n' + ('gait: pace\n' if tool == 'scenario' else
                                               'events:\n  - {t: 1.0, gait: pace}\n'))
        module, args = 'replan_experiments.scenario', [str(scenario), '--out', str(out)]
    assert_refused_in_one_line(module, args, ros_domain, out, expected)


def test_scenario_refuses_terrain_set_in_two_places(ros_domain, tmp_path):
    scenario = tmp_path / 'step.yaml'
    scenario.write_text('duration: 2\nparams:\n  sim: {terrain: step_down}\n'
                        'events:\n  - {t: 0.5, cmd_vel: [0.1, 0.0, 0.0]}\n')
    out = tmp_path / 'out'
    result, wall = _run_tool('replan_experiments.scenario', [str(scenario), '--out', str(out)],
                             ros_domain, timeout=60)
    assert result.returncode == 2, result.stdout + result.stderr
    lines = (result.stdout + result.stderr).strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"config error: {scenario}: params.sim.terrain = 'step_down' "
                               'conflicts with the top-level terrain (flat'), lines
    assert 'top-level terrain: key' in lines[0]
    assert not out.exists()
    assert wall < 15.0


def test_node_started_alone_with_a_bad_value_exits_non_zero(launcher):
    gait = launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml',
                          params={'replan_window': 0})
    gait.process.wait(30)
    assert gait.process.returncode == 2
    assert 'config error: command line (-p): gait.replan_window = 0 is out of range [1, 8]' \
        in gait.log()


@pytest.mark.parametrize('node', ['sim', 'wbc'])
def test_node_started_alone_with_an_unknown_robot_exits_non_zero(node, launcher):
    process = launcher.start(f'{node}_node', params_file=CONFIG_DIR / f'{node}.yaml',
                             params={'robot_file': 'solo12'})
    process.process.wait(30)
    assert process.process.returncode == 2
    assert ("config error: unknown robot 'solo12' (known: a1, anymal_b, anymal_c, b1, go1, "
            "go2, hyq"
            in process.log())


def test_wbc_refuses_an_observer_gain_at_its_control_rate(launcher):
    """Each value is in range, their combination is not: the foot-force observer's gain must
    stay below the control rate (gain * dt < 1), which only the node knows."""
    wbc = launcher.start('wbc_node', params_file=CONFIG_DIR / 'wbc.yaml',
                         params={'state_estimation': True, 'control_rate': 250.0,
                                 'estimator.contact_observer_gain': 300.0})
    wbc.process.wait(30)
    assert wbc.process.returncode == 2
    assert 'config error: wbc: contact_observer_gain (1/s) must be >= 0 and below 1 / dt, got ' \
        '300.0 (control_rate 250.0 Hz)' in wbc.log()


def test_node_started_alone_with_a_misspelt_key_exits_non_zero(launcher, tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('mpc:\n  ros__parameters:\n    horizn: 6.0\n')
    mpc = launcher.start('mpc_node', params_file=CONFIG_DIR / 'mpc.yaml',
                         ros_args=['--params-file', str(bad)])
    mpc.process.wait(30)
    assert mpc.process.returncode == 2
    assert f'config error: {bad}: mpc.horizn = 6.0 is not a parameter of mpc ' \
           '(did you mean horizon?)' in mpc.log()


def test_recorder_started_alone_with_a_bad_regex_exits_non_zero(launcher, tmp_path):
    """The recorder checks its parameters as every node does: a bad regex must not leave it
    recording everything or nothing."""
    bad = tmp_path / 'bad.yaml'
    bad.write_text("recorder:\n  ros__parameters:\n    exclude_regex: '^/(tf'\n")
    recorder = launcher.start('recorder_node', params_file=CONFIG_DIR / 'recorder.yaml',
                              params={'output': str(tmp_path / 'never.mcap')},
                              ros_args=['--params-file', str(bad)])
    recorder.process.wait(30)
    assert recorder.process.returncode == 2
    assert f"config error: {bad}: recorder.exclude_regex = '^/(tf' is not a valid regular " \
        'expression' in recorder.log()
    assert not (tmp_path / 'never.mcap').exists()


def _set(probe, client, name, value):
    future = client.set_parameters([Parameter(name, value=value)])
    assert probe.spin_until(future.done, 10.0)
    return future.result().results[0]


def test_run_time_changes_are_refused_when_read_only_or_invalid(launcher, probe):
    # An int accepted for a float on the command line (ROS's rule): start_delay:=2.
    launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml',
                   params={'start_delay': 2})
    client = AsyncParameterClient(probe.node, 'gait')
    assert client.wait_for_services(timeout_sec=30.0), launcher.logs()
    result = _set(probe, client, 'replan_window', 2)
    assert not result.successful
    assert 'read-only' in result.reason and 'replan_window' in result.reason
    result = _set(probe, client, 'warn_period', -1.0)          # writable, out of range
    assert not result.successful and 'out of range' in result.reason, result.reason
    assert _set(probe, client, 'warn_period', 5.0).successful
    future = client.get_parameters(['warn_period', 'replan_window', 'start_delay'])
    assert probe.spin_until(future.done, 10.0)
    values = [v.double_value or v.integer_value for v in future.result().values]
    assert values == [5.0, 1, 2.0]
    future = client.describe_parameters(['replan_window'])
    assert probe.spin_until(future.done, 10.0)
    descriptor = future.result().descriptors[0]
    assert descriptor.read_only
    assert (descriptor.integer_range[0].from_value, descriptor.integer_range[0].to_value) == (1, 8)


def test_a_node_that_keeps_dying_stops_the_graph(ros_domain, tmp_path):
    """mpc cannot load its URDF: it dies at start, is respawned after 1 s and 2 s, and its
    third death within 30 s stops the graph with exit code 4 and its last log lines. The other
    nodes idle meanwhile (the controller waits for its first plans, the sim for a command)."""
    bad = tmp_path / 'bad_urdf.yaml'
    bad.write_text("mpc:\n  ros__parameters:\n    urdf_path: '/nonexistent/robot.urdf'\n")
    result, wall = _run_tool('replan_ros.launch.launch_graph',
                             ['--params', str(bad), '--profile', 'ideal', '--duration', '100',
                              '--run-dir', str(tmp_path / 'run')], ros_domain, timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 4, output
    assert output.count('node mpc died') == 3, output
    assert 'respawning mpc in 1 s' in output and 'respawning mpc in 2 s' in output, output
    assert 'mpc died 3 times within 30 s: stopping the graph' in output, output
    tail = output.split('stopping the graph', 1)[1]
    assert "cannot load the URDF '/nonexistent/robot.urdf'" in tail, output
    assert 'all nodes stopped' in output
    assert wall < 90.0
