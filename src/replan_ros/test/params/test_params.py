"""The parameter tables (replan_ros/params/) and the check of a run's parameter files."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest

from replan_core.estimation.settings import EstimatorParams
from replan_ros import params
from replan_ros.launch.param_files import check_run_files
from replan_ros.params import ConfigError, Source, check_run, resolve, sources_from_argv

REPO = Path(__file__).resolve().parents[4]
CONFIG = REPO / 'config'
NODES = tuple(params.TABLES)


def _source(text: str, label: str = '/tmp/x.yaml') -> Source:
    return Source(label, params.parse_param_doc(params.load_yaml(text), label))


def _error(text: str, nodes=NODES) -> str:
    with pytest.raises(ConfigError) as info:
        check_run([_source(text)], nodes)
    return str(info.value)


# ------------------------------------------------------------------------------ tables
@pytest.mark.parametrize('node', NODES)
def test_node_file_keys_are_in_the_table_with_its_defaults(node):
    """config/<node>.yaml holds only parameters of the table, each at the table's default:
    the table is the one source of the defaults, the file shows them."""
    values = params.load_param_file(CONFIG / f'{node}.yaml')[node]
    specs = params.table(node)
    for name, value in values.items():
        if name in params.BUILTIN:
            continue
        assert name in specs, f'{node}.{name} is in config/{node}.yaml but not in the table'
        default = specs[name].default
        assert params.check_value(specs[name], value) == pytest.approx(default), name


@pytest.mark.parametrize('node', NODES)
def test_specs_are_consistent(node):
    for spec in params.TABLES[node]:
        assert spec.description
        params.check_value(spec, spec.default)       # every default is valid
        if spec.min is not None and spec.max is not None:
            assert spec.min <= spec.max, spec.name
    names = [spec.name for spec in params.TABLES[node]]
    assert len(names) == len(set(names))


def test_nearly_everything_is_read_only():
    writable = {(n, s.name) for n in NODES for s in params.TABLES[n] if not s.read_only}
    assert writable <= {('gait', 'cmd_vel_timeout'), ('gait', 'cmd_vel_reject_above'),
                        ('gait', 'warn_period'), ('mpc', 'warn_period'),
                        ('sim', 'damping_gain'), ('sim', 'damping_abduction_stiffness'),
                        ('wbc', 'plan_timeout')}


def test_importing_the_tables_loads_no_solver_simulator_or_plotting():
    """The tables read the core's settings modules (numpy only): a process that checks or
    declares parameters (the launcher, the sim, the recorder) loads none of these."""
    heavy = ('pinocchio', 'proxsuite', 'pybullet', 'scipy', 'matplotlib')
    code = ('import sys, replan_ros.params; '
            f'print(",".join(sorted(m for m in {heavy!r} if m in sys.modules)))')
    out = subprocess.run([sys.executable, '-c', code], check=True, capture_output=True,
                         text=True)
    assert out.stdout.strip() == ''


def test_wbc_declares_every_estimator_field():
    wbc = params.table('wbc')
    for item in dataclasses.fields(EstimatorParams):
        spec = wbc[f'estimator.{item.name}']
        assert spec.default == getattr(EstimatorParams(), item.name)


@pytest.mark.parametrize('node', ('sim', 'gait', 'mpc', 'wbc', 'recorder', 'live_view'))
def test_every_node_declares_its_parameters_from_its_table_only(node):
    """One source of truth: each node declares through declare_node_parameters and nowhere
    else (the recorder had its own defaults beside its table)."""
    path = 'view/live_view' if node == 'live_view' else f'nodes/{node}_node'
    source = (REPO / f'src/replan_ros/replan_ros/{path}.py').read_text()
    assert 'declare_node_parameters(self' in source
    assert re.search(r'\.declare_parameters?\(', source) is None


@pytest.mark.parametrize(('key', 'value', 'reason'), [
    ('topics_regex', "'^/(odom'", 'is not a valid regular expression (missing ), unterminated '
     'subpattern at position 2)'),
    ('exclude_regex', "'*'", 'is not a valid regular expression (nothing to repeat at '
     'position 0)'),
    ('metadata_json', "'{\"seed\": 7'", 'is not valid JSON'),
    ('metadata_json', "'[1, 2]'", 'is not a JSON object ({...})'),
])
def test_recorder_strings_with_a_syntax_are_checked(key, value, reason):
    message = _error(f'recorder:\n  ros__parameters:\n    {key}: {value}\n')
    assert message.startswith(f'/tmp/x.yaml: recorder.{key} = '), message
    assert reason in message, message


def test_recorder_strings_with_a_valid_syntax_pass():
    check_run([_source('recorder:\n  ros__parameters:\n    topics_regex: "^/(odom|imu)$"\n'
                       '    metadata_json: \'{"seed": 7}\'\n    exclude_regex: ""\n')],
              NODES)


# ------------------------------------------------------------------------------ checking
def test_shipped_files_pass():
    for profile in ('realistic', 'ideal'):
        check_run_files(CONFIG, [CONFIG / 'profiles' / f'{profile}.yaml'])


def test_unknown_key_names_the_closest_one():
    message = _error('gait:\n  ros__parameters:\n    replan_windw: 2\n')
    assert message == ('/tmp/x.yaml: gait.replan_windw = 2 is not a parameter of gait '
                       '(did you mean replan_window?)')


def test_unknown_node_names_the_closest_one():
    assert 'gaits is not a node of the graph (did you mean gait?)' in _error(
        'gaits:\n  ros__parameters:\n    haptic: true\n')


def test_out_of_range():
    assert _error('gait:\n  ros__parameters:\n    replan_window: 0\n') == (
        '/tmp/x.yaml: gait.replan_window = 0 is out of range [1, 8]')
    assert 'out of range' in _error('sim:\n  ros__parameters:\n    friction: -0.1\n')


def test_wrong_type():
    assert _error('mpc:\n  ros__parameters:\n    horizon: "eight"\n') == (
        "/tmp/x.yaml: mpc.horizon = 'eight' has the wrong type: expected a float "
        '(an int is accepted)')
    assert 'wrong type' in _error('gait:\n  ros__parameters:\n    n_footholds: 8.0\n')
    assert 'wrong type' in _error('gait:\n  ros__parameters:\n    haptic: 1\n')
    assert 'wrong type' in _error('gait:\n  ros__parameters:\n    use_sim_time: 1\n')


def test_an_int_is_accepted_for_a_float_and_becomes_one():
    resolved = check_run([_source('mpc:\n  ros__parameters:\n    horizon: 6\n'
                                  'sim:\n  ros__parameters:\n    payload_offset: [0, 0.1, 0]\n'
                                  '    contact_stiffness: 1.0e5\n')], NODES)
    assert resolved.values['mpc']['horizon'] == 6.0
    assert isinstance(resolved.values['mpc']['horizon'], float)
    assert resolved.values['sim']['payload_offset'] == [0.0, 0.1, 0.0]
    assert resolved.values['sim']['contact_stiffness'] == 1e5      # rcl reads 1.0e5 as a float
    assert resolved.where('mpc', 'horizon') == '/tmp/x.yaml'
    assert resolved.where('mpc', 'dt') == 'default'


def test_bad_choice_and_list_length():
    assert _error('sim:\n  ros__parameters:\n    terrain: moon\n') == (
        "/tmp/x.yaml: sim.terrain = 'moon' is not one of flat, step_down, step_up, rough")
    assert 'has 2 values: expected 3' in _error(
        'sim:\n  ros__parameters:\n    payload_offset: [0.1, 0.2]\n')
    assert 'not one of lf, rf, lh, rh' in _error(
        'gait:\n  ros__parameters:\n    sequence: [lh, lf, rh, xx]\n')
    assert 'each leg' in _error('gait:\n  ros__parameters:\n    sequence: [lh, lf, rh, lh]\n')


def test_nested_estimator_keys_are_checked():
    check_run([_source('wbc:\n  ros__parameters:\n    estimator: {accel_gate: 3.0}\n')], NODES)
    assert 'did you mean estimator.accel_gate?' in _error(
        'wbc:\n  ros__parameters:\n    estimator: {acel_gate: 3.0}\n')


def test_wildcard_section_applies_to_every_node():
    resolved = check_run([_source('/**:\n  ros__parameters:\n    warn_period: 5.0\n')], NODES)
    assert resolved.values['gait']['warn_period'] == 5.0
    assert resolved.values['mpc']['warn_period'] == 5.0


def test_malformed_files(tmp_path):
    with pytest.raises(ConfigError, match='expected exactly one key ros__parameters'):
        _source('gait:\n  replan_window: 2\n')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('gait: [1\n')
    with pytest.raises(ConfigError, match='not valid YAML'):
        params.load_param_file(bad)
    with pytest.raises(ConfigError, match='cannot read'):
        params.load_param_file(tmp_path / 'missing.yaml')


def test_cross_node_checks():
    assert 'wbc.control_rate = 200.0 (/tmp/x.yaml) disagrees with sim.control_period' in _error(
        'wbc:\n  ros__parameters:\n    control_rate: 200.0\n')
    check_run([_source('wbc:\n  ros__parameters:\n    control_rate: 500.0\n'
                       'sim:\n  ros__parameters:\n    control_period: 0.002\n')], NODES)
    assert 'sim.command_timeout = 1.0 (/tmp/x.yaml) must exceed wbc.plan_timeout' in _error(
        'sim:\n  ros__parameters:\n    command_timeout: 1.0\n')
    assert 'must be below' in _error('wbc:\n  ros__parameters:\n    fz_min: 900.0\n')
    assert 'must be at least' in _error('mpc:\n  ros__parameters:\n    horizon: 0.2\n'
                                        '    dt: 0.3\n')
    assert _error('mpc:\n  ros__parameters:\n    position_sway: 0.7\n'
                  '    position_weight: 0.0\n').startswith(
        'mpc.position_sway = 0.7 (/tmp/x.yaml) has no effect with mpc.position_weight = 0.0')
    check_run([_source('mpc:\n  ros__parameters:\n    position_sway: 0.5\n'
                       '    position_weight: 100.0\n')], NODES)
    crouched = '[-0.2, 0.9, -1.8, -0.2, 0.9, -1.8, -0.2, -0.9, 1.8, -0.2, -0.9, 1.8]'
    message = _error(f'sim:\n  ros__parameters:\n    standing_joint_positions: {crouched}\n')
    assert message.startswith('wbc.standing_joint_positions = [-0.2, 0.75, -1.5') and (
        'disagrees with sim.standing_joint_positions = [-0.2, 0.9, -1.8') in message, message
    check_run([_source(f'/**:\n  ros__parameters:\n    standing_joint_positions: {crouched}\n')],
              NODES)


def test_later_files_win_and_are_checked_in_order():
    sources = [_source('gait:\n  ros__parameters:\n    replan_window: 2\n', 'a.yaml'),
               _source('gait:\n  ros__parameters:\n    replan_window: 3\n', 'b.yaml')]
    resolved = resolve(sources, ['gait'])
    assert resolved.values['gait']['replan_window'] == 3
    assert resolved.where('gait', 'replan_window') == 'b.yaml'


def test_sources_from_a_node_command_line(tmp_path):
    path = tmp_path / 'p.yaml'
    path.write_text('gait:\n  ros__parameters:\n    replan_window: 2\n')
    argv = ['gait_node', '--ros-args', '-r', '__node:=gait', '--params-file', str(path),
            '-p', 'replan_window:=3', '-p', 'sequence:=[lf, rf, lh, rh]']
    sources = sources_from_argv(argv, 'gait')
    resolved = resolve(sources, ['gait'])
    assert resolved.values['gait']['replan_window'] == 3            # -p wins, as in rcl
    assert resolved.values['gait']['sequence'] == ['lf', 'rf', 'lh', 'rh']
    with pytest.raises(ConfigError, match=r'command line \(-p\): gait.replan_window = 0'):
        resolve(sources_from_argv([*argv, '-p', 'replan_window:=0'], 'gait'), ['gait'])


def _same_types(a, b) -> list[str]:
    """The fields of two dataclass instances whose types (arrays: dtype and shape) differ."""
    import numpy as np
    bad = []
    for item in dataclasses.fields(a):
        x, y = getattr(a, item.name), getattr(b, item.name)
        if isinstance(y, np.ndarray):
            same = isinstance(x, np.ndarray) and (x.dtype, x.shape) == (y.dtype, y.shape)
        else:
            same = type(x) is type(y)
        if not same:
            bad.append(item.name)
    return bad


@pytest.mark.parametrize('node, build, core', [
    ('gait', params.gait_params, 'replan_core.gait.crawl.GaitParams'),
    ('mpc', params.mpc_settings, 'replan_core.mpc.settings.MpcSettings'),
    ('wbc', params.wbc_params, 'replan_core.wbc.settings.WbcParams'),
    ('wbc', params.estimator_params, 'replan_core.estimation.settings.EstimatorParams'),
    ('wbc', params.protocol_params, 'replan_core.wbc.settings.ProtocolParams'),
    ('sim', params.actuator_params, 'replan_core.sim.settings.ActuatorParams'),
    ('sim', params.imu_noise_params, 'replan_core.sim.sensors.ImuNoiseParams'),
    ('sim', params.joint_sensor_params, 'replan_core.sim.sensors.JointSensorParams'),
    ('sim', params.terrain_settings, 'replan_core.sim.settings.TerrainSettings'),
    ('sim', params.world_settings, 'replan_core.sim.settings.WorldSettings'),
])
def test_each_core_dataclass_is_filled_from_its_table(node, build, core):
    """The one conversion (dataclass_from_params) fills every field from the table's defaults
    (or leaves it at the core's, when named fixed) with the core's types; the values are the
    table's (where the table's default is not the core's, e.g. mpc.velocity_weight)."""
    import importlib
    module, name = core.rsplit('.', 1)
    cls = getattr(importlib.import_module(module), name)
    built, table_defaults = build(params.defaults(node)), params.defaults(node)
    assert _same_types(built, cls()) == []
    if node == 'mpc':
        assert built.velocity_weight == table_defaults['velocity_weight'] == 300.0


def test_the_sims_world_settings_from_its_parameters():
    """The sim's one conversion: its defaults are the core's world (spawned in the table's
    standing pose); the terrain, spawn pose and actuators come from their own keys."""
    import dataclasses as dc

    from replan_core.common.types import STANDING_POSE
    from replan_core.sim.settings import ActuatorParams, TerrainSettings, WorldSettings
    values = params.defaults('sim')
    assert params.world_settings(values) == dc.replace(
        WorldSettings(), initial_joint_positions=tuple(STANDING_POSE.tolist()))
    pose = [0.1 * k for k in range(12)]
    world = params.world_settings({
        **values, 'terrain': 'rough', 'terrain_rough_amplitude': 0.05, 'terrain_width': 3,
        'standing_joint_positions': pose, 'initial_base_height': 0.7, 'seed': 4,
        'actuator_delay': 0.002, 'joint_viscous_damping': 0.1, 'contact_stiffness': 1.0e5})
    assert world.terrain == TerrainSettings(kind='rough', rough_amplitude=0.05, width=3.0)
    assert type(world.terrain.width) is float
    assert world.initial_joint_positions == tuple(pose)
    assert (world.initial_base_height, world.seed, world.contact_stiffness) == (0.7, 4, 1.0e5)
    assert world.actuator == ActuatorParams(delay=0.002, viscous_damping=0.1)


def test_dataclass_from_params_converts_and_refuses_a_field_without_parameter():
    import numpy as np

    @dataclasses.dataclass
    class Core:
        gain: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))
        rate: float = 1.0
        count: int = 2
        names: tuple = ('a',)
        solver: str = 'exact'

    built = params.dataclass_from_params(
        Core, {'x.gain': [1, 2], 'x.rate': 3, 'count_of': 4, 'x.names': ['b', 'c']},
        prefix='x.', names={'count': 'count_of'}, fixed=('solver',))
    assert built.gain.dtype == float and built.gain.tolist() == [1.0, 2.0]
    assert type(built.rate) is float and built.rate == 3.0
    assert built.count == 4 and built.names == ('b', 'c') and built.solver == 'exact'
    with pytest.raises(KeyError, match=r"Core.solver has no parameter 'x.solver'"):
        params.dataclass_from_params(
            Core, {'x.gain': [1, 2], 'x.rate': 3, 'count_of': 4, 'x.names': []}, prefix='x.',
            names={'count': 'count_of'})
    with pytest.raises(ValueError, match='stance_offsets needs 8 values'):
        params.gait_params({**params.defaults('gait'), 'stance_offsets': [0.0] * 6})
