"""The per-node parameter tables: ``SIM``, ``RECORDER`` and ``LIVE_VIEW`` written out, and
``GAIT``, ``MPC`` and ``WBC`` (``estimator.<field>`` included), whose defaults come from the
core's settings (``GaitParams``, ``MpcSettings``, ``WbcParams``, ``ProtocolParams``,
``EstimatorParams``); the SIM table's terrains, standing pose, world (``WorldSettings``) and
actuator defaults are the core's too. The core's settings modules are numpy only, so importing
the tables loads neither pinocchio, proxsuite nor PyBullet. ``TABLES`` maps each node name to
its table, ``table`` and ``defaults`` give one node's specs and default values. The YAML files in
``config/`` only repeat values the user is meant to see and change (a unit test checks that they
equal these defaults).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from replan_core.common.types import LEGS, STANDING_POSE
from replan_core.estimation.settings import EstimatorParams
from replan_core.gait.crawl import CORRECTION_HIPS, GaitParams
from replan_core.mpc.settings import MpcSettings
from replan_core.sim.settings import (
    TERRAIN_DEFAULTS,
    TERRAINS,
    ActuatorParams,
    WorldSettings,
)
from replan_core.wbc.settings import ProtocolParams, WbcParams
from replan_ros.params.spec import ParamSpec

_INT_MAX = 2 ** 31 - 1


def _p(name: str, default: Any, description: str, unit: str = '', **kw) -> ParamSpec:
    return ParamSpec(name, default, description, unit, **kw)


_ACT = ActuatorParams()             # the sim's defaults: the core's settings
_WORLD = WorldSettings()
_TER = TERRAIN_DEFAULTS
_URDF = "robot URDF; '' = $REPLAN_URDF, else <repo>/urdf/hyq.urdf"
_ROBOT_FILE = _p(
    'robot_file', '', "robot file (docs/robot_files.md): a name of config/robots/ (go1) or a "
    "path; its model, and its joint and foot names mapped to the project's on the topics "
    "(a urdf_path replaces its model, same names); '' = urdf_path with the project's names. "
    'The launcher sets it (--robot), with the parameters derived for the robot')


_G = GaitParams()
GAIT = (
    _ROBOT_FILE,
    _p('urdf_path', '', "robot URDF for the hip positions; '' = $REPLAN_URDF"),
    _p('swing_duration', _G.swing_duration, 'duration of one swing', 's', min=0.05, max=5.0),
    _p('four_feet_duration', _G.four_feet_duration, 'four feet on the ground before each swing',
       's', min=0.0, max=5.0),
    _p('step_height', _G.step_height, 'swing apex above the higher of lift-off and foothold',
       'm', min=0.0, max=0.4),
    _p('gait', 'crawl', 'the start gait, a name of config/gaits/ (the launcher sets it '
       'with the gait file\'s values: --gait, a scenario\'s gait:)'),
    _p('gait_library', '', 'the gaits a run may switch to (gait_command): JSON, name -> '
       'the gait file\'s values scaled for the robot, as the launcher writes it; \'\' = '
       'the start gait only'),
    _p('sequence', [LEGS[i] for i in _G.sequence],
       'swing order, each leg once; group_size legs in a row swing together',
       choices=tuple(LEGS), length=4),
    _p('group_size', 1, 'legs per step: 1 = one at a time (the crawl), 2 = pairs of the '
       'sequence (a trot\'s diagonals)', choices=(1, 2)),
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
    _p('n_footholds', _G.n_footholds, 'steps per plan (paper: 8 over 8 s)', min=1, max=40),
    _p('replan_window', _G.replan_window, 're-plan at every K-th touchdown (paper: 1)', min=1,
       max=8),
    _p('haptic', _G.haptic, 'swings end at sensed contact (paper section V.A)'),
    _p('foothold_correction', _G.foothold_correction,
       'first foothold of each leg about the hip (paper section V.B; whose hip: '
       'correction_hips)'),
    _p('correction_threshold', _G.correction_threshold, 'a push: sway_free hips, the whole '
       'foot pattern follows them only when its common offset exceeds this (its shape is '
       'restored at every step); actual hips, a first foothold moves to the hip only when '
       'that differs from the foot-relative one by more (0: always)', 'm', min=0.0,
       max=1.0),
    _p('correction_hips', _G.correction_hips, 'foothold correction about the hips of: '
       'sway_free = the trunk\'s trend over the last crawl cycle (its sway averaged out); '
       'actual = the trunk now, sway included (docs/gait.md)', choices=CORRECTION_HIPS),
    _p('min_swing_fraction', 0.5, 'haptic touchdown accepted after this fraction of the '
       'planned swing (sent in footholds: the controller applies the same)', min=0.0, max=1.0),
    _p('max_extension', 0.3, 'haptic swing forced to end this long after its planned '
       'touchdown (sent in footholds)', 's', min=0.0, max=5.0),
    _p('plan_latency', 0.0, 'from a re-plan trigger until its plans take effect: the '
       'controller tracks the old plan until the first control tick at or after it, and the '
       "new plan's first lift-off waits for that tick (sent in footholds)", 'sim s', min=0.0,
       max=0.99),
    _p('start_delay', 1.0, 'first plan with a set-point already non-zero: stand this long '
       'before the first lift-off', 's', min=0.0, max=60.0),
    _p('idle_stance', _G.idle_stance, 'stand still (all four feet down, no step) until the '
       'first set-point and after idle_after of zero set-point; false: step in place'),
    _p('idle_after', _G.idle_after, 'zero set-point for this long before the crawl stands '
       'still (default: one crawl cycle)', 'sim s', min=0.0, max=3600.0),
    _p('idle_replan_period', _G.idle_replan_period, 'while standing, re-plan this often (a '
       'zero-length trigger step, so a new set-point is picked up deterministically)', 's',
       min=0.05, max=5.0),
    _p('velocity_feedback_gain', _G.velocity_feedback_gain, 'velocity feedback in foot '
       'placement: each re-plan adds gain * (set-point - the mean estimated velocity over the '
       'last crawl cycle) * dt to the stride correction (per cycle the remaining speed error '
       'shrinks by about 1 - gain); 0: off (docs/gait.md)', '1/cycle', min=0.0, max=1.0),
    _p('velocity_feedback_limit', _G.velocity_feedback_limit, 'largest stride correction of '
       'the velocity feedback', 'm', min=0.0, max=0.3),
    _p('velocity_feedback_max_error', _G.velocity_feedback_max_error, 'a cycle whose mean '
       'velocity misses the set-point by more than this is a disturbance (a push, a slip) '
       'and leaves the stride correction as it is', 'm/s', min=0.001, max=1.0),
    _p('measured_step_period', _G.measured_step_period, 'lay the strides out for the step '
       'period measured over the last cycle (the median touchdown interval: touchdowns come '
       'later than planned, and a stride planned for the planned period is walked slower); '
       'false: for the planned period (docs/gait.md, "Step timing")'),
    _p('contacts_poll_period', 0.02, 'wall s between two reads of the queued contacts ticks; '
       'bounds the delay of a re-plan whose touchdown has no contact event', 's', min=0.001,
       max=1.0),
    _p('warn_period', 2.0, 'throttle of repeated warnings', 'wall s', min=0.0, max=3600.0,
       read_only=False),
    _p('contacts_wait_warn', 10.0, 'warn (every warn_period) while no contacts tick has '
       'come this long after the start: a node the sim\'s contacts do not reach would '
       'otherwise wait silently', 'wall s', min=0.1, max=3600.0),
)


_M = MpcSettings()
MPC = (
    _ROBOT_FILE,
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
    # The node's defaults: the core's 0 is the paper's cost, without a position target
    # (config/mpc.yaml says why the node has one).
    _p('position_weight', 10000.0, 'weight of the CoM-over-its-feet term (0 disables it; '
       'not in the paper)', '1/m^2', min=0.0, max=1e9),
    _p('position_sway', 0.5, "the position term's reference: 0 the centre of the four "
       'feet, 1 the centroid of the feet in stance', min=0.0, max=1.0),
    # HyQ's, the reference robot's (its model measures 0.0393, 0.0151 m: a unit test
    # checks it); another robot's is measured on its model (config/robots/scaling.yaml).
    _p('com_offset', [0.0393, 0.0151], "the CoM about the centre of the feet in the "
       "standing pose, body frame x, y: added to the position term's reference, turned "
       'with the yaw reference', 'm', min=-0.5, max=0.5, length=2),
    _p('line_support_width', 0.02, 'width of the strip about the '
       'segment of two stance feet (a trot\'s diagonal) the ZMP stays in; 0: two feet are a '
       'degenerate polygon (docs/mpc.md, "Line support")', 'm', min=0.0, max=0.2),
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
    'initial_position_noise': 'm', 'initial_velocity_noise': 'm/s',
    'contact_observer_gain': '1/s'}
# Ranges narrower than the generic 0..1e6: the observer's gain must also stay below the control
# rate (gain * dt < 1, else one step overshoots), which the wbc node checks with its rate.
_ESTIMATOR_RANGES = {'contact_observer_gain': (0.0, 1000.0)}


def _estimator_specs() -> tuple[ParamSpec, ...]:
    """``estimator.<field>`` of ``EstimatorParams``, its defaults (the core is the source)."""
    defaults = EstimatorParams()
    specs = []
    for item in dataclasses.fields(EstimatorParams):
        value = getattr(defaults, item.name)
        value = value.tolist() if hasattr(value, 'tolist') else value
        low = 1 if isinstance(value, int) and not isinstance(value, bool) else 0.0
        high = 1000 if isinstance(value, int) and not isinstance(value, bool) else 1e6
        low, high = _ESTIMATOR_RANGES.get(item.name, (low, high))
        specs.append(_p(f'estimator.{item.name}', value,
                        f'state estimator: {item.name} '
                        '(replan_core.estimation.settings.EstimatorParams)',
                        _ESTIMATOR_UNITS.get(item.name, ''), min=low, max=high))
    return tuple(specs)


_W = WbcParams()
_P = ProtocolParams()   # one default each: the protocol's dataclass
WBC = (
    _ROBOT_FILE,
    _p('urdf_path', '', _URDF),
    _p('control_rate', _P.control_rate,
       'the sim control tick rate, 1 / sim.control_period: stale-input '
       'check', 'Hz', min=1.0, max=10000.0),
    _p('plan_timeout', 2.0, 'wait this long for footholds + com_plan of a due re-plan; then go '
       'on with the old plans and report WARN', 'wall s', min=0.0, max=600.0, read_only=False),
    _p('missed_replans_to_stand', _P.missed_replans_to_stand,
       'this many due re-plans in a row without their plans '
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
    _p('standing_joint_positions', STANDING_POSE.tolist(), 'the pose a robot that sat down '
       'stands up to, JOINT_NAMES order; must equal sim.standing_joint_positions (set both, '
       'or once in a /** section)', 'rad', min=-math.pi, max=math.pi, length=12),
    _p('sat_down_height', _P.sat_down_height,
       'legs this much shorter (median of the four, base above '
       'foot) than in the standing pose mean the robot sat down (the sim\'s damping mode): '
       'it stands up in joint space before it walks', 'm', min=0.01, max=0.5),
    _p('stand_adopt_age', _P.stand_adopt_age,
       'a stand ends only with a plan pair at most this old: one '
       'that waited while the sim ran on would start seconds into its schedule', 'sim s',
       min=0.004, max=10.0),
    _p('stand_adopt_lead', _P.stand_adopt_lead,
       'a stand ends only with a plan whose first swing lifts off '
       'at least this long after its adoption, so that the CoM reaches the support of the '
       'other three feet first (a plan adopted after its lift-off tipped the robot over '
       'the swing leg)', 'sim s', min=0.0, max=10.0),
    _p('fall_tilt', _W.fall_tilt, 'a trunk tilted further than this from upright has '
       'fallen: joints damped, plans ignored, /diagnostics ERROR, until the wbc is '
       'restarted', 'rad', min=0.1, max=math.pi),
    _p('fall_time', _P.fall_time,
       'the trunk tilted beyond fall_tilt for this long (every tick) '
       'is a fall: one odd estimate is not', 'sim s', min=0.0, max=5.0),
    _p('fall_damping', _W.fall_damping, 'joint damping of a fallen robot', 'N m s/rad',
       min=0.0, max=500.0),
    _p('first_plan_timeout', 30.0, 'wait this long for the very first plans before standing',
       'wall s', min=0.0, max=3600.0),
    _p('plan_max_age', _P.plan_max_age,
       'a plan pair older than this (or past its horizon) -> stand',
       'sim s', min=0.0, max=60.0),
    _p('stale_ticks', _P.stale_ticks,
       'a gap of more than this many control periods between answered ticks '
       'means the inputs went stale: stand until a new plan', 'ticks', min=1, max=10000),
    _p('haptic_velocity', _W.haptic_velocity,
       'descent of a haptic swing foot after its planned touchdown', 'm/s', min=0.0, max=2.0),
    _p('touchdown_depth', _W.touchdown_depth,
       'a haptic swing aims this far below its foothold (a non-haptic one at it)',
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
    _p('first_command_waits_for', [], 'nodes that must subscribe to odom, contacts, '
       'contact_events and joint_torque_cmd (an entry name=topic+topic: to those only) before '
       'the first estimate is published and the first command lets the sim move (the launcher '
       "sets the planners' and the recorder's: a restarted wbc is heard before the sim steps, "
       'and a bag holds the estimate and the commands from t = 0)', kind='str[]'),
    _p('first_command_wait_timeout', 10.0, 'longest wait for first_command_waits_for; '
       'then the first command goes out anyway, with a warning naming what is missing',
       'wall s', min=0.0, max=3600.0),
    *_estimator_specs(),
)


SIM = (
    _ROBOT_FILE,
    _p('urdf_path', '', _URDF),
    _p('physics_dt', _WORLD.physics_dt, 'physics step', 's', min=1e-5, max=0.01),
    _p('control_period', _WORLD.control_period, 'control tick (a multiple of physics_dt)', 's',
       min=1e-4, max=0.1),
    _p('clock_period', 0.02, '/clock period (a multiple of control_period)', 's', min=1e-4,
       max=1.0),
    _p('standing_joint_positions', STANDING_POSE.tolist(),
       'spawn joint angles, JOINT_NAMES order', 'rad', min=-math.pi, max=math.pi, length=12),
    _p('initial_base_height', _WORLD.initial_base_height,
       'spawn base_link height; 0 = feet touching the ground', 'm', min=0.0, max=3.0),
    _p('terrain', _WORLD.terrain.kind, 'terrain', choices=TERRAINS),
    _p('terrain_step_x', _TER['step_x'], 'step_down/step_up: x of the step edge', 'm',
       min=-10.0, max=10.0),
    _p('terrain_step_height', _TER['step_height'], 'step_down: drop, step_up: rise', 'm',
       min=0.0, max=1.0),
    _p('terrain_step_length', _TER['step_length'], 'step_up: box length along x', 'm',
       min=0.01, max=100.0),
    _p('terrain_width', _TER['width'], 'step_up/rough: extent along y', 'm', min=0.01,
       max=100.0),
    _p('terrain_rough_start_x', _TER['rough_start_x'], 'rough: x where the heightfield begins',
       'm', min=-10.0, max=10.0),
    _p('terrain_rough_length', _TER['rough_length'], 'rough: extent along x', 'm', min=0.01,
       max=100.0),
    _p('terrain_rough_amplitude', _TER['rough_amplitude'],
       'rough: heights uniform in [0, amplitude]', 'm', min=0.0, max=0.5),
    _p('terrain_rough_resolution', _TER['rough_resolution'], 'rough: cell size', 'm',
       min=0.005, max=1.0),
    _p('seed', _WORLD.seed, 'rough: heightfield seed', min=0, max=_INT_MAX),
    _p('friction', _WORLD.friction, 'foot/ground Coulomb friction coefficient', min=0.0,
       max=5.0),
    _p('contact_stiffness', _WORLD.contact_stiffness,
       'foot contact stiffness; 0 = rigid (PyBullet)', 'N/m', min=0.0, max=1e9),
    _p('contact_damping', _WORLD.contact_damping,
       'foot contact damping (with contact_stiffness)', 'N s/m', min=0.0, max=1e7),
    _p('actuator_time_constant', _ACT.time_constant,
       'first-order lag of the torque loop; 0 = none', 's', min=0.0, max=1.0),
    _p('actuator_delay', _ACT.delay, 'transport delay of the torque command; 0 = none',
       's', min=0.0, max=1.0),
    _p('joint_viscous_damping', _ACT.viscous_damping, 'joint viscous friction',
       'N m s/rad', min=0.0, max=100.0),
    _p('joint_coulomb_friction', _ACT.coulomb_friction, 'joint Coulomb friction', 'N m',
       min=0.0, max=100.0),
    _p('torque_limit_scale', _ACT.torque_limit_scale,
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
    _p('contact_threshold', _WORLD.contact_threshold, 'normal force for contact', 'N', min=0.0,
       max=1e4),
    _p('debounce_ticks', _WORLD.debounce_ticks,
       'ticks the force must stay above/below the threshold', 'ticks', min=1, max=100),
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
    _p('gui', _WORLD.gui, 'open the PyBullet GUI'),
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
    _p('queue_depth', 0, 'history of each subscription: 0 keeps all until taken (no loss), '
       'N the newest N (older ones lost when the recorder falls behind)', 'messages', min=0,
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
    _ROBOT_FILE,        # the robot the bag's /tf and /robot_description draw
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
    _ROBOT_FILE,
    _p('urdf_path', '', _URDF),
)


TABLES: Mapping[str, tuple[ParamSpec, ...]] = {
    'sim': SIM, 'gait': GAIT, 'mpc': MPC, 'wbc': WBC, 'recorder': RECORDER,
    'live_view': LIVE_VIEW}


def table(node: str) -> dict[str, ParamSpec]:
    return {spec.name: spec for spec in TABLES[node]}


def defaults(node: str) -> dict[str, Any]:
    return {spec.name: spec.default for spec in TABLES[node]}
