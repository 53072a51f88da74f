"""Benchmarks of the core algorithms (ROS-free), run from ``scripts/bench_*.sh``.

A bench runs the reference robot of ``config/robots/scaling.yaml`` (HyQ) with its own tuned
values, or another robot file with those values scaled by the same file's rules
(``bench_robots``).
"""

from __future__ import annotations

from pathlib import Path

import yaml

from replan_core.robot.robot_file import RobotFileError, RobotSpec, load_robot_file, robot_file_path

SCALING_FILE = Path('config') / 'robots' / 'scaling.yaml'


def scaling_rules(root: Path) -> dict:
    """``root``/config/robots/scaling.yaml: its ``reference`` robot and its rules.
    RobotFileError (one line naming the file) for a file that cannot be read."""
    path = Path(root) / SCALING_FILE
    try:
        rules = yaml.safe_load(path.read_text())
        if not isinstance(rules, dict) or not isinstance(rules.get('reference'), str):
            raise ValueError('no reference: robot name')
    except (OSError, yaml.YAMLError, ValueError) as err:
        raise RobotFileError(f'{path}: {err}') from None
    return rules


def bench_robots(robot: str, root: Path) -> tuple[RobotSpec, RobotSpec, dict]:
    """(the robot file ``robot``: a name of ``root``/config/robots/ or a path; the reference
    robot of scaling.yaml; its rules). RobotFileError names the file and key of a bad file."""
    root = Path(root)
    rules = scaling_rules(root)
    spec = load_robot_file(robot_file_path(robot or rules['reference'], root / 'config'), root)
    reference = load_robot_file(robot_file_path(rules['reference'], root / 'config'), root)
    return spec, reference, rules


def is_reference(spec: RobotSpec, reference: RobotSpec) -> bool:
    """``spec`` is the reference robot itself (it keeps the tuned values, as the launcher
    does)."""
    return spec.urdf == reference.urdf and spec.joints == reference.joints
