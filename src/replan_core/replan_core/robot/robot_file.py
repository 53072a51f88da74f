"""Robot files: one YAML file per robot (``config/robots/<name>.yaml``) says where its model
comes from and how its names map into the project's (docs/robot_files.md).

A file names the URDF (and optionally the SRDF) as a file of this project or a model of the
installed ``example-robot-data`` package (found through ``sys.path``, never a path of one
machine), the root link, per leg in the project's order ``lf rf lh rh`` the model's hip
abduction / hip flexion / knee joints and its foot frame, the foot's contact sphere, the
standing pose (12 values or the SRDF's ``standing`` group state), the actuator kind and node
parameter overrides. ``load_robot_file`` checks every name against the model and refuses a
file with one line naming the file and the key.

ROS-free; the facts measured on a loaded model (mass, leg length, standing height, the
smallest joint inertia) are ``robot_facts``'s.
"""

from __future__ import annotations

import math
import os
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from replan_core.common.types import LEGS

ACTUATOR_KINDS = ('hydraulic', 'series_elastic', 'geared_electric')
SOURCES = ('project', 'example-robot-data')
_KEYS = {'name', 'model', 'root_link', 'legs', 'foot_contact', 'standing_pose', 'actuator',
         'parameters'}
_MODEL_KEYS = {'source', 'urdf', 'srdf'}


# The model a run uses without a robot file: the reference robot's, under the project's root.
DEFAULT_URDF = Path('urdf') / 'hyq.urdf'


def default_urdf(*roots: str | Path) -> str:
    """The URDF of a run without a robot file: ``$REPLAN_URDF`` (scripts/env.sh sets it), else
    ``DEFAULT_URDF`` under the first of ``roots`` (project roots, e.g. the repository and an
    installed share) that holds it, else under the first root."""
    env = os.environ.get('REPLAN_URDF', '')
    if env:
        return env
    candidates = [Path(root) / DEFAULT_URDF for root in roots]
    return str(next((path for path in candidates if path.is_file()), candidates[0]))


class RobotFileError(ValueError):
    """A robot file that cannot be used; the message is one line naming file and key."""


@dataclass
class RobotSpec:
    """A robot as its file describes it, every name checked against its model."""

    name: str
    urdf: Path                               # the model's URDF
    srdf: Path | None                        # its SRDF, if the file names one
    root_link: str
    joints: tuple[str, ...]                  # 12 model joint names, JOINT_NAMES order
    feet: tuple[str, ...]                    # 4 model foot frames, LEGS order
    foot_radius: float                       # m, contact sphere radius
    foot_offset: np.ndarray                  # (3,) m, sphere centre in the foot frame
    standing_pose: np.ndarray                # (12,) rad, JOINT_NAMES order
    actuator: str                            # one of ACTUATOR_KINDS
    parameters: dict = field(default_factory=dict)   # node -> {parameter: value}


def example_robot_data_dir() -> Path:
    """The ``robots`` folder of the installed example-robot-data (its wheel ships a share
    tree under ``cmeel.prefix``, no Python module)."""
    for entry in sys.path:
        candidate = Path(entry) / 'cmeel.prefix' / 'share' / 'example-robot-data' / 'robots'
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError('example-robot-data is not installed (requirements.txt pins it)')


def _fail(label: str, key: str, problem: str) -> RobotFileError:
    return RobotFileError(f'robot file {label}: {key}: {problem}')


def _model_path(label: str, key: str, source: str, relative: str, project_root: Path) -> Path:
    base = project_root if source == 'project' else example_robot_data_dir()
    path = base / relative
    if not path.is_file():
        raise _fail(label, key, f'no file {relative!r} in {source} ({base})')
    return path


def _urdf_names(urdf: Path) -> tuple[set[str], set[str], dict[str, str], set[str]]:
    """Links, joints, each joint's type and the root links (no joint's child) of a URDF (its
    top-level elements: a ``<transmission>`` names joints too)."""
    root = ET.parse(urdf).getroot()
    links = {link.get('name') for link in root.findall('link')}
    types = {joint.get('name'): joint.get('type') for joint in root.findall('joint')}
    children = {child.get('link') for child in root.findall('joint/child')}
    return links, set(types), types, links - children


def srdf_standing_pose(srdf: Path, joints: tuple[str, ...], state: str = 'standing'
                       ) -> np.ndarray:
    """The joint values of the SRDF group state ``state``, in the order of ``joints``."""
    root = ET.parse(srdf).getroot()
    for group_state in root.iter('group_state'):
        if group_state.get('name') == state:
            values = {j.get('name'): j.get('value') for j in group_state.iter('joint')}
            missing = [j for j in joints if j not in values]
            if missing:
                raise KeyError(f'group state {state!r} of {srdf.name} lacks {missing}')
            return np.array([float(values[j]) for j in joints])
    raise KeyError(f'{srdf.name} has no group state {state!r}')


def robot_spec(doc: dict, label: str, project_root: Path) -> RobotSpec:
    """A ``RobotSpec`` from a parsed robot file ``doc`` (``label``: its path, for errors)."""
    if not isinstance(doc, dict):
        raise _fail(label, '(top)', 'not a mapping')
    unknown = sorted(set(doc) - _KEYS)
    if unknown:
        raise _fail(label, unknown[0], f'unknown key (known: {", ".join(sorted(_KEYS))})')
    for key in ('name', 'model', 'root_link', 'legs', 'foot_contact', 'standing_pose',
                'actuator'):
        if key not in doc:
            raise _fail(label, key, 'missing')
    model = doc['model']
    if not isinstance(model, dict) or set(model) - _MODEL_KEYS or 'urdf' not in model:
        raise _fail(label, 'model', 'needs source, urdf and optionally srdf')
    source = model.get('source', 'project')
    if source not in SOURCES:
        raise _fail(label, 'model.source', f'{source!r} is not one of {", ".join(SOURCES)}')
    urdf = _model_path(label, 'model.urdf', source, str(model['urdf']), project_root)
    srdf = (_model_path(label, 'model.srdf', source, str(model['srdf']), project_root)
            if model.get('srdf') else None)
    links, joint_names, joint_types, roots = _urdf_names(urdf)
    if doc['root_link'] not in links:
        raise _fail(label, 'root_link', f'no link {doc["root_link"]!r} in {urdf.name}')
    if doc['root_link'] not in roots:
        # PyBullet and pinocchio float the URDF's root link: the base the nodes report.
        raise _fail(label, 'root_link', f'{doc["root_link"]!r} is not the root link of '
                                        f'{urdf.name} ({", ".join(sorted(roots))})')
    legs = doc['legs']
    if not isinstance(legs, dict) or sorted(legs) != sorted(LEGS):
        raise _fail(label, 'legs', f'needs exactly the legs {", ".join(LEGS)}')
    joints, feet = [], []
    for leg in LEGS:
        entry = legs[leg]
        names = entry.get('joints') if isinstance(entry, dict) else None
        if not isinstance(names, list) or len(names) != 3:
            raise _fail(label, f'legs.{leg}.joints', 'needs 3 joints: haa, hfe, kfe')
        for k, name in enumerate(names):
            if name not in joint_names:
                raise _fail(label, f'legs.{leg}.joints[{k}]', f'no joint {name!r} in {urdf.name}')
            if joint_types[name] not in ('revolute', 'continuous'):
                raise _fail(label, f'legs.{leg}.joints[{k}]',
                            f'{name!r} is {joint_types[name]}, not revolute')
        if entry.get('foot') not in links:
            raise _fail(label, f'legs.{leg}.foot', f'no link {entry.get("foot")!r} in {urdf.name}')
        joints += names
        feet.append(entry['foot'])
    if len(set(joints)) != 12 or len(set(feet)) != 4:
        raise _fail(label, 'legs', 'a joint or foot is named twice')
    contact = doc['foot_contact']
    radius = contact.get('radius') if isinstance(contact, dict) else None
    offset = contact.get('offset', [0.0, 0.0, 0.0]) if isinstance(contact, dict) else None
    if not (isinstance(radius, (int, float)) and 0.0 < radius < 0.2):
        raise _fail(label, 'foot_contact.radius', 'needs a radius in (0, 0.2) m')
    if not (isinstance(offset, list) and len(offset) == 3
            and all(isinstance(v, (int, float)) and abs(v) < 0.2 for v in offset)):
        raise _fail(label, 'foot_contact.offset', 'needs 3 values within 0.2 m')
    pose = doc['standing_pose']
    if pose == 'srdf':
        if srdf is None:
            raise _fail(label, 'standing_pose', "'srdf' needs model.srdf")
        try:
            standing = srdf_standing_pose(srdf, tuple(joints))
        except KeyError as err:
            raise _fail(label, 'standing_pose', str(err.args[0])) from None
    elif (isinstance(pose, list) and len(pose) == 12
          and all(isinstance(v, (int, float)) and abs(v) <= math.pi for v in pose)):
        standing = np.array(pose, dtype=float)
    else:
        raise _fail(label, 'standing_pose', "needs 12 values within [-pi, pi] rad or 'srdf'")
    if doc['actuator'] not in ACTUATOR_KINDS:
        raise _fail(label, 'actuator', f'{doc["actuator"]!r} is not one of '
                                       f'{", ".join(ACTUATOR_KINDS)}')
    parameters = doc.get('parameters') or {}
    if not (isinstance(parameters, dict)
            and all(isinstance(v, dict) for v in parameters.values())):
        raise _fail(label, 'parameters', 'needs a mapping node -> {parameter: value}')
    return RobotSpec(str(doc['name']), urdf, srdf, str(doc['root_link']), tuple(joints),
                     tuple(feet), float(radius), np.array(offset, dtype=float), standing,
                     str(doc['actuator']), parameters)


def robot_file_path(robot: str, config_dir: str | Path) -> Path:
    """The robot file of ``robot``: a name of ``<config_dir>/robots/`` (``go1``) or a path to a
    YAML file; RobotFileError (one line, with the known names) for an unknown name."""
    if robot.endswith(('.yaml', '.yml')) or '/' in robot:
        return Path(robot)
    path = Path(config_dir) / 'robots' / f'{robot}.yaml'
    if robot == 'scaling' or not path.is_file():
        raise RobotFileError(f'unknown robot {robot!r} (known: '
                             f'{", ".join(robot_names(config_dir))}; or a robot file, '
                             'docs/robot_files.md)')
    return path


def robot_names(config_dir: str | Path) -> list[str]:
    """The robots of ``<config_dir>/robots/`` by name, sorted (not ``scaling.yaml``)."""
    return sorted(p.stem for p in (Path(config_dir) / 'robots').glob('*.yaml')
                  if p.stem != 'scaling')


def load_robot_file(path: str | Path, project_root: str | Path) -> RobotSpec:
    """Read and check the robot file at ``path`` (models of the project resolved against
    ``project_root``); RobotFileError with one line naming the file and key."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        detail = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise RobotFileError(f'robot file {path}: {detail}') from None
    return robot_spec(doc, str(path), Path(project_root))


@dataclass(frozen=True)
class RobotFacts:
    """What the model says about a robot standing in its standing pose."""

    mass: float                 # kg, total
    leg_mass: float             # kg, one leg: the links below its abduction joint (mean of 4)
    leg_length: float           # m, hip flexion axis to foot (thigh + shank), mean of 4 legs
    standing_height: float      # m, base origin above the ground under the feet's spheres
    com_height: float           # m, CoM above that ground
    foot_height: float          # m, foot frame origins above that ground (mean of 4 feet)
    min_joint_inertia: float    # kg m^2, smallest diagonal entry of the joint-space inertia
    feet_about_hips: np.ndarray  # (4, 2) m, each foot about its hip (haa axis), base frame xy
    feet_xy: np.ndarray         # (4, 2) m, each foot in the base frame xy
    com_about_feet: np.ndarray  # (2,) m, the CoM about the centre of the feet, base frame xy


def robot_facts(spec: RobotSpec) -> RobotFacts:
    """Measured on the model (pinocchio, free-flyer root) in the standing pose."""
    import pinocchio as pin

    from replan_core.robot.model import joint_id, link_frame_id

    model = pin.buildModelFromUrdf(str(spec.urdf), pin.JointModelFreeFlyer())
    data = model.createData()
    q = pin.neutral(model)
    for name, value in zip(spec.joints, spec.standing_pose, strict=True):
        q[model.joints[joint_id(model, name)].idx_q] = value
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    frames = [data.oMf[link_frame_id(model, f)] for f in spec.feet]
    feet = np.array([f.translation for f in frames])
    # The contact sphere's lowest point: its centre (offset in the foot frame) less the radius.
    soles = np.array([f.translation + f.rotation @ spec.foot_offset for f in frames])
    soles[:, 2] -= spec.foot_radius
    hips = np.array([data.oMi[joint_id(model, spec.joints[3 * k + 1])].translation
                     for k in range(4)])
    abductions = np.array([data.oMi[joint_id(model, spec.joints[3 * k])].translation
                           for k in range(4)])
    knees = np.array([data.oMi[joint_id(model, spec.joints[3 * k + 2])].translation
                      for k in range(4)])
    leg = np.linalg.norm(knees - hips, axis=1) + np.linalg.norm(feet - knees, axis=1)
    ground = float(soles[:, 2].mean())
    com = pin.centerOfMass(model, data, q)
    pin.computeSubtreeMasses(model, data)
    legs = [data.mass[joint_id(model, spec.joints[3 * k])] for k in range(4)]
    inertia = pin.crba(model, data, q)
    joint_rows = [model.joints[joint_id(model, n)].idx_v for n in spec.joints]
    return RobotFacts(mass=float(sum(i.mass for i in model.inertias)),
                      leg_mass=float(np.mean(legs)),
                      leg_length=float(leg.mean()),
                      standing_height=float(q[2] - ground),
                      com_height=float(com[2] - ground),
                      foot_height=float(feet[:, 2].mean() - ground),
                      min_joint_inertia=float(min(inertia[r, r] for r in joint_rows)),
                      feet_about_hips=feet[:, :2] - abductions[:, :2],
                      feet_xy=feet[:, :2] - q[:2],
                      com_about_feet=com[:2] - feet[:, :2].mean(axis=0))
