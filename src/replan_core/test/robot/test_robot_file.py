"""Robot files (robot_file.py) and the scaling rules (robot/scaling.py): the four robots of
config/robots/ load with every name checked against their models, their facts agree with
independent measurements (shared/notes/quadrupeds.md), a wrong name stops with one line, and
the derived parameters follow the rules."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from replan_core.robot.robot_file import (
    RobotFileError,
    load_robot_file,
    robot_facts,
    robot_file_path,
    robot_spec,
    srdf_standing_pose,
)
from replan_core.robot.scaling import derived_parameters

ROOT = Path(__file__).resolve().parents[4]
ROBOTS = ROOT / 'config' / 'robots'
# kg, total mass; m, standing height over the ground (measured with PyBullet and pinocchio
# for the notes, independently of this code).
EXPECTED = {'hyq': (86.76, 0.60), 'anymal_c': (52.13, 0.54), 'go1': (13.10, 0.27),
            'b1': (55.69, 0.53), 'anymal_b': (30.48, 0.49), 'a1': (13.74, 0.27),
            'go2': (16.09, 0.335)}
# kg, one leg (the links below its abduction joint), summed from each URDF's leg links.
LEG_MASS = {'hyq': 6.45, 'anymal_c': 6.44, 'go1': 1.88, 'b1': 7.47, 'anymal_b': 3.41,
            'a1': 1.93, 'go2': 2.20}


@pytest.fixture(scope='module')
def facts():
    return {name: robot_facts(load_robot_file(ROBOTS / f'{name}.yaml', ROOT))
            for name in EXPECTED}


@pytest.mark.parametrize('name', sorted(EXPECTED))
def test_each_robot_file_maps_its_model_into_the_project_names(name, facts):
    spec = load_robot_file(ROBOTS / f'{name}.yaml', ROOT)
    assert spec.name == name and len(spec.joints) == 12 and len(spec.feet) == 4
    assert spec.urdf.is_file() and spec.standing_pose.shape == (12,)
    mass, height = EXPECTED[name]
    assert facts[name].mass == pytest.approx(mass, abs=0.01)
    assert facts[name].standing_height == pytest.approx(height, abs=0.01)
    assert facts[name].leg_mass == pytest.approx(LEG_MASS[name], abs=0.01)
    # The feet stand outside (or under) their hips, symmetric left to right.
    about = facts[name].feet_about_hips
    assert np.allclose(about[0], about[1] * [1, -1], atol=1e-3)
    assert 0.0 <= about[0, 1] < 0.2


def test_a_standing_pose_from_the_srdf_is_its_standing_group_state():
    spec = load_robot_file(ROBOTS / 'go1.yaml', ROOT)
    assert spec.srdf is not None
    assert spec.standing_pose.tolist() == [0.0, 0.8, -1.853] * 4
    assert srdf_standing_pose(spec.srdf, spec.joints[:3]).tolist() == [0.0, 0.8, -1.853]
    with pytest.raises(KeyError, match='no group state'):
        srdf_standing_pose(spec.srdf, spec.joints, 'lying')


def _doc(name='go1'):
    return yaml.safe_load((ROBOTS / f'{name}.yaml').read_text())


@pytest.mark.parametrize('change, key, problem', [
    (lambda d: d['legs']['lf']['joints'].__setitem__(0, 'FL_hip_jont'), 'legs.lf.joints[0]',
     "no joint 'FL_hip_jont' in go1.urdf"),
    (lambda d: d['legs']['rh'].__setitem__('foot', 'RR_toe'), 'legs.rh.foot', "no link 'RR_toe'"),
    (lambda d: d['legs']['lf']['joints'].__setitem__(0, 'FL_foot_fixed'), 'legs.lf.joints[0]',
     'is fixed, not revolute'),
    (lambda d: d['legs'].pop('lh'), 'legs', 'needs exactly the legs lf, rf, lh, rh'),
    (lambda d: d.__setitem__('root_link', 'trunkk'), 'root_link', "no link 'trunkk'"),
    (lambda d: d.__setitem__('root_link', 'trunk'), 'root_link',
     "'trunk' is not the root link of go1.urdf (base)"),
    (lambda d: d.__setitem__('colour', 'red'), 'colour', 'unknown key'),
    (lambda d: d['model'].__setitem__('source', 'internet'), 'model.source', "'internet'"),
    (lambda d: d['model'].__setitem__('urdf', 'go1_description/urdf/go2.urdf'), 'model.urdf',
     'no file'),
    (lambda d: d['model'].pop('srdf'), 'standing_pose', "'srdf' needs model.srdf"),
    (lambda d: d.__setitem__('standing_pose', [0.0] * 11), 'standing_pose', '12 values'),
    (lambda d: d['foot_contact'].__setitem__('radius', 0.0), 'foot_contact.radius', 'radius'),
    (lambda d: d.__setitem__('actuator', 'steam'), 'actuator', "'steam' is not one of"),
    (lambda d: d.__setitem__('parameters', {'wbc': 3}), 'parameters', 'mapping'),
])
def test_a_wrong_robot_file_stops_with_one_line_naming_file_and_key(change, key, problem):
    doc = _doc()
    change(doc)
    with pytest.raises(RobotFileError) as error:
        robot_spec(doc, 'my_go1.yaml', ROOT)
    message = str(error.value)
    assert message.startswith(f'robot file my_go1.yaml: {key}: ') and problem in message
    assert '\n' not in message


def test_a_robot_is_a_name_of_config_robots_or_a_file():
    assert robot_file_path('go1', ROOT / 'config') == ROBOTS / 'go1.yaml'
    assert robot_file_path('/x/my_go1.yaml', ROOT / 'config') == Path('/x/my_go1.yaml')
    for wrong in ('solo12', 'scaling'):
        with pytest.raises(RobotFileError, match=re.escape(
                f"unknown robot '{wrong}' (known: a1, anymal_b, anymal_c, b1, go1, go2, hyq; "
                "or a robot file")):
            robot_file_path(wrong, ROOT / 'config')


def test_an_unreadable_robot_file_is_one_line_too(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: [unclosed\n')
    with pytest.raises(RobotFileError, match=re.escape(f'robot file {bad}: ')):
        load_robot_file(bad, ROOT)
    with pytest.raises(RobotFileError, match=re.escape('missing.yaml')):
        load_robot_file(tmp_path / 'missing.yaml', ROOT)


RULES = {'rules': {'weight': ['wbc.fz_max'],
                   'leg_weight': ['wbc.estimator.contact_force_threshold'],
                   'length': ['gait.step_height'],
                   'time': ['gait.swing_duration'], 'speed': ['gait.max_linear_x'],
                   'rate': ['gait.max_angular_z'], 'joint_inertia': ['wbc.fall_damping']},
         'measured': {'mpc.com_height': 'com_height'}}
VALUES = {'wbc': {'fz_max': 800.0, 'fall_damping': 2.0,
                  'estimator.contact_force_threshold': 40.0},
          'gait': {'step_height': 0.1, 'swing_duration': 0.5, 'max_linear_x': 0.2,
                   'max_angular_z': 0.25},
          'mpc': {'com_height': 0.55}}


def test_the_reference_robot_keeps_its_tuned_values_exactly(facts):
    hyq = facts['hyq']
    assert derived_parameters(hyq, hyq, VALUES, RULES, measure=False) == {
        'wbc': {'fz_max': 800.0, 'fall_damping': 2.0,
                'estimator.contact_force_threshold': 40.0},
        'gait': {'step_height': 0.1, 'swing_duration': 0.5, 'max_linear_x': 0.2,
                 'max_angular_z': 0.25}}


def test_each_rule_scales_by_its_physics(facts):
    hyq, go1 = facts['hyq'], facts['go1']
    out = derived_parameters(go1, hyq, VALUES, RULES)
    legs = go1.leg_length / hyq.leg_length
    assert out['wbc']['fz_max'] == pytest.approx(800.0 * go1.mass / hyq.mass)
    assert out['wbc']['estimator.contact_force_threshold'] == pytest.approx(
        40.0 * go1.leg_mass / hyq.leg_mass)
    assert out['gait']['step_height'] == pytest.approx(0.1 * legs)
    assert out['gait']['swing_duration'] == pytest.approx(0.5 * math.sqrt(legs))
    assert out['gait']['max_linear_x'] == pytest.approx(0.2 * math.sqrt(legs))
    assert out['gait']['max_angular_z'] == pytest.approx(0.25 / math.sqrt(legs))
    assert out['mpc']['com_height'] == pytest.approx(go1.com_height)
    assert out['mpc']['com_height'] == pytest.approx(0.255, abs=0.005)


def test_torques_stiffness_damping_and_lists_scale_too(facts):
    hyq, go1 = facts['hyq'], facts['go1']
    rules = {'rules': {'torque': ['wbc.stand_up_kp'], 'stiffness': ['wbc.swing_kp'],
                       'damping': ['wbc.swing_kd'], 'length': ['sim.payload_offset'],
                       'position_cost': ['mpc.position_weight']}}
    values = {'wbc': {'stand_up_kp': 400.0, 'swing_kp': [1500.0] * 3, 'swing_kd': [50.0] * 3},
              'sim': {'payload_offset': [0.1, 0.05, 0.05]}, 'mpc': {'position_weight': 1e4}}
    out = derived_parameters(go1, hyq, values, rules)
    mass, legs = go1.mass / hyq.mass, go1.leg_length / hyq.leg_length
    assert out['mpc']['position_weight'] == pytest.approx(1e4 / legs ** 3)   # about 4.4e4
    assert out['wbc']['stand_up_kp'] == pytest.approx(400.0 * mass * legs)
    assert out['wbc']['swing_kp'] == pytest.approx([1500.0 * mass / legs] * 3)
    assert out['wbc']['swing_kd'] == pytest.approx([50.0 * mass / math.sqrt(legs)] * 3)
    assert out['sim']['payload_offset'] == pytest.approx([0.1 * legs, 0.05 * legs, 0.05 * legs])
    # The reference gets its lists back exactly.
    assert derived_parameters(hyq, hyq, values, rules, measure=False) == values


def test_derived_joint_damping_stays_below_what_250_hz_can_apply(facts):
    rules = yaml.safe_load((ROBOTS / 'scaling.yaml').read_text())
    assert rules['reference'] == 'hyq'
    for name, robot in facts.items():
        damping = derived_parameters(robot, facts['hyq'], VALUES,
                                     {'rules': {'joint_inertia': ['wbc.fall_damping']}})
        # Explicit damping at a control period dt is stable below 2 I / dt.
        assert damping['wbc']['fall_damping'] < 0.5 * 2 * robot.min_joint_inertia / 0.004, name


def test_every_haptic_swing_presses_its_foot_with_the_same_share_of_its_threshold(facts):
    """The project's rules: swing stiffness x touchdown depth over the estimator's contact
    threshold is the reference's for every robot (rule press_depth; B1 at the length rule
    pressed with 32 % of its threshold, HyQ 56 %, and half its touchdowns were sensed late)."""
    wanted = ('wbc.swing_kp', 'wbc.touchdown_depth', 'wbc.estimator.contact_force_threshold')
    project = yaml.safe_load((ROBOTS / 'scaling.yaml').read_text())['rules']
    rules = {'rules': {scale: [key for key in keys if key in wanted]
                       for scale, keys in project.items()}}
    assert sum(len(keys) for keys in rules['rules'].values()) == 3
    values = {'wbc': {'swing_kp': [1500.0] * 3, 'touchdown_depth': 0.015,
                      'estimator.contact_force_threshold': 40.0}}
    shares = {}
    for name, robot in facts.items():
        wbc = derived_parameters(robot, facts['hyq'], values, rules, measure=False)['wbc']
        shares[name] = (wbc['swing_kp'][0] * wbc['touchdown_depth']
                        / wbc['estimator.contact_force_threshold'])
    assert shares == pytest.approx({name: 1500.0 * 0.015 / 40.0 for name in facts}, rel=1e-12)
    b1 = derived_parameters(facts['b1'], facts['hyq'], values, rules, measure=False)['wbc']
    assert b1['touchdown_depth'] == pytest.approx(0.027, abs=0.001)   # m; 0.015 by length


def test_unknown_scales_measurements_and_parameters_are_refused(facts):
    hyq = facts['hyq']
    with pytest.raises(ValueError, match="unknown scale 'mass'"):
        derived_parameters(hyq, hyq, VALUES, {'rules': {'mass': ['wbc.fz_max']}})
    no_such = re.escape('wbc.fz_mx: the reference has no such parameter')
    with pytest.raises(ValueError, match=no_such):
        derived_parameters(hyq, hyq, VALUES, {'rules': {'weight': ['wbc.fz_mx']}})
    with pytest.raises(ValueError, match="unknown measurement 'height'"):
        derived_parameters(hyq, hyq, VALUES, {'measured': {'mpc.com_height': 'height'}})
    with pytest.raises(ValueError, match=re.escape('is not node.parameter')):
        derived_parameters(hyq, hyq, VALUES, {'rules': {'weight': ['fz_max']}})


def test_the_actuator_lag_follows_the_actuator_kind_and_nothing_else(facts):
    """The project's rule (scaling.yaml actuator_kinds): each robot file's kind gets its
    figure, whatever its size; a profile without the lag (0) keeps none."""
    project = yaml.safe_load((ROBOTS / 'scaling.yaml').read_text())
    rules = {'actuator_kinds': project['actuator_kinds']}
    figures = rules['actuator_kinds']['sim.actuator_time_constant']
    realistic = {'sim': {'actuator_time_constant': 0.003}}
    kinds = {name: load_robot_file(ROBOTS / f'{name}.yaml', ROOT).actuator for name in facts}
    assert kinds['hyq'] == 'hydraulic' and kinds['anymal_c'] == 'series_elastic'
    for name, robot in facts.items():
        lag = derived_parameters(robot, facts['hyq'], realistic, rules, measure=False,
                                 actuators=(kinds[name], 'hydraulic'))
        assert lag['sim']['actuator_time_constant'] == pytest.approx(figures[kinds[name]]), name
        ideal = derived_parameters(robot, facts['hyq'], {'sim': {'actuator_time_constant': 0.0}},
                                   rules, measure=False, actuators=(kinds[name], 'hydraulic'))
        assert ideal['sim']['actuator_time_constant'] == 0.0
    # Without the kinds nothing is derived from them; a kind without a figure is refused.
    assert derived_parameters(facts['go1'], facts['hyq'], realistic, rules) == {}
    with pytest.raises(ValueError, match='no figure for pneumatic'):
        derived_parameters(facts['go1'], facts['hyq'], realistic, rules,
                           actuators=('pneumatic', 'hydraulic'))
