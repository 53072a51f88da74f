"""config/robots/scaling.yaml against the parameter tables: every rule names a parameter of its
node, and derived from the reference's own resolved values (defaults and config file) the
reference robot gets exactly those values back."""

from pathlib import Path

import yaml

from replan_core.robot.robot_file import load_robot_file, robot_facts
from replan_core.robot.scaling import derived_parameters
from replan_ros.params import defaults, load_param_file, table

ROOT = Path(__file__).resolve().parents[4]
RULES = yaml.safe_load((ROOT / 'config' / 'robots' / 'scaling.yaml').read_text())


def _keys():
    keys = [k for keys in RULES['rules'].values() for k in keys]
    return keys + list(RULES['measured'])


def test_every_rule_names_a_parameter_of_its_node():
    for key in _keys():
        node, _, name = key.partition('.')
        assert name in table(node), key


def test_the_reference_robot_gets_its_resolved_values_back():
    nodes = {key.partition('.')[0] for key in _keys()}
    values = {}
    for node in nodes:
        values[node] = dict(defaults(node))
        values[node].update(load_param_file(ROOT / 'config' / f'{node}.yaml').get(node, {}))
    reference = robot_facts(load_robot_file(
        ROOT / 'config' / 'robots' / f'{RULES["reference"]}.yaml', ROOT))
    derived = derived_parameters(reference, reference, values, RULES, measure=False)
    for node, params in derived.items():
        for name, value in params.items():
            assert value == values[node][name], (node, name)


def test_the_reference_com_offset_is_its_model_s():
    """``mpc.com_offset`` is measured for every other robot; the reference keeps its file's
    value, which must be what its model measures (to 1 mm), or the position term would pull
    HyQ's CoM off its place over the feet."""
    reference = robot_facts(load_robot_file(
        ROOT / 'config' / 'robots' / f'{RULES["reference"]}.yaml', ROOT))
    configured = load_param_file(ROOT / 'config' / 'mpc.yaml')['mpc']['com_offset']
    assert RULES['measured']['mpc.com_offset'] == 'com_about_feet'
    assert configured == defaults('mpc')['com_offset']
    for got, want in zip(configured, reference.com_about_feet, strict=True):
        assert abs(got - want) < 1e-3
