"""Every node parameter in one place: default, unit, range, description (issue 15).

Each node declares its parameters from its table here (``declare_node_parameters``): the
descriptor carries the description, unit, range (``FloatingPointRange`` / ``IntegerRange``)
and ``read_only`` (the nodes read their parameters once at start). The launcher and the scenario
runner check every parameter file of a run against the same tables before anything starts
(``check_run``), and each node repeats the check on its own command line, so a bad value stops
the start with one line naming the file, the node, the key, the value and what is allowed:

    config error: /tmp/x.yaml: gait.replan_window = 0 is out of range [1, 8]

Where a core dataclass holds a default (``GaitParams``, ``MpcSettings``, ``WbcParams``,
``EstimatorParams``) the table takes it from there; the YAML files in
``config/`` only repeat values the user is meant to see and change (a unit test checks that
they equal these defaults).
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
import re
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from replan_core.types import LEGS

INF = math.inf
_INT_MAX = 2 ** 31 - 1
# Declared by rclpy itself in every node; allowed in every section.
BUILTIN = {'use_sim_time': bool, 'start_type_description_service': bool}
KINDS = ('bool', 'int', 'float', 'str', 'bool[]', 'int[]', 'float[]', 'str[]')
_SYNTAXES = {'': '', 'regex': 'a Python regular expression', 'json_object': 'a JSON object'}
_KIND_NAMES = {'bool': 'a bool', 'int': 'an int', 'float': 'a float (an int is accepted)',
               'str': 'a string', 'bool[]': 'a list of bools', 'int[]': 'a list of ints',
               'float[]': 'a list of floats (ints accepted)', 'str[]': 'a list of strings'}
RESTART_HINT = 'read once at start: change it in a parameter file and restart the node'


class ConfigError(ValueError):
    """A parameter file or value that must not start: one line, without 'config error: '."""


def _kind_of(value: Any) -> str:
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        return 'int'
    if isinstance(value, float):
        return 'float'
    if isinstance(value, str):
        return 'str'
    if isinstance(value, (list, tuple)) and value:
        return _kind_of(value[0]) + '[]'
    raise ValueError(f'cannot infer the kind of {value!r}: give kind=')


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: ``min``/``max`` bound a number or each element of a list; ``length``
    fixes a list's length; ``choices`` are the allowed strings (or list elements)."""

    name: str
    default: Any
    description: str
    unit: str = ''
    min: float | None = None
    max: float | None = None
    choices: tuple = ()
    read_only: bool = True
    length: int | None = None
    kind: str = ''
    syntax: str = ''          # a string's syntax when not empty: 'regex' or 'json_object'

    def __post_init__(self) -> None:
        if not self.kind:
            object.__setattr__(self, 'kind', _kind_of(self.default))
        if isinstance(self.default, tuple):
            object.__setattr__(self, 'default', list(self.default))
        assert self.kind in KINDS, self.kind
        assert self.syntax in _SYNTAXES, self.syntax

    @property
    def is_list(self) -> bool:
        return self.kind.endswith('[]')

    @property
    def element(self) -> str:
        return self.kind.removesuffix('[]')

    def allowed(self) -> str:
        """What the parameter accepts, in words."""
        parts = [_KIND_NAMES[self.kind]]
        if self.length is not None:
            parts.append(f'of {self.length} values')
        if self.choices:
            parts.append('one of ' + ', '.join(map(str, self.choices)))
        if self.syntax:
            parts.append(_SYNTAXES[self.syntax])
        if self.min is not None or self.max is not None:
            parts.append(f'in {self.range_text()}')
        return ' '.join(parts)

    def range_text(self) -> str:
        lo = '-inf' if self.min is None else _fmt(self.min)
        hi = 'inf' if self.max is None else _fmt(self.max)
        return f'[{lo}, {hi}]'

    def full_description(self) -> str:
        text = self.description + (f' [{self.unit}]' if self.unit else '')
        return text + (f' (read-only: {RESTART_HINT})' if self.read_only else '')


def _fmt(value: Any) -> str:
    """A value as the user wrote it (YAML-like)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return repr(value)
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_fmt(v) for v in value) + ']'
    return str(value)


def _p(name: str, default: Any, description: str, unit: str = '', **kw) -> ParamSpec:
    return ParamSpec(name, default, description, unit, **kw)


# ------------------------------------------------------------------------------ the tables
# GAIT, MPC and WBC take their defaults from the core's dataclasses, whose modules load
# pinocchio, proxsuite and scipy (60 MB): those tables are built on first use (_LazyTables), so
# the sim and the recorder, which read only their own, do not load them.
# As replan_core.sim_world (TERRAINS, STANDING_POSE, ActuatorParams' defaults), written out:
# importing it loads PyBullet, which prints to stdout and would spoil the launcher's one-line
# error. test_params.py checks that the two agree.
TERRAINS = ('flat', 'step_down', 'step_up', 'rough')
STANDING_POSE = (-0.2, 0.75, -1.5, -0.2, 0.75, -1.5, -0.2, -0.75, 1.5, -0.2, -0.75, 1.5)
_ACT = {'time_constant': 0.0, 'delay': 0.0, 'viscous_damping': 0.0,
                     'coulomb_friction': 0.0, 'torque_limit_scale': 1.0}
_URDF = "robot URDF; '' = $REPLAN_URDF, else <repo>/urdf/hyq.urdf"

def _gait_table() -> tuple[ParamSpec, ...]:
    from replan_core.gait import GaitParams  # lazy: see _LazyTables
    _G = GaitParams()
    return (
        _p('urdf_path', '', "robot URDF for the hip positions; '' = $REPLAN_URDF"),
        _p('swing_duration', _G.swing_duration, 'duration of one swing', 's', min=0.05, max=5.0),
        _p('four_feet_duration', _G.four_feet_duration, 'four feet on the ground before each swing',
           's', min=0.0, max=5.0),
        _p('step_height', _G.step_height, 'swing apex above the higher of lift-off and foothold',
           'm', min=0.0, max=0.4),
        _p('sequence', [LEGS[i] for i in _G.sequence],
           'crawl order, one swing leg at a time, each leg once', choices=tuple(LEGS), length=4),
        _p('stance_offsets', [float(v) for xy in _G.stance_offsets for v in xy],
           'nominal foot about its hip, base frame x, y per leg (lf rf lh rh)', 'm',
           min=-0.5, max=0.5, length=8),
        _p('max_step_length_x', _G.max_step_length_x,
           'max foot displacement per step along the body x axis', 'm', min=0.0, max=1.5),
        _p('max_step_length_y', _G.max_step_length_y,
           'max foot displacement per step along the body y axis', 'm', min=0.0, max=1.5),
        _p('max_linear_x', _G.max_linear_x, '|cmd_vel linear.x| clamp', 'm/s', min=0.0, max=2.0),
        _p('max_linear_y', _G.max_linear_y, '|cmd_vel linear.y| clamp', 'm/s', min=0.0, max=2.0),
        _p('max_angular_z', _G.max_angular_z, '|cmd_vel angular.z| clamp', 'rad/s', min=0.0,
           max=3.0),
        _p('cmd_vel_reject_above', 10.0, 'a cmd_vel component above this magnitude is absurd and '
           'rejected; smaller ones beyond the limits are clamped', 'm/s, rad/s', min=0.0, max=1e6,
           read_only=False),
        _p('cmd_vel_timeout', 0.5, 'no cmd_vel for this long: stand still (cmd_vel_stamped does '
           'not time out)', 'sim s', min=0.0, max=3600.0, read_only=False),
        _p('n_footholds', _G.n_footholds, 'steps per plan (paper: 8 over 8 s)', min=1, max=16),
        _p('replan_window', _G.replan_window, 're-plan at every K-th touchdown (paper: 1)', min=1,
           max=8),
        _p('haptic', _G.haptic, 'swings end at sensed contact (paper section V.A)'),
        _p('foothold_correction', _G.foothold_correction,
           'first foothold of each leg about the actual hip (paper section V.B)'),
        _p('correction_threshold', _G.correction_threshold, 'foothold correction moves a first '
           'foothold to the actual hip only when that differs from the foot-relative one by more '
           '(0: always)', 'm', min=0.0, max=1.0),
        _p('min_swing_fraction', 0.5, 'haptic touchdown accepted after this fraction of the '
           'planned swing (sent in footholds: the controller applies the same)', min=0.0, max=1.0),
        _p('max_extension', 0.3, 'haptic swing forced to end this long after its planned '
           'touchdown (sent in footholds)', 's', min=0.0, max=5.0),
        _p('start_delay', 1.0, 'first plan: stand this long before the first lift-off', 's',
           min=0.0, max=60.0),
        _p('idle_stance', _G.idle_stance, 'stand still (all four feet down, no step) after '
           'idle_after of zero set-point; false: step in place'),
        _p('idle_after', _G.idle_after, 'zero set-point for this long before the crawl stands '
           'still (default: one crawl cycle)', 'sim s', min=0.0, max=3600.0),
        _p('idle_replan_period', _G.idle_replan_period, 'while standing, re-plan this often (a '
           'zero-length trigger step, so a new set-point is picked up deterministically)', 's',
           min=0.05, max=5.0),
        _p('contacts_poll_period', 0.02, 'wall s between two reads of the queued contacts ticks; '
           'bounds the delay of a re-plan whose touchdown has no contact event', 's', min=0.001,
           max=1.0),
        _p('warn_period', 2.0, 'throttle of repeated warnings', 'wall s', min=0.0, max=3600.0,
           read_only=False),
    )

def _mpc_table() -> tuple[ParamSpec, ...]:
    from replan_core.mpc import MpcSettings  # lazy: see _LazyTables
    _M = MpcSettings()
    return (
        _p('urdf_path', '', "robot URDF for the CoM (pinocchio); '' = $REPLAN_URDF"),
        _p('dt', _M.dt, 'sampling = constant-jerk interval of the plan', 's', min=0.005, max=0.5),
        _p('horizon', _M.horizon, 'planning horizon (paper: 8 s)', 's', min=0.1, max=30.0),
        _p('com_height', _M.com_height, 'LIP CoM height above the mean stance foot height (eq. 1)',
           'm', min=0.05, max=2.0),
        _p('gravity', _M.gravity, 'gravity', 'm/s^2', min=0.1, max=30.0),
        _p('jerk_weight', _M.jerk_weight, 'R of eq. (6), weight of the squared jerk', min=1e-9,
           max=1e9),
        # The node's default: the core's 0 is the paper's plain jerk cost (config/mpc.yaml says
        # why).
        _p('velocity_weight', 300.0, 'weight of the velocity-tracking term (0 disables it)',
           min=0.0, max=1e9),
        _p('zmp_margin', 0.02, 'inward safety margin of the support polygons', 'm', min=0.0,
           max=0.2),
        _p('terminal_capture_point', _M.terminal_capture_point,
           'keep the capture point at the end of the horizon in the last polygon'),
        _p('eps_abs', _M.eps_abs, 'proxsuite absolute tolerance', min=1e-12, max=1.0),
        _p('max_iter', _M.max_iter, 'proxsuite iterations per QP solve', min=1, max=100000),
        _p('state_buffer', 20, 'joint_states / odom samples queued for the lookup (newest ones)',
           'messages', min=2, max=1000),
        _p('state_wait', 0.02, 'a request waits this long for the state of its stamp before it is '
           'left pending', 'wall s', min=0.0, max=10.0),
        _p('retry_period', 0.02, 'between two looks for a pending state', 'wall s', min=0.001,
           max=10.0),
        _p('state_fallback_window', 0.2, 'the state of a request that will never come (newer '
           'ones are here without it): plan from the oldest newer one if it is at most this '
           'much later, else drop the request; 0 = never', 'sim s', min=0.0, max=5.0),
        _p('warn_period', 2.0, 'throttle of repeated warnings', 'wall s', min=0.0, max=3600.0,
           read_only=False),
    )


def _gain(defaults: Any, name: str, description: str, unit: str) -> ParamSpec:
    return _p(name, getattr(defaults, name).tolist(), description, unit, min=0.0, max=1e6,
              length=3)


_ESTIMATOR_UNITS = {
    'contact_force_threshold': 'N', 'contact_release_threshold': 'N',
    'contact_debounce_ticks': 'ticks', 'jacobian_damping': 'm', 'foot_radius': 'm',
    'attitude_gain': '1/s', 'gyro_bias_gain': '1/s^2', 'gyro_bias_limit': 'rad/s',
    'accel_gate': 'm/s^2', 'accel_noise': 'm/s^2/sqrt(Hz)', 'base_position_noise': 'm/sqrt(s)',
    'foot_stance_noise': 'm/sqrt(s)', 'foot_swing_noise': 'm/sqrt(s)',
    'foot_position_noise': 'm', 'foot_velocity_noise': 'm/s', 'swing_velocity_noise': 'm/s',
    'initial_position_noise': 'm', 'initial_velocity_noise': 'm/s'}


def _estimator_specs() -> tuple[ParamSpec, ...]:
    """``estimator.<field>`` of ``EstimatorParams``, its defaults (the core is the source)."""
    from replan_core.estimator import EstimatorParams  # lazy: see _LazyTables

    defaults = EstimatorParams()
    specs = []
    for item in dataclasses.fields(EstimatorParams):
        value = getattr(defaults, item.name)
        value = value.tolist() if hasattr(value, 'tolist') else value
        low = 1 if isinstance(value, int) and not isinstance(value, bool) else 0.0
        high = 1000 if isinstance(value, int) and not isinstance(value, bool) else 1e6
        specs.append(_p(f'estimator.{item.name}', value,
                        f'state estimator: {item.name} (replan_core.estimator.EstimatorParams)',
                        _ESTIMATOR_UNITS.get(item.name, ''), min=low, max=high))
    return tuple(specs)


def _wbc_table() -> tuple[ParamSpec, ...]:
    from replan_core.wbc import WbcParams  # lazy: see _LazyTables
    _W = WbcParams()
    return (
        _p('urdf_path', '', _URDF),
        _p('control_rate', 250.0, 'the sim control tick rate, 1 / sim.control_period: stale-input '
           'check', 'Hz', min=1.0, max=10000.0),
        _p('plan_timeout', 2.0, 'wait this long for footholds + com_plan of a due re-plan; then go '
           'on with the old plans and report WARN', 'wall s', min=0.0, max=600.0, read_only=False),
        _p('missed_replans_to_stand', 2, 'this many due re-plans in a row without their plans '
           '(each after plan_timeout) mean a planner is gone, not slow: stand with the feet in '
           'place until a new plan pair arrives', 're-plans', min=1, max=1000),
        _p('stand_up_time', _W.stand_up_time, 'a robot that sat down (legs folded: the sim\'s '
           'damping mode) stands up in joint space along a minimum-jerk path to the standing '
           'pose in this time', 's', min=0.2, max=10.0),
        _p('stand_up_hold', _W.stand_up_hold, 'then holds the standing pose this long before '
           'the base estimate starts over and plans made from then on are adopted', 's',
           min=0.0, max=10.0),
        _p('stand_up_kp', _W.stand_up_kp, 'joint PD stiffness of the stand-up', 'N m/rad',
           min=0.0, max=5000.0),
        _p('stand_up_kd', _W.stand_up_kd, 'joint PD damping of the stand-up', 'N m s/rad',
           min=0.0, max=500.0),
        _p('standing_joint_positions', list(STANDING_POSE), 'the pose a robot that sat down '
           'stands up to, JOINT_NAMES order; must equal sim.standing_joint_positions (set both, '
           'or once in a /** section)', 'rad', min=-math.pi, max=math.pi, length=12),
        _p('sat_down_height', 0.1, 'legs this much shorter (median of the four, base above '
           'foot) than in the standing pose mean the robot sat down (the sim\'s damping mode): '
           'it stands up in joint space before it walks', 'm', min=0.01, max=0.5),
        _p('stand_adopt_age', 0.5, 'a stand ends only with a plan pair at most this old: one '
           'that waited while the sim ran on would start seconds into its schedule', 'sim s',
           min=0.004, max=10.0),
        _p('stand_adopt_lead', 0.1, 'a stand ends only with a plan whose first swing lifts off '
           'at least this long after its adoption, so that the CoM reaches the support of the '
           'other three feet first (a plan adopted after its lift-off tipped the robot over '
           'the swing leg)', 'sim s', min=0.0, max=10.0),
        _p('fall_tilt', _W.fall_tilt, 'a trunk tilted further than this from upright has '
           'fallen: joints damped, plans ignored, /diagnostics ERROR, until the wbc is '
           'restarted', 'rad', min=0.1, max=math.pi),
        _p('fall_time', 0.1, 'the trunk tilted beyond fall_tilt for this long (every tick) '
           'is a fall: one odd estimate is not', 'sim s', min=0.0, max=5.0),
        _p('fall_damping', _W.fall_damping, 'joint damping of a fallen robot', 'N m s/rad',
           min=0.0, max=500.0),
        _p('first_plan_timeout', 30.0, 'wait this long for the very first plans before standing',
           'wall s', min=0.0, max=3600.0),
        _p('plan_max_age', 6.0, 'a plan pair older than this (or past its horizon) -> stand',
           'sim s', min=0.0, max=60.0),
        _p('stale_ticks', 3, 'a gap of more than this many control periods between answered ticks '
           'means the inputs went stale: stand until a new plan', 'ticks', min=1, max=10000),
        _p('haptic_velocity', _W.haptic_velocity,
           'descent of a haptic swing foot after its planned touchdown', 'm/s', min=0.0, max=2.0),
        _p('touchdown_depth', _W.touchdown_depth,
           'a swing (haptic or not) aims this far below its foothold',
           'm', min=0.0, max=0.1),
        _gain(_W, 'com_kp', 'CoM PD stiffness x y z', '1/s^2'),
        _gain(_W, 'com_kd', 'CoM PD damping x y z', '1/s'),
        _gain(_W, 'trunk_kp', 'trunk orientation PD stiffness roll pitch yaw', '1/s^2'),
        _gain(_W, 'trunk_kd', 'trunk orientation PD damping roll pitch yaw', '1/s'),
        _gain(_W, 'swing_kp', 'swing foot stiffness x y z', 'N/m'),
        _gain(_W, 'swing_kd', 'swing foot damping x y z', 'N s/m'),
        _p('friction', _W.friction, 'friction coefficient of the force QP (inner pyramid mu / '
           'sqrt 2)', min=0.01, max=5.0),
        _p('fz_min', _W.fz_min, 'least normal force of a stance foot', 'N', min=0.0, max=1e4),
        _p('fz_max', _W.fz_max, 'largest normal force of a stance foot', 'N', min=1.0, max=1e5),
        _p('weight_force', _W.weight_force, 'QP weight of the force rows', '1/N^2', min=0.0,
           max=1e6),
        _p('weight_moment', _W.weight_moment, 'QP weight of the moment rows', '1/(N m)^2', min=0.0,
           max=1e6),
        _p('regularization', _W.regularization, 'QP weight of |f|^2', min=0.0, max=1e3),
        _p('fallback_kp', _W.fallback_kp, 'joint PD of the safe stand after a numerical failure',
           'N m/rad', min=0.0, max=1e5),
        _p('fallback_kd', _W.fallback_kd, 'same, damping', 'N m s/rad', min=0.0, max=1e4),
        _p('diagnostics_period', 1.0, 'between /diagnostics messages', 'wall s', min=0.01,
           max=3600.0),
        _p('state_estimation', False, "true: base pose and twist from the state estimator; false: "
           "the simulator's ground_truth/odom (ideal)"),
        _p('contact_estimation', False, "true: foot contacts from forces estimated from the joint "
           "torques; false: the simulator's ground_truth/contacts (ideal)"),
        _p('plan_latency', 0.0, 'from a re-plan trigger until its plans take effect (rounded up to '
           'control ticks)', 'sim s', min=0.0, max=0.99),
        _p('first_command_waits_for', [], 'nodes that must subscribe to odom, contacts and '
           'contact_events before the first command lets the sim move (the launcher sets the '
           "recorder's, so a bag holds the estimate from t = 0)", kind='str[]'),
        _p('first_command_wait_timeout', 10.0, 'longest wait for first_command_waits_for; '
           'then the first command goes out anyway, with a warning naming what is missing',
           'wall s', min=0.0, max=3600.0),
        *_estimator_specs(),
    )

SIM = (
    _p('urdf_path', '', _URDF),
    _p('physics_dt', 0.001, 'physics step', 's', min=1e-5, max=0.01),
    _p('control_period', 0.004, 'control tick (a multiple of physics_dt)', 's', min=1e-4,
       max=0.1),
    _p('clock_period', 0.02, '/clock period (a multiple of control_period)', 's', min=1e-4,
       max=1.0),
    _p('standing_joint_positions', list(STANDING_POSE),
       'spawn joint angles, JOINT_NAMES order', 'rad', min=-math.pi, max=math.pi, length=12),
    _p('initial_base_height', 0.0, 'spawn base_link height; 0 = feet touching the ground', 'm',
       min=0.0, max=3.0),
    _p('terrain', 'flat', 'terrain', choices=TERRAINS),
    _p('terrain_step_x', 0.6, 'step_down/step_up: x of the step edge', 'm', min=-10.0,
       max=10.0),
    _p('terrain_step_height', 0.1, 'step_down: drop, step_up: rise', 'm', min=0.0, max=1.0),
    _p('terrain_step_length', 2.0, 'step_up: box length along x', 'm', min=0.01, max=100.0),
    _p('terrain_width', 4.0, 'step_up/rough: extent along y', 'm', min=0.01, max=100.0),
    _p('terrain_rough_start_x', 0.6, 'rough: x where the heightfield begins', 'm', min=-10.0,
       max=10.0),
    _p('terrain_rough_length', 4.0, 'rough: extent along x', 'm', min=0.01, max=100.0),
    _p('terrain_rough_amplitude', 0.03, 'rough: heights uniform in [0, amplitude]', 'm',
       min=0.0, max=0.5),
    _p('terrain_rough_resolution', 0.05, 'rough: cell size', 'm', min=0.005, max=1.0),
    _p('seed', 0, 'rough: heightfield seed', min=0, max=_INT_MAX),
    _p('friction', 0.8, 'foot/ground Coulomb friction coefficient', min=0.0, max=5.0),
    _p('contact_stiffness', 0.0, 'foot contact stiffness; 0 = rigid (PyBullet)', 'N/m',
       min=0.0, max=1e9),
    _p('contact_damping', 0.0, 'foot contact damping (with contact_stiffness)', 'N s/m',
       min=0.0, max=1e7),
    _p('actuator_time_constant', _ACT['time_constant'],
       'first-order lag of the torque loop; 0 = none', 's', min=0.0, max=1.0),
    _p('actuator_delay', _ACT['delay'], 'transport delay of the torque command; 0 = none',
       's', min=0.0, max=1.0),
    _p('joint_viscous_damping', _ACT['viscous_damping'], 'joint viscous friction',
       'N m s/rad', min=0.0, max=100.0),
    _p('joint_coulomb_friction', _ACT['coulomb_friction'], 'joint Coulomb friction', 'N m',
       min=0.0, max=100.0),
    _p('torque_limit_scale', _ACT['torque_limit_scale'],
       'actuator torque limits, times the URDF effort limits', min=0.01, max=10.0),
    _p('imu_gyro_noise_density', 0.0, 'gyro white noise', 'rad/s/sqrt(Hz)', min=0.0, max=1.0),
    _p('imu_gyro_bias_random_walk', 0.0, 'gyro bias random walk', 'rad/s^2/sqrt(Hz)', min=0.0,
       max=1.0),
    _p('imu_gyro_initial_bias', 0.0, 'gyro bias at start, std per axis', 'rad/s', min=0.0,
       max=1.0),
    _p('imu_accel_noise_density', 0.0, 'accelerometer white noise', 'm/s^2/sqrt(Hz)', min=0.0,
       max=10.0),
    _p('imu_accel_bias_random_walk', 0.0, 'accelerometer bias random walk', 'm/s^3/sqrt(Hz)',
       min=0.0, max=10.0),
    _p('imu_accel_initial_bias', 0.0, 'accelerometer bias at start, std per axis', 'm/s^2',
       min=0.0, max=10.0),
    _p('encoder_counts_per_rev', 0, 'joint encoder resolution; 0 = exact', 'counts/rev',
       min=0, max=_INT_MAX),
    _p('joint_position_noise', 0.0, 'joint position noise (std)', 'rad', min=0.0, max=1.0),
    _p('joint_velocity_noise', 0.0, 'joint velocity noise (std)', 'rad/s', min=0.0, max=10.0),
    _p('joint_torque_noise', 0.0, 'joint torque sensor noise (std)', 'N m', min=0.0, max=100.0),
    _p('payload_mass', 0.0, 'payload fixed to the trunk, unknown to the controller', 'kg',
       min=0.0, max=100.0),
    _p('payload_offset', [0.0, 0.0, 0.0], 'payload position in base_link', 'm', min=-1.0,
       max=1.0, length=3),
    _p('leg_mass_error', 0.0, 'leg link masses off by up to this fraction (seeded)', min=0.0,
       max=0.9),
    _p('noise_seed', 0, 'seed of the sensor noise and the leg mass errors', min=0,
       max=_INT_MAX),
    _p('contact_threshold', 30.0, 'normal force for contact', 'N', min=0.0, max=1e4),
    _p('debounce_ticks', 2, 'ticks the force must stay above/below the threshold', 'ticks',
       min=1, max=100),
    _p('lock_step', True, 'advance one tick per joint_torque_cmd of the current stamp'),
    _p('stop_time', 0.0, 'step no further than the first tick at or after this sim time and '
       'hold there (the state republished as while waiting), so a run of a given duration '
       'ends at the same tick every time; 0 = run until stopped', 's', min=0.0, max=1e9),
    _p('republish_period', 0.1, 'lock-step: republish the state after this long without its '
       'command', 'wall s', min=0.001, max=10.0),
    _p('command_timeout', 3.0, "without a command this long: damping mode (above the "
       "controller's plan_timeout)", 'wall s', min=0.01, max=600.0),
    _p('damping_gain', 40.0, 'controller-dead joint damping', 'N m s/rad', min=0.0, max=1000.0,
       read_only=False),
    _p('damping_abduction_stiffness', 200.0, 'controller-dead: the abduction (HAA) joints are '
       'held at the standing pose\'s angle with this stiffness, so that the legs fold under '
       'the trunk instead of splaying (damping alone let the robot roll over)', 'N m/rad',
       min=0.0, max=5000.0, read_only=False),
    _p('real_time_factor', 1.0, 'free-run/damping: sim s per wall s to aim for', min=0.001,
       max=1000.0),
    _p('gui', False, 'open the PyBullet GUI'),
    _p('diagnostics_period', 1.0, '/diagnostics period', 'wall s', min=0.01, max=3600.0),
)

# The recorder (recorder_node.py) declares these through declare_node_parameters, as every node.
RECORDER = (
    _p('output', '', "bag file (*.mcap) or directory; '' = output_dir"),
    _p('output_dir', '', "directory for <dir>/replan_<date>_<time>.mcap; both '' = ./runs/"),
    _p('topics', [], 'exact topic names to record', kind='str[]'),
    _p('topics_regex', '', 'also record topics whose name matches this regex', syntax='regex'),
    _p('exclude_regex', '', 'never record topics matching this regex', syntax='regex'),
    _p('include_hidden', False, 'record hidden topics too'),
    _p('discovery_period', 0.5, 'graph poll for new topics', 's', min=0.01, max=60.0),
    _p('queue_depth', 1000, 'history depth of each subscription', 'messages', min=1,
       max=1_000_000),
    _p('take_period', 0.1, 'take and write the queued messages this often', 'wall s',
       min=0.001, max=10.0),
    _p('chunk_size', 1 << 20, 'close a chunk at this size (uncompressed)', 'bytes', min=1024,
       max=_INT_MAX),
    _p('chunk_interval', 1.0, 'close a chunk at least this often', 'wall s', min=0.01,
       max=3600.0),
    _p('compression', 'zstd', 'chunk compression', choices=('zstd', 'lz4', 'none')),
    _p('publish_time', 'source', 'mcap publish_time', choices=('source', 'header', 'receive')),
    _p('log_time_clock', 'sim', "mcap log_time's clock: sim = the newest /clock taken (read "
       "on demand with the recorded topics, so use_sim_time stays false), wall = the system "
       'clock (a real robot)', choices=('sim', 'wall')),
    _p('config_files', [], 'parameter YAML files of the run, stored in the bag', kind='str[]'),
    _p('scenario_file', '', 'scenario file of the run, stored in the bag'),
    _p('metadata_json', '', 'JSON object of extra key/values stored in the bag',
       syntax='json_object'),
    _p('diagnostics_period', 1.0, '/diagnostics status period', 's', min=0.01, max=3600.0),
)

# The live view (live_view.py): the graph over a Foxglove WebSocket, off the critical path.
LIVE_VIEW = (
    _p('host', '127.0.0.1', 'address to serve on; 127.0.0.1 = this machine only (ssh -L from '
       'elsewhere), 0.0.0.0 = every interface'),
    _p('port', 8765, 'WebSocket port; 0 = any free port (logged)', min=0, max=65535),
    _p('take_period', 0.05, "look at the graph's topics this often: the highest rate of a "
       'high-rate topic sent to viewers', 'wall s', min=0.005, max=5.0),
    _p('discovery_period', 1.0, 'graph poll for new topics', 'wall s', min=0.05, max=60.0),
    _p('view_period', 0.04, 'at most one /tf, force markers and velocity error per this much '
       'sim time', 's', min=0.004, max=10.0),
    _p('force_scale', 0.001, 'length of a contact force arrow per newton', 'm/N', min=0.0,
       max=1.0),
    _p('client_topics', ['cmd_vel'], 'geometry_msgs/Twist topics that viewers may publish on '
       '(Foxglove Teleop panel)', kind='str[]'),
    _p('queue_size', 500, 'frames queued per viewer before the oldest are dropped', 'frames',
       min=1, max=1_000_000),
    _p('urdf_path', '', _URDF),
)


class _LazyTables(Mapping):
    """node -> its table, each built on first use: the sim's process must not import the
    core modules behind the other tables (pinocchio: the sim's peak memory went from 112 to
    172 MB when they were imported here eagerly)."""

    def __init__(self, builders: dict[str, Callable[[], tuple[ParamSpec, ...]]]) -> None:
        self._builders = builders
        self._built: dict[str, tuple[ParamSpec, ...]] = {}

    def __getitem__(self, node: str) -> tuple[ParamSpec, ...]:
        if node not in self._built:
            self._built[node] = self._builders[node]()
        return self._built[node]

    def __contains__(self, node: object) -> bool:      # without building the table
        return node in self._builders

    def __iter__(self):
        return iter(self._builders)

    def __len__(self) -> int:
        return len(self._builders)


TABLES: Mapping[str, tuple[ParamSpec, ...]] = _LazyTables({
    'sim': lambda: SIM, 'gait': _gait_table, 'mpc': _mpc_table, 'wbc': _wbc_table,
    'recorder': lambda: RECORDER, 'live_view': lambda: LIVE_VIEW})
_TABLE_NAMES = {'GAIT': 'gait', 'MPC': 'mpc', 'WBC': 'wbc'}


def __getattr__(name: str) -> tuple[ParamSpec, ...]:
    """``params.GAIT``, ``params.MPC``, ``params.WBC``: built on first use (PEP 562)."""
    if name in _TABLE_NAMES:
        return TABLES[_TABLE_NAMES[name]]
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def table(node: str) -> dict[str, ParamSpec]:
    return {spec.name: spec for spec in TABLES[node]}


def defaults(node: str) -> dict[str, Any]:
    return {spec.name: spec.default for spec in TABLES[node]}


def dataclass_from_params(cls: type, values: Mapping[str, Any], *, prefix: str = '',
                          names: Mapping[str, str] | None = None,
                          convert: Mapping[str, Callable[[Any], Any]] | None = None,
                          fixed: Iterable[str] = ()) -> Any:
    """A core dataclass (``cls``, every field with a default) from a node's checked parameter
    values: field ``f`` takes ``values[names.get(f, prefix + f)]``, converted by
    ``convert[f]`` or to the type of the field's default (a numpy array becomes a float
    array, a tuple a tuple). The fields in ``fixed`` are not parameters: they keep the core's
    default. Any other field without its parameter is a KeyError naming it, so a field added
    to the core cannot miss its parameter table unnoticed. ValueError from a converter passes
    through (the node reports it as a config error)."""
    import numpy as np

    names, convert, fixed = names or {}, convert or {}, set(fixed)
    defaults_ = cls()
    kwargs = {}
    for item in dataclasses.fields(cls):
        if item.name in fixed:
            continue
        key = names.get(item.name, prefix + item.name)
        if key not in values:
            raise KeyError(f'{cls.__name__}.{item.name} has no parameter {key!r} (and is not '
                           'one of the fixed fields)')
        value = values[key]
        if item.name in convert:
            kwargs[item.name] = convert[item.name](value)
            continue
        default = getattr(defaults_, item.name)
        if isinstance(default, np.ndarray):
            kwargs[item.name] = np.array(value, dtype=float)
        elif isinstance(default, (tuple, list, bool, int, float, str)):
            kwargs[item.name] = type(default)(value)
        else:
            kwargs[item.name] = value
    return cls(**kwargs)



# How each node's checked values fill the core's dataclasses (dataclass_from_params); the core
# modules are imported here on use, as for the tables (_LazyTables).
# The MpcSettings fields that are not node parameters: the solver's internals, the core's
# defaults (scripts/bench_mpc.sh compares the alternatives).
MPC_FIXED = ('formulation', 'warm_start', 'violation_tol', 'slack_weight', 'max_rounds',
             'drop_inactive', 'add_peaks_only', 'working_set_tol', 'dual_mu_in',
             'iteration_budget', 'exact_dual')


def _stance_offsets(values) -> tuple:
    offsets = [float(v) for v in values]
    if len(offsets) != 8:
        raise ValueError('stance_offsets needs 8 values (x, y per leg)')
    return tuple((offsets[2 * i], offsets[2 * i + 1]) for i in range(4))


def gait_params(values: Mapping[str, Any]):
    """``GaitParams`` of the gait node (leg names to indices, offsets to pairs; the hip
    offsets are the core's)."""
    from replan_core.gait import GaitParams
    return dataclass_from_params(GaitParams, values, fixed=('hip_offsets',), convert={
        'sequence': lambda names: tuple(LEGS.index(str(n).lower()) for n in names),
        'stance_offsets': _stance_offsets})


def mpc_settings(values: Mapping[str, Any]):
    """``MpcSettings`` of the mpc node."""
    from replan_core.mpc import MpcSettings
    return dataclass_from_params(MpcSettings, values, fixed=MPC_FIXED)


def wbc_params(values: Mapping[str, Any]):
    """``WbcParams`` of the wbc node (the force QP's solver settings are the core's)."""
    from replan_core.wbc import WbcParams
    return dataclass_from_params(WbcParams, values, fixed=('qp_max_iter', 'qp_eps_abs'))


def estimator_params(values: Mapping[str, Any]):
    """``EstimatorParams`` of the wbc node (``estimator.<field>``)."""
    from replan_core.estimator import EstimatorParams
    return dataclass_from_params(EstimatorParams, values, prefix='estimator.')


def actuator_params(values: Mapping[str, Any]):
    """``ActuatorParams`` of the sim node."""
    from replan_core.sim_world import ActuatorParams
    return dataclass_from_params(ActuatorParams, values, names={
        'time_constant': 'actuator_time_constant', 'delay': 'actuator_delay',
        'viscous_damping': 'joint_viscous_damping', 'coulomb_friction': 'joint_coulomb_friction'})


def imu_noise_params(values: Mapping[str, Any]):
    """``ImuNoiseParams`` of the sim node (``imu_<field>``)."""
    from replan_core.sensors import ImuNoiseParams
    return dataclass_from_params(ImuNoiseParams, values, prefix='imu_')


def joint_sensor_params(values: Mapping[str, Any]):
    """``JointSensorParams`` of the sim node (``joint_<field>``)."""
    from replan_core.sensors import JointSensorParams
    return dataclass_from_params(JointSensorParams, values, prefix='joint_',
                                 names={'encoder_counts_per_rev': 'encoder_counts_per_rev'})


# ------------------------------------------------------------------------------ checking
def _suggest(name: str, known: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f' (did you mean {close[0]}?)' if close else ''


def _check_element(spec: ParamSpec, value: Any, kind: str) -> tuple[Any, str | None]:
    """(coerced value, None) or (value, reason) for one scalar of ``kind``."""
    if kind == 'bool':
        ok = isinstance(value, bool)
    elif kind == 'int':
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif kind == 'float':
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok:
            value = float(value)        # ROS's rule: an int is accepted for a float
            if not math.isfinite(value):
                return value, 'is not finite'
    else:
        ok = isinstance(value, str)
    if not ok:
        return value, f'has the wrong type: expected {_KIND_NAMES[spec.kind]}'
    if spec.choices and value not in spec.choices:
        return value, 'is not one of ' + ', '.join(map(str, spec.choices))
    if spec.syntax and value:
        reason = _syntax_error(spec.syntax, value)
        if reason:
            return value, reason
    if kind in ('int', 'float') and (
            (spec.min is not None and value < spec.min)
            or (spec.max is not None and value > spec.max)):
        return value, f'is out of range {spec.range_text()}'
    return value, None


def _syntax_error(syntax: str, text: str) -> str | None:
    """Why ``text`` is not a valid ``syntax`` string, or None."""
    if syntax == 'regex':
        try:
            re.compile(text)
        except re.error as err:
            return f'is not a valid regular expression ({err})'
        return None
    try:
        parsed = json.loads(text)
    except ValueError as err:
        return f'is not valid JSON ({err})'
    return None if isinstance(parsed, dict) else 'is not a JSON object ({...})'


def check_value(spec: ParamSpec, value: Any) -> Any:
    """The value, coerced to the spec's kind (int -> float); ConfigError with the reason."""
    if spec.is_list:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f'has the wrong type: expected {_KIND_NAMES[spec.kind]}')
        if spec.length is not None and len(value) != spec.length:
            raise ConfigError(f'has {len(value)} values: expected {spec.length}')
        out = []
        for item in value:
            item, reason = _check_element(spec, item, spec.element)
            if reason:
                raise ConfigError(f'has an element {_fmt(item)} that {reason}')
            out.append(item)
        return out
    value, reason = _check_element(spec, value, spec.kind)
    if reason:
        raise ConfigError(reason)
    return value


def _flatten(values: Mapping, prefix: str = '') -> dict[str, Any]:
    """``{estimator: {a: 1}}`` -> ``{'estimator.a': 1}`` (how rcl reads nested parameters)."""
    out = {}
    for key, value in values.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(_flatten(value, name + '.'))
        else:
            out[name] = value
    return out


def _section_node(section: str) -> str:
    return section.strip('/').split('/')[-1] if section not in ('/**', '**') else '**'


def parse_param_doc(doc: Any, label: str) -> dict[str, dict[str, Any]]:
    """A ROS parameter document -> {node: {name: value}} (nested names flattened, ``/**`` kept
    as ``**``); ConfigError for a malformed one."""
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{label}: the top level must map node names to sections')
    out: dict[str, dict[str, Any]] = {}
    for section, body in doc.items():
        if not isinstance(body, dict) or set(body) != {'ros__parameters'}:
            raise ConfigError(f'{label}: {section}: expected exactly one key ros__parameters '
                              f'under the node name')
        values = body['ros__parameters'] or {}
        if not isinstance(values, dict):
            raise ConfigError(f'{label}: {section}.ros__parameters must be a mapping')
        out.setdefault(_section_node(str(section)), {}).update(_flatten(values))
    return out


class _RosLoader(yaml.SafeLoader):
    """YAML as rcl reads parameter files: ``1.0e5`` is a float (YAML 1.1 wants ``1.0e+5``)."""


_RosLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'''^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$''', re.X),
    list('-+0123456789.'))


def load_yaml(text: str) -> Any:
    """A YAML document read the way rcl reads parameter files."""
    return yaml.load(text, Loader=_RosLoader)           # a SafeLoader subclass


def load_param_file(path: str | Path) -> dict[str, dict[str, Any]]:
    try:
        doc = load_yaml(Path(path).read_text())
    except OSError as err:
        raise ConfigError(f'{path}: cannot read: {err.strerror}') from err
    except yaml.YAMLError as err:
        line = str(err).replace('\n', ' ')
        raise ConfigError(f'{path}: not valid YAML: {line}') from err
    return parse_param_doc(doc, str(path))


@dataclass
class Source:
    """One parameter source of a run: a file (or a label) and its {node: {name: value}}."""

    label: str
    sections: dict[str, dict[str, Any]]
    nodes: tuple[str, ...] | None = None      # only these nodes read it (None: every node)


@dataclass
class Resolved:
    """Effective values per node, and where each came from ('default' or a source label)."""

    values: dict[str, dict[str, Any]] = field(default_factory=dict)
    origin: dict[str, dict[str, str]] = field(default_factory=dict)

    def where(self, node: str, name: str) -> str:
        return self.origin[node].get(name, 'default')


def resolve(sources: Sequence[Source], nodes: Iterable[str]) -> Resolved:
    """Check every key of every source against the tables (unknown node or key, type, range,
    choices) and merge them in order onto the defaults; ConfigError on the first problem."""
    nodes = list(nodes)
    result = Resolved()
    for node in nodes:
        result.values[node] = defaults(node)
        result.origin[node] = {}
    for source in sources:
        for section, values in source.sections.items():
            targets = nodes if section == '**' else [section]
            if section != '**' and section not in TABLES:
                raise ConfigError(f'{source.label}: {section} is not a node of the graph'
                                  f'{_suggest(section, TABLES)}; nodes: {", ".join(TABLES)}')
            for node in targets:
                if node not in result.values:
                    continue           # a node this run does not start (the recorder)
                if source.nodes is not None and node not in source.nodes:
                    continue
                specs = table(node)
                for name, value in values.items():
                    where = f'{source.label}: {node}.{name} = {_fmt(value)}'
                    if name in BUILTIN:
                        if not isinstance(value, BUILTIN[name]):
                            raise ConfigError(f'{where} has the wrong type: expected a bool')
                        continue
                    spec = specs.get(name)
                    if spec is None:
                        if section == '**':
                            continue   # a wildcard section may hold other nodes' keys
                        raise ConfigError(f'{where} is not a parameter of {node}'
                                          f'{_suggest(name, specs)}')
                    try:
                        result.values[node][name] = check_value(spec, value)
                    except ConfigError as err:
                        raise ConfigError(f'{where} {err}') from None
                    result.origin[node][name] = source.label
    for node in nodes:
        _node_checks(node, result)
    return result


def _value_at(resolved: Resolved, node: str, name: str) -> str:
    return (f'{node}.{name} = {_fmt(resolved.values[node][name])} '
            f'({resolved.where(node, name)})')


def _node_checks(node: str, r: Resolved) -> None:
    """Constraints between parameters of one node (also checked by the node itself)."""
    v = r.values[node]
    if node == 'gait' and sorted(v['sequence']) != sorted(LEGS):
        raise ConfigError(f'{r.where(node, "sequence")}: gait.sequence = {_fmt(v["sequence"])} '
                          f'must hold each leg of {", ".join(LEGS)} once')
    if node == 'mpc' and v['horizon'] < v['dt']:
        raise ConfigError(f'{_value_at(r, node, "horizon")} must be at least '
                          f'{_value_at(r, node, "dt")}')
    if node == 'wbc' and v['fz_min'] >= v['fz_max']:
        raise ConfigError(f'{_value_at(r, node, "fz_min")} must be below '
                          f'{_value_at(r, node, "fz_max")}')
    if node == 'sim' and v['control_period'] < v['physics_dt']:
        raise ConfigError(f'{_value_at(r, node, "control_period")} must be at least '
                          f'{_value_at(r, node, "physics_dt")}')


def cross_node_checks(r: Resolved) -> None:
    """Values that two nodes hold and that must agree (checked by the launcher)."""
    if 'sim' in r.values and 'wbc' in r.values:
        period, rate = r.values['sim']['control_period'], r.values['wbc']['control_rate']
        if not math.isclose(rate * period, 1.0, rel_tol=1e-6):
            raise ConfigError(f'{_value_at(r, "wbc", "control_rate")} disagrees with '
                              f'{_value_at(r, "sim", "control_period")}: control_rate must be '
                              f'1 / control_period = {1.0 / period:g}')
        sim_pose = r.values['sim']['standing_joint_positions']
        wbc_pose = r.values['wbc']['standing_joint_positions']
        if any(abs(a - b) > 1e-9 for a, b in zip(sim_pose, wbc_pose, strict=True)):
            raise ConfigError(f'{_value_at(r, "wbc", "standing_joint_positions")} disagrees with '
                              f'{_value_at(r, "sim", "standing_joint_positions")}: the robot '
                              'stands up to the pose it spawns in (set both, or once in /**)')
        timeout, plan = r.values['sim']['command_timeout'], r.values['wbc']['plan_timeout']
        if timeout <= plan:
            raise ConfigError(f'{_value_at(r, "sim", "command_timeout")} must exceed '
                              f'{_value_at(r, "wbc", "plan_timeout")}: a slow re-plan would '
                              'be taken for a dead controller')


def check_run(sources: Sequence[Source], nodes: Iterable[str]) -> Resolved:
    """The launcher's check of a whole run: every file, every node, then cross-node rules."""
    resolved = resolve(sources, nodes)
    cross_node_checks(resolved)
    return resolved


# ------------------------------------------------------------------------------ in a node
def sources_from_argv(argv: Sequence[str], node: str) -> list[Source]:
    """The parameter sources on a node's command line, in rcl's order of precedence: every
    ``--params-file`` in order, then every ``-p name:=value`` (they win)."""
    files: list[Source] = []
    overrides: dict[str, Any] = {}
    in_ros_args = False
    args = list(argv)
    i = 0
    while i < len(args):
        arg = args[i]
        if arg == '--ros-args':
            in_ros_args = True
        elif arg == '--':
            in_ros_args = False
        elif in_ros_args and arg == '--params-file' and i + 1 < len(args):
            i += 1
            files.append(Source(args[i], load_param_file(args[i])))
        elif in_ros_args and arg in ('-p', '--param') and i + 1 < len(args):
            i += 1
            key, sep, text = args[i].partition(':=')
            if not sep:
                raise ConfigError(f'command line: -p {args[i]}: expected name:=value')
            try:
                overrides[key] = load_yaml(text)
            except yaml.YAMLError:
                overrides[key] = text
        i += 1
    if overrides:
        files.append(Source('command line (-p)', {node: _flatten(overrides)}))
    return files


def declare_node_parameters(node, table_name: str | None = None,
                            on_change: Callable[[str, Any], None] | None = None,
                            argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Check the node's own parameter files and -p values against its table (a problem is
    logged as one ``config error:`` line and the process exits with code 2), declare every
    parameter with its descriptor (range, read-only, description with unit), and refuse
    run-time changes that are read-only or invalid. ``on_change(name, value)`` applies an
    accepted change of a writable parameter. Returns {name: value}."""
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        SetParametersResult,
    )

    name = table_name or node.get_name()
    try:
        sources = sources_from_argv(sys.argv if argv is None else argv, node.get_name())
        for source in sources:        # this process reads its own name's sections
            source.sections = {name if k == node.get_name() else k: v
                               for k, v in source.sections.items()
                               if k in (node.get_name(), '**')}
        values = resolve(sources, [name]).values[name]
    except ConfigError as err:
        node.get_logger().fatal(f'config error: {err}')
        raise SystemExit(2) from None
    specs = table(name)
    for spec in specs.values():
        descriptor = ParameterDescriptor(description=spec.full_description(),
                                         read_only=spec.read_only)
        constraints = []
        if spec.choices:
            constraints.append('one of ' + ', '.join(map(str, spec.choices)))
        if spec.length is not None:
            constraints.append(f'{spec.length} values')
        if spec.is_list and (spec.min is not None or spec.max is not None):
            constraints.append(f'each in {spec.range_text()}')
        descriptor.additional_constraints = '; '.join(constraints)
        if spec.kind == 'float' and (spec.min is not None or spec.max is not None):
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(-INF if spec.min is None else spec.min),
                to_value=float(INF if spec.max is None else spec.max), step=0.0)]
        elif spec.kind == 'int' and (spec.min is not None or spec.max is not None):
            descriptor.integer_range = [IntegerRange(
                from_value=int(-2 ** 63 if spec.min is None else spec.min),
                to_value=int(2 ** 63 - 1 if spec.max is None else spec.max), step=1)]
        # The value was checked above from the same files; rclpy's own override would refuse
        # an int for a float, which ROS files commonly hold.
        node.declare_parameter(spec.name, values[spec.name], descriptor, ignore_override=True)

    def on_set(parameters) -> SetParametersResult:
        for parameter in parameters:
            spec = specs.get(parameter.name)
            if spec is None:
                continue              # rclpy's own (use_sim_time)
            if spec.read_only:
                return SetParametersResult(successful=False, reason=(
                    f'{name}.{spec.name} is read-only: {RESTART_HINT}'))
            try:
                check_value(spec, parameter.value)
            except ConfigError as err:
                return SetParametersResult(successful=False, reason=(
                    f'{name}.{spec.name} = {_fmt(parameter.value)} {err}'))
        return SetParametersResult(successful=True)

    def post_set(parameters) -> None:
        for parameter in parameters:
            if parameter.name in specs and on_change is not None:
                on_change(parameter.name, parameter.value)

    node.add_on_set_parameters_callback(on_set)
    node.add_post_set_parameters_callback(post_set)
    return dict(values)
