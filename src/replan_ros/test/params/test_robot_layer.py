"""The robot of a run (params/robot.py, launch/param_files.robot_parameters): what a node loads
for its robot_file parameter, and the parameters a launcher gives the nodes for a robot: for
the reference robot exactly the values it had without one (HyQ's runs stay bit-identical), for
another robot its standing pose, the derived values and its file's own overrides, all checked
as any parameter file; a wrong robot is one line."""

from pathlib import Path

import pytest
import yaml

from replan_core.common.types import BASE_FRAME, FOOT_FRAMES, JOINT_NAMES
from replan_ros.launch.param_files import check_run_files, profile_file, robot_parameters
from replan_ros.params import ConfigError, load_param_file
from replan_ros.params.robot import POSE_NODES, ROBOT_NODES, node_robot

ROOT = Path(__file__).resolve().parents[4]
CONFIG = ROOT / 'config'
ROBOTS = CONFIG / 'robots'


@pytest.fixture(autouse=True)
def _repository(monkeypatch):
    # The nodes find robot names and project models through these (scripts/env.sh sets them).
    monkeypatch.setenv('REPLAN_ROOT', str(ROOT))
    monkeypatch.setenv('REPLAN_CONFIG', str(CONFIG))


def test_a_node_without_a_robot_file_keeps_the_project_names():
    robot = node_robot('', '', '/x/hyq.urdf')
    assert (robot.urdf, robot.joints, robot.feet, robot.root_link, robot.spec) == (
        '/x/hyq.urdf', JOINT_NAMES, FOOT_FRAMES, BASE_FRAME, None)
    assert node_robot('', '/y/other.urdf', '/x/hyq.urdf').urdf == '/y/other.urdf'


def test_a_node_with_a_robot_file_loads_its_model_and_names():
    robot = node_robot('go1', '', '/x/hyq.urdf')
    assert robot.urdf.endswith('go1_description/urdf/go1.urdf') and Path(robot.urdf).is_file()
    assert robot.joints[:3] == ('FL_hip_joint', 'FL_thigh_joint', 'FL_calf_joint')
    assert robot.feet == ('FL_foot', 'FR_foot', 'RL_foot', 'RR_foot')
    assert robot.root_link == 'base'
    # A path works as a name does; urdf_path replaces the model (a variant, same names).
    assert node_robot(str(ROBOTS / 'go1.yaml'), '', '').joints == robot.joints
    assert node_robot('go1', '/v/go1-variant.urdf', '').urdf == '/v/go1-variant.urdf'
    hyq = node_robot('hyq', '', '')
    assert hyq.joints == JOINT_NAMES and hyq.feet == FOOT_FRAMES
    assert Path(hyq.urdf) == ROOT / 'urdf' / 'hyq.urdf'


def test_a_node_with_an_unknown_robot_gets_one_line():
    with pytest.raises(ConfigError) as error:
        node_robot('solo12', '', '')
    assert str(error.value) == ("unknown robot 'solo12' (known: a1, anymal_b, anymal_c, b1, "
                                'go1, go2, hyq; or a robot file, docs/robot_files.md)')


@pytest.mark.parametrize('profile', ['realistic', 'ideal'])
def test_the_reference_robot_changes_no_value(profile):
    """HyQ through its robot file: every parameter of every node as without one (the
    robot_file itself aside), so a HyQ run is the run it was."""
    path = profile_file(CONFIG, profile)
    layer = robot_parameters(CONFIG, 'hyq', path)
    before = check_run_files(CONFIG, [path]).values
    after = check_run_files(CONFIG, [path, layer.derived, layer.overrides]).values
    for node, values in before.items():
        changed = {k for k, v in after[node].items() if v != values[k]}
        assert changed <= {'robot_file'}, (node, changed)
        if node in ROBOT_NODES:
            assert after[node]['robot_file'] == 'hyq'


def test_another_robot_gets_its_pose_derived_values_and_names(tmp_path):
    path = profile_file(CONFIG, 'ideal')
    layer = robot_parameters(CONFIG, 'go1', path)
    written = load_param_file(layer.write(tmp_path / 'robot.yaml'))
    resolved = check_run_files(CONFIG, [path, tmp_path / 'robot.yaml']).values
    for node in POSE_NODES:
        assert resolved[node]['standing_joint_positions'] == [0.0, 0.8, -1.853] * 4
    for node in ROBOT_NODES:
        assert written[node]['robot_file'] == 'go1'
    hyq = check_run_files(CONFIG, [path]).values
    ratio = resolved['wbc']['fz_max'] / hyq['wbc']['fz_max']
    assert ratio == pytest.approx(13.10 / 86.76, rel=1e-3)          # the weight rule
    assert resolved['wbc']['estimator.contact_force_threshold'] == pytest.approx(
        hyq['wbc']['estimator.contact_force_threshold'] * 1.88 / 6.45, rel=5e-3)   # leg weight
    assert resolved['mpc']['com_height'] == pytest.approx(0.255, abs=0.005)   # measured
    assert resolved['wbc']['estimator.foot_radius'] == pytest.approx(0.02, abs=1e-6)


@pytest.mark.parametrize('robot, lag', [('go1', 0.001), ('b1', 0.001), ('anymal_c', 0.0023)])
def test_the_realistic_actuator_lag_is_the_robots_actuator_kinds(robot, lag):
    """config/robots/scaling.yaml actuator_kinds: HyQ's hydraulic 3 ms becomes the robot
    kind's; the ideal profile has no lag for any robot."""
    for profile, wanted in (('realistic', lag), ('ideal', 0.0)):
        path = profile_file(CONFIG, profile)
        layer = robot_parameters(CONFIG, robot, path)
        resolved = check_run_files(CONFIG, [path, layer.derived, layer.overrides]).values
        assert resolved['sim']['actuator_time_constant'] == pytest.approx(wanted, abs=1e-12)
        assert resolved['sim']['actuator_delay'] == check_run_files(
            CONFIG, [path]).values['sim']['actuator_delay']


def _robot_file(tmp_path: Path, change) -> Path:
    doc = yaml.safe_load((ROBOTS / 'go1.yaml').read_text())
    change(doc)
    path = tmp_path / 'my_go1.yaml'
    path.write_text(yaml.safe_dump(doc))
    return path


def test_a_robot_files_own_parameters_win_over_the_derived_ones(tmp_path):
    path = _robot_file(tmp_path, lambda d: d.__setitem__(
        'parameters', {'wbc': {'fz_max': 99.0, 'estimator': {'contact_force_threshold': 5.5}}}))
    layer = robot_parameters(CONFIG, str(path), None)
    resolved = check_run_files(CONFIG, [layer.derived, layer.overrides]).values
    assert resolved['wbc']['fz_max'] == 99.0
    assert resolved['wbc']['estimator.contact_force_threshold'] == 5.5
    # A file given by path is named by its absolute path in the run's parameters.
    assert resolved['sim']['robot_file'] == str(path.resolve())
    layer.write(tmp_path / 'robot.yaml')
    again = check_run_files(CONFIG, [tmp_path / 'robot.yaml']).values
    assert again['wbc']['estimator.contact_force_threshold'] == 5.5


def test_a_robot_files_bad_parameter_is_one_line_naming_the_file(tmp_path):
    path = _robot_file(tmp_path, lambda d: d.__setitem__('parameters', {'wbc': {'fz_mx': 1.0}}))
    layer = robot_parameters(CONFIG, str(path), None)
    with pytest.raises(ConfigError) as error:
        check_run_files(CONFIG, [layer.derived, layer.overrides])
    assert str(error.value).startswith(f'{path} (parameters): wbc.fz_mx = 1.0 is not a '
                                       'parameter of wbc')


@pytest.mark.parametrize('change, message', [
    (lambda d: d['legs']['lf']['joints'].__setitem__(0, 'FL_hip_jont'),
     "legs.lf.joints[0]: no joint 'FL_hip_jont' in go1.urdf"),
    (lambda d: d.__setitem__('root_link', 'trunk'),
     "root_link: 'trunk' is not the root link of go1.urdf (base)"),
])
def test_a_robot_file_that_does_not_match_its_model_is_refused(tmp_path, change, message):
    path = _robot_file(tmp_path, change)
    for attempt in (lambda: robot_parameters(CONFIG, str(path), None),
                    lambda: node_robot(str(path), '', '')):
        with pytest.raises(ConfigError) as error:
            attempt()
        assert str(error.value) == f'robot file {path}: {message}'
