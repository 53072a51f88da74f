"""The robot-dependent parameters of a robot, derived from a reference robot's tuned values by
the rules of ``config/robots/scaling.yaml`` (docs/robot_files.md, "Scaling rules").

value(R) = value(reference) * scale(R) / scale(reference), each scale measured on the models
(``robot_file.RobotFacts``): ``weight`` m g, ``leg_weight`` one leg's m_leg g, ``length`` the
leg length l, ``time`` sqrt(l / g),
``speed`` sqrt(g l), ``rate`` sqrt(g / l), ``torque`` m g l, ``stiffness`` m g / l, ``damping``
m sqrt(g / l), ``press_depth`` l m_leg / m (a leg's weight over the swing stiffness),
``joint_inertia`` the smallest joint inertia, ``position_cost`` l^-3; a list
parameter scales each value. ``actuator_kinds``: a parameter scaled by a figure of the robot
file's actuator kind (hydraulic, series-elastic, geared electric) over the reference's. Values
``measured`` on the model (CoM height, feet about the hips, foot frame height) are set, not
scaled.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from replan_core.common.types import GRAVITY
from replan_core.robot.robot_file import RobotFacts

SCALES = {
    'weight': lambda f: f.mass * GRAVITY,                    # N
    'leg_weight': lambda f: f.leg_mass * GRAVITY,            # N
    'length': lambda f: f.leg_length,                        # m
    'time': lambda f: math.sqrt(f.leg_length / GRAVITY),     # s
    'speed': lambda f: math.sqrt(GRAVITY * f.leg_length),    # m/s
    'rate': lambda f: math.sqrt(GRAVITY / f.leg_length),     # 1/s
    'torque': lambda f: f.mass * GRAVITY * f.leg_length,     # N m
    'stiffness': lambda f: f.mass * GRAVITY / f.leg_length,  # N/m
    'damping': lambda f: f.mass * math.sqrt(GRAVITY / f.leg_length),   # N s/m
    # leg_weight / stiffness: how far below the ground a swing must aim for its stiffness to
    # press the foot with the share of the contact threshold (a leg's weight) the reference's does
    'press_depth': lambda f: f.leg_mass * f.leg_length / f.mass,  # m
    'joint_inertia': lambda f: f.min_joint_inertia,          # kg m^2
    # a weight of a squared position against the squared jerk: (l / T^3)^2 / l^2, T ~ sqrt(l)
    'position_cost': lambda f: f.leg_length ** -3,           # 1/m^3
}
MEASURED = {
    'com_height': lambda f: float(f.com_height),
    'foot_height': lambda f: float(f.foot_height),
    'feet_about_hips': lambda f: [float(v) for v in np.asarray(f.feet_about_hips).ravel()],
    'com_about_feet': lambda f: [float(v) for v in np.asarray(f.com_about_feet).ravel()],
}


def _split(key: str) -> tuple[str, str]:
    """'wbc.estimator.contact_force_threshold' -> ('wbc', 'estimator.contact_force_threshold')."""
    node, _, name = key.partition('.')
    if not node or not name:
        raise ValueError(f'{key!r} is not node.parameter')
    return node, name


def derived_parameters(facts: RobotFacts, reference: RobotFacts,
                       reference_values: Mapping[str, Mapping], rules: Mapping,
                       measure: bool = True,
                       actuators: tuple[str, str] | None = None) -> dict:
    """node -> {parameter: value} for the robot of ``facts``: each parameter of
    ``rules['rules']`` scaled from ``reference_values`` (node -> {parameter: value}, the
    reference robot's), each of ``rules['measured']`` set from ``facts`` (with ``measure``;
    the reference robot itself keeps its files' tuned values: measure=False); with
    ``actuators`` (the robot's actuator kind, the reference's), each parameter of
    ``rules['actuator_kinds']`` scaled by its figure for the one kind over the other's.
    ValueError names an unknown scale, measurement, kind or parameter."""
    out: dict[str, dict] = {}

    def scaled(key: str, ratio: float) -> None:
        node, name = _split(key)
        if name not in reference_values.get(node, {}):
            raise ValueError(f'{key}: the reference has no such parameter')
        value = reference_values[node][name]
        out.setdefault(node, {})[name] = (
            [float(v) * ratio for v in value] if isinstance(value, (list, tuple))
            else float(value) * ratio)

    for scale, keys in rules.get('rules', {}).items():
        if scale not in SCALES:
            raise ValueError(f'unknown scale {scale!r} (known: {", ".join(SCALES)})')
        ratio = SCALES[scale](facts) / SCALES[scale](reference)
        for key in keys:
            scaled(key, ratio)
    for key, figures in (rules.get('actuator_kinds', {}) if actuators else {}).items():
        missing = [kind for kind in actuators if kind not in figures]
        if missing:
            raise ValueError(f'actuator_kinds.{key}: no figure for {", ".join(missing)}')
        # A profile without the dynamics (0, the ideal world) stays without them.
        scaled(key, float(figures[actuators[0]]) / float(figures[actuators[1]]))
    for key, what in (rules.get('measured', {}) if measure else {}).items():
        if what not in MEASURED:
            raise ValueError(f'{key}: unknown measurement {what!r} (known: '
                             f'{", ".join(MEASURED)})')
        node, name = _split(key)
        out.setdefault(node, {})[name] = MEASURED[what](facts)
    return out
