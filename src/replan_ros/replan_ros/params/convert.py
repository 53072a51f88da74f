"""From a node's checked parameter values to the core's dataclasses: ``dataclass_from_params``
fills any core dataclass field by field (a field without its parameter is an error, so a field
added to the core cannot miss its table unnoticed), and one function per dataclass says how
(``gait_params``, ``mpc_settings``, ``wbc_params``, ``protocol_params``, ``estimator_params``,
``actuator_params``, ``terrain_settings``, ``world_settings``, ``imu_noise_params``,
``joint_sensor_params``). The core's settings modules
it imports are numpy only: importing this module loads none of the core's solvers.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np

from replan_core.common.types import LEGS
from replan_core.estimation.settings import EstimatorParams
from replan_core.gait.crawl import GaitParams
from replan_core.mpc.settings import MpcSettings
from replan_core.sim.sensors import ImuNoiseParams, JointSensorParams
from replan_core.sim.settings import ActuatorParams, TerrainSettings, WorldSettings
from replan_core.wbc.settings import ProtocolParams, WbcParams


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


# How each node's checked values fill the core's dataclasses (dataclass_from_params).
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


def gait_params(values: Mapping[str, Any]) -> GaitParams:
    """``GaitParams`` of the gait node (leg names to indices, offsets to pairs, the sequence
    cut into steps of ``group_size`` legs; the hip offsets are the core's)."""
    params = dataclass_from_params(GaitParams, values, fixed=('hip_offsets', 'groups'), convert={
        'sequence': lambda names: tuple(LEGS.index(str(n).lower()) for n in names),
        'stance_offsets': _stance_offsets})
    size = int(values['group_size'])
    if size == 1:
        return params
    order = params.sequence
    groups = tuple(tuple(order[i:i + size]) for i in range(0, len(order), size))
    return dataclasses.replace(params, groups=groups)


def mpc_settings(values: Mapping[str, Any]) -> MpcSettings:
    """``MpcSettings`` of the mpc node."""
    return dataclass_from_params(MpcSettings, values, fixed=MPC_FIXED)


def wbc_params(values: Mapping[str, Any]) -> WbcParams:
    """``WbcParams`` of the wbc node (the force QP's solver settings are the core's)."""
    return dataclass_from_params(WbcParams, values, fixed=('qp_max_iter', 'qp_eps_abs'))


def protocol_params(values: Mapping[str, Any]) -> ProtocolParams:
    """``ProtocolParams`` of the wbc node (the controller's re-plan protocol)."""
    return dataclass_from_params(ProtocolParams, values)


def estimator_params(values: Mapping[str, Any]) -> EstimatorParams:
    """``EstimatorParams`` of the wbc node (``estimator.<field>``)."""
    return dataclass_from_params(EstimatorParams, values, prefix='estimator.')


def actuator_params(values: Mapping[str, Any]) -> ActuatorParams:
    """``ActuatorParams`` of the sim node."""
    return dataclass_from_params(ActuatorParams, values, names={
        'time_constant': 'actuator_time_constant', 'delay': 'actuator_delay',
        'viscous_damping': 'joint_viscous_damping', 'coulomb_friction': 'joint_coulomb_friction'})


def terrain_settings(values: Mapping[str, Any]) -> TerrainSettings:
    """``TerrainSettings`` of the sim node (``terrain`` and ``terrain_<size>``)."""
    return dataclass_from_params(TerrainSettings, values, prefix='terrain_',
                                 names={'kind': 'terrain'})


def world_settings(values: Mapping[str, Any]) -> WorldSettings:
    """``WorldSettings`` of the sim node: its spawn pose is ``standing_joint_positions``, its
    terrain and actuators as ``terrain_settings`` and ``actuator_params``."""
    world = dataclass_from_params(
        WorldSettings, values, fixed=('terrain', 'actuator'),
        names={'initial_joint_positions': 'standing_joint_positions'},
        convert={'initial_joint_positions': lambda pose: tuple(float(q) for q in pose)})
    return dataclasses.replace(world, terrain=terrain_settings(values),
                               actuator=actuator_params(values))


def imu_noise_params(values: Mapping[str, Any]) -> ImuNoiseParams:
    """``ImuNoiseParams`` of the sim node (``imu_<field>``)."""
    return dataclass_from_params(ImuNoiseParams, values, prefix='imu_')


def joint_sensor_params(values: Mapping[str, Any]) -> JointSensorParams:
    """``JointSensorParams`` of the sim node (``joint_<field>``)."""
    return dataclass_from_params(JointSensorParams, values, prefix='joint_',
                                 names={'encoder_counts_per_rev': 'encoder_counts_per_rev'})
