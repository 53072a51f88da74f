"""The robot of a run (docs/robot_files.md): what a node loads for the ``robot_file``
parameter (``node_robot``: the model and its names in the project's order) and the parameters
a launcher gives the nodes for a robot (``robot_layer``: the robot file itself, its standing
pose, the parameters derived by ``config/robots/scaling.yaml`` and the file's own
``parameters:``).

Topics keep the project's names (``replan_core.common.types``: legs lf rf lh rh, joints haa hfe
kfe): the sim and the controllers map the model's joints and feet to them by position in the robot
file's lists, so only the processes that load the model know its names.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from replan_core.common.types import BASE_FRAME, FOOT_FRAMES, JOINT_NAMES
from replan_core.robot.robot_file import (
    RobotFileError,
    RobotSpec,
    load_robot_file,
    robot_file_path,
)
from replan_ros.params.files import Source, _flatten
from replan_ros.params.spec import ConfigError

# The nodes that load the robot's model (the recorder and the live view to draw it).
ROBOT_NODES = ('sim', 'gait', 'mpc', 'wbc', 'live_view', 'recorder')
# The nodes whose standing pose is the robot's (spawn, and stand-up after a sit-down).
POSE_NODES = ('sim', 'wbc')
_SCALING = 'scaling.yaml'


def project_root() -> Path:
    """The repository (``$REPLAN_ROOT``, set by scripts/env.sh; else found from this file)."""
    env = os.environ.get('REPLAN_ROOT', '')
    return Path(env) if env else Path(__file__).resolve().parents[4]


def config_dir() -> Path:
    """The configuration folder (``$REPLAN_CONFIG``, else ``<root>/config``)."""
    env = os.environ.get('REPLAN_CONFIG', '')
    return Path(env) if env else project_root() / 'config'


@dataclass(frozen=True)
class NodeRobot:
    """The model a node loads and its names in the project's order."""

    urdf: str                        # the model (urdf_path if given, else the robot file's)
    joints: tuple[str, ...]          # 12 model joints, JOINT_NAMES order
    feet: tuple[str, ...]            # 4 model foot links, LEGS order
    root_link: str                   # the model's floating base
    spec: RobotSpec | None           # the robot file, if one was given

    def foot_contact(self) -> dict[str, Any]:
        """The robot file's foot sphere as ``SimWorld`` takes it (``foot_offset`` m,
        ``foot_radius`` m); none without a robot file (the model's own feet)."""
        if self.spec is None:
            return {}
        return {'foot_offset': self.spec.foot_offset, 'foot_radius': self.spec.foot_radius}


def node_robot(robot_file: str, urdf_path: str, default_urdf: str) -> NodeRobot:
    """What a node with parameters ``robot_file`` and ``urdf_path`` loads: the robot file's
    model and names (``urdf_path``, if set, replaces its URDF: a variant with the same
    names), or without one the project's names on ``urdf_path`` or ``default_urdf``.
    ConfigError (one line naming the file and key) for a robot file that cannot be used."""
    if not robot_file:
        return NodeRobot(urdf_path or default_urdf, JOINT_NAMES, FOOT_FRAMES, BASE_FRAME, None)
    try:
        spec = load_robot_file(robot_file_path(robot_file, config_dir()), project_root())
    except RobotFileError as err:
        raise ConfigError(str(err)) from None
    return NodeRobot(urdf_path or str(spec.urdf), spec.joints, spec.feet, spec.root_link, spec)


@dataclass
class RobotLayer:
    """A robot's parameters for a run, as two sources (derived, then the file's own
    ``parameters:``), and the parameter document that holds both."""

    name: str
    path: Path
    spec: RobotSpec
    derived: Source
    overrides: Source
    # Its standing height over the reference robot's (1.0 for the reference): what scales
    # the run's fall height (metrics.FallLimits).
    height_ratio: float = 1.0
    # Derives the robot's parameters from other reference values (a gait's): scaling.derived_
    # parameters with this robot's facts and rules.
    derive: Any = None

    def gait_values(self, reference_values: Mapping[str, Mapping[str, Any]],
                    keys) -> dict[str, Any]:
        """The gait node's ``keys`` for this robot from the reference robot's values of
        another gait (its layer on the node files and profile): scaled as the run's own."""
        derived = self.derive(reference_values).get('gait', {})
        return {key: _plain(derived.get(key, reference_values['gait'][key])) for key in keys}

    def document(self) -> dict:
        """The ROS parameter file of both sources (``estimator.x`` nested, as rcl reads it)."""
        doc: dict[str, Any] = {}
        for source in (self.derived, self.overrides):
            for node, values in source.sections.items():
                section = doc.setdefault(node, {'ros__parameters': {}})['ros__parameters']
                for key, value in values.items():
                    *parents, leaf = key.split('.')
                    target = section
                    for parent in parents:
                        target = target.setdefault(parent, {})
                    target[leaf] = value
        return doc

    def write(self, path: Path) -> Path:
        header = (f'# The robot of this run: {self.name} ({self.path}); written by the launcher '
                  '(replan_ros/params/robot.py): its standing pose, the parameters derived by '
                  'config/robots/scaling.yaml, then its file\'s own parameters.\n')
        path.write_text(header + yaml.safe_dump(self.document(), sort_keys=False))
        return path


def _plain(value: Any) -> Any:
    """Numbers as YAML writes and rcl reads them back exactly (no numpy scalars)."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, 'item'):
        return value.item()
    return value


def robot_layer(robot: str, configs: Path, root: Path,
                reference_values: Mapping[str, Mapping[str, Any]]) -> RobotLayer:
    """The parameters of ``robot`` (a name of ``configs/robots/`` or a robot file) for a run
    whose reference-robot values (node files and profile, resolved) are ``reference_values``.
    ConfigError with one line for an unknown name or a file that does not fit its model."""
    from replan_core.robot.robot_file import robot_facts  # pinocchio: only when launching
    from replan_core.robot.scaling import derived_parameters

    try:
        path = robot_file_path(robot, configs)
        spec = load_robot_file(path, root)
        rules_path = configs / 'robots' / _SCALING
        rules = yaml.safe_load(rules_path.read_text())
        reference = load_robot_file(robot_file_path(rules['reference'], configs), root)
    except RobotFileError as err:
        raise ConfigError(str(err)) from None
    except (OSError, yaml.YAMLError, KeyError, TypeError) as err:
        raise ConfigError(f'{configs / "robots" / _SCALING}: {err}') from None
    is_reference = spec.urdf == reference.urdf and spec.joints == reference.joints
    reference_facts = robot_facts(reference)
    facts = reference_facts if is_reference else robot_facts(spec)
    def derive(values: Mapping[str, Mapping[str, Any]]) -> dict:
        try:
            # The reference keeps its tuned values (a ratio of exactly 1, nothing measured).
            return derived_parameters(facts, reference_facts, values, rules,
                                      measure=not is_reference,
                                      actuators=(spec.actuator, reference.actuator))
        except ValueError as err:
            raise ConfigError(f'{rules_path}: {err}') from None

    derived = derive(reference_values)
    # A name stays a name (the run can be made again from its bag on another machine).
    given = robot if path.parent == configs / 'robots' and path.stem == robot else str(
        path.resolve())
    sections: dict[str, dict[str, Any]] = {}
    for node in ROBOT_NODES:
        sections[node] = {'robot_file': given}
    for node in POSE_NODES:
        sections[node]['standing_joint_positions'] = [float(v) for v in spec.standing_pose]
    for node, values in derived.items():
        sections.setdefault(node, {}).update({k: _plain(v) for k, v in values.items()})
    # Nested as in a parameter file (estimator: {x: ..}) or dotted (estimator.x), as rcl reads.
    overrides = {node: _flatten(values) for node, values in spec.parameters.items()}
    return RobotLayer(spec.name, path, spec,
                      Source(f'robot {spec.name} (derived: {rules_path.name})', sections),
                      Source(f'{path} (parameters)', overrides),
                      facts.standing_height / reference_facts.standing_height, derive)
