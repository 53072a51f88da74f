"""The simulator's merged copy of a model (replan_core.urdf_merge)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from replan_core.robot_file import load_robot_file
from replan_core.urdf_merge import _matrix_rpy, _rpy_matrix, merged_fixed_links

ROOT = Path(__file__).resolve().parents[3]


def _spec(name):
    return load_robot_file(ROOT / 'config' / 'robots' / f'{name}.yaml', ROOT)


def test_a_model_whose_only_fixed_links_are_its_feet_is_used_as_it_is():
    spec = _spec('hyq')
    assert merged_fixed_links(str(spec.urdf), keep=spec.feet) == str(spec.urdf)


@pytest.mark.parametrize('name', ['anymal_c', 'go1', 'b1'])
def test_merged_model_keeps_joints_and_feet_and_moves_as_the_original(name, tmp_path):
    """Every moving joint and foot is still there, every other fixed link is gone, and
    pinocchio finds the feet where it finds them in the original, at a random pose."""
    spec = _spec(name)
    path = merged_fixed_links(str(spec.urdf), keep=spec.feet, out_dir=str(tmp_path))
    assert Path(path).parent == tmp_path
    robot = ET.parse(path).getroot()
    fixed = [j.find('child').get('link') for j in robot.findall('joint')
             if j.get('type') == 'fixed']
    assert sorted(fixed) == sorted(spec.feet)
    moving = {j.get('name') for j in robot.findall('joint') if j.get('type') != 'fixed'}
    assert moving == set(spec.joints)

    models = [pin.buildModelFromUrdf(p, pin.JointModelFreeFlyer()) for p in (str(spec.urdf), path)]
    rng = np.random.default_rng(3)
    q_joints = spec.standing_pose + rng.uniform(-0.3, 0.3, 12)
    base = pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.2, 0.3), np.array([0.1, 0.2, 0.5]))
    feet = []
    for model in models:
        data = model.createData()
        q = pin.neutral(model)
        q[:7] = pin.SE3ToXYZQUAT(base)
        for joint, angle in zip(spec.joints, q_joints, strict=True):
            q[model.joints[model.getJointId(joint)].idx_q] = angle
        pin.framesForwardKinematics(model, data, q)
        feet.append(np.array([data.oMf[model.getFrameId(f)].translation for f in spec.feet]))
    np.testing.assert_allclose(feet[1], feet[0], atol=1e-12)
    # The same file for the same input: the name holds a hash of the content.
    assert merged_fixed_links(str(spec.urdf), keep=spec.feet, out_dir=str(tmp_path)) == path


@pytest.mark.parametrize('rpy', [(0.0, 0.0, 0.0), (0.3, -1.2, 2.9), (-3.0, 0.4, -0.1),
                                 (0.5, math.pi / 2, 0.2)])
def test_rpy_round_trip(rpy):
    rotation = _rpy_matrix(*rpy)
    np.testing.assert_allclose(rotation, pin.rpy.rpyToMatrix(*rpy), atol=1e-12)
    np.testing.assert_allclose(_rpy_matrix(*_matrix_rpy(rotation)), rotation, atol=1e-9)
