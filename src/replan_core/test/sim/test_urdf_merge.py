"""The simulator's copy of a model (replan_core.sim.urdf_merge)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from replan_core.robot.model import joint_id, link_frame_id
from replan_core.robot.robot_file import load_robot_file
from replan_core.sim.urdf_merge import _matrix_rpy, _rpy_matrix, simulator_model

ROOT = Path(__file__).resolve().parents[4]


def _spec(name):
    return load_robot_file(ROOT / 'config' / 'robots' / f'{name}.yaml', ROOT)


def test_a_model_whose_only_fixed_links_are_its_feet_is_used_as_it_is():
    """HyQ: nothing to merge, sphere feet, no mesh: its own file, so its runs do not change."""
    spec = _spec('hyq')
    assert simulator_model(str(spec.urdf), keep=spec.feet) == str(spec.urdf)
    assert simulator_model(str(spec.urdf), keep=spec.feet, visuals=False,
                           foot_sphere=(spec.foot_radius, spec.foot_offset)) == str(spec.urdf)


def _foot_collisions(path, feet):
    robot = ET.parse(path).getroot()
    return {name: [(c.find('geometry')[0].tag, c.find('geometry')[0].attrib,
                    c.find('origin').attrib if c.find('origin') is not None else {})
                   for c in robot.find(f"link[@name='{name}']").findall('collision')]
            for name in feet}


def test_a_mesh_foot_gets_the_robot_files_sphere_and_a_sphere_foot_keeps_its_own(tmp_path):
    """Go2's feet are convex meshes: each becomes the robot file's one sphere at its offset.
    Go1's are spheres of the model: left as they are, whatever sphere is asked for."""
    go2 = _spec('go2')
    assert {shape for shapes in _foot_collisions(str(go2.urdf), go2.feet).values()
            for shape, _, _ in shapes} == {'mesh'}
    path = simulator_model(str(go2.urdf), keep=go2.feet, out_dir=str(tmp_path),
                           foot_sphere=(go2.foot_radius, go2.foot_offset))
    for shapes in _foot_collisions(path, go2.feet).values():
        assert len(shapes) == 1
        shape, attributes, origin = shapes[0]
        assert shape == 'sphere' and float(attributes['radius']) == go2.foot_radius
        np.testing.assert_allclose([float(v) for v in origin['xyz'].split()], go2.foot_offset)
    go1 = _spec('go1')
    path = simulator_model(str(go1.urdf), keep=go1.feet, out_dir=str(tmp_path),
                           foot_sphere=(0.05, np.array([0.0, 0.0, 0.1])))
    assert (_foot_collisions(path, go1.feet)
            == _foot_collisions(simulator_model(str(go1.urdf), keep=go1.feet,
                                                out_dir=str(tmp_path)), go1.feet))


def test_without_a_window_the_copy_has_no_visual_mesh_and_the_same_dynamics(tmp_path):
    """Visual meshes cost memory in a simulator nobody watches; nothing else changes."""
    spec = _spec('go1')
    drawn = simulator_model(str(spec.urdf), keep=spec.feet, out_dir=str(tmp_path))
    headless = simulator_model(str(spec.urdf), keep=spec.feet, out_dir=str(tmp_path),
                               visuals=False)
    assert ET.parse(drawn).getroot().findall('.//visual/geometry/mesh')
    assert not ET.parse(headless).getroot().findall('.//visual/geometry/mesh')
    for tag in ('inertial', 'collision', 'joint'):
        assert (ET.tostring(ET.parse(drawn).getroot().find(f'.//{tag}'))
                == ET.tostring(ET.parse(headless).getroot().find(f'.//{tag}')))


@pytest.mark.parametrize('name', ['anymal_c', 'go1', 'b1', 'go2'])
def test_merged_model_keeps_joints_and_feet_and_moves_as_the_original(name, tmp_path):
    """Every moving joint and foot is still there, every other fixed link is gone, and
    pinocchio finds the feet where it finds them in the original, at a random pose."""
    spec = _spec(name)
    path = simulator_model(str(spec.urdf), keep=spec.feet, out_dir=str(tmp_path))
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
            q[model.joints[joint_id(model, joint)].idx_q] = angle
        pin.framesForwardKinematics(model, data, q)
        feet.append(np.array([data.oMf[link_frame_id(model, f)].translation for f in spec.feet]))
    np.testing.assert_allclose(feet[1], feet[0], atol=1e-12)
    # The same file for the same input: the name holds a hash of the content.
    assert simulator_model(str(spec.urdf), keep=spec.feet, out_dir=str(tmp_path)) == path


@pytest.mark.parametrize('rpy', [(0.0, 0.0, 0.0), (0.3, -1.2, 2.9), (-3.0, 0.4, -0.1),
                                 (0.5, math.pi / 2, 0.2)])
def test_rpy_round_trip(rpy):
    rotation = _rpy_matrix(*rpy)
    np.testing.assert_allclose(rotation, pin.rpy.rpyToMatrix(*rpy), atol=1e-12)
    np.testing.assert_allclose(_rpy_matrix(*_matrix_rpy(rotation)), rotation, atol=1e-9)
