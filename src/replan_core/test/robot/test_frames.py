"""Unit tests of replan_core.robot.frames: the link transforms chain up to the feet that the
controller's free-flyer model computes, and the tree is the URDF's."""

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from replan_core.common.rotations import quaternion_to_matrix
from replan_core.common.types import FOOT_FRAMES, STANDING_POSE, BaseState, JointState
from replan_core.robot.frames import LinkFrames, base_transform, compose
from replan_core.robot.model import RobotModel

ROOT = Path(__file__).resolve().parents[4]
URDF = os.environ.get('REPLAN_URDF') or str(ROOT / 'urdf' / 'hyq.urdf')


@pytest.fixture(scope='module')
def frames():
    return LinkFrames(URDF)


def test_one_transform_per_urdf_joint_parent_to_child(frames):
    joints = ET.parse(URDF).getroot().findall('joint')
    expected = {(j.find('parent').get('link'), j.find('child').get('link')) for j in joints}
    got = frames.link_transforms(STANDING_POSE)
    assert {(t.parent, t.child) for t in got} == expected
    assert len(got) == len(joints) == 16
    assert frames.links[0] == 'base_link' and len(set(frames.links)) == 17
    for t in got:
        assert abs(np.linalg.norm(t.rotation) - 1.0) < 1e-12


def test_chain_to_each_foot_matches_the_free_flyer_model(frames):
    rng = np.random.default_rng(3)
    model = RobotModel(URDF)
    for _ in range(5):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        position = rng.normal(size=3)
        q = STANDING_POSE + 0.3 * rng.normal(size=12)
        expected = model.foot_positions(BaseState(0.0, position, quat, np.zeros(3), np.zeros(3)),
                                        JointState(0.0, q, np.zeros(12), np.zeros(12)))
        by_child = {t.child: t for t in frames.link_transforms(q)}
        for leg, foot in enumerate(FOOT_FRAMES):
            chain = []
            link = foot
            while link in by_child:
                chain.append(by_child[link])
                link = by_child[link].parent
            assert link == 'base_link' and len(chain) == 4
            current = base_transform(position, quat)
            translation, rotation = np.asarray(current.translation), quaternion_to_matrix(quat)
            for step in reversed(chain):
                translation = translation + rotation @ np.asarray(step.translation)
                rotation = rotation @ quaternion_to_matrix(np.asarray(step.rotation))
            np.testing.assert_allclose(translation, expected[leg], atol=1e-9)


def test_joint_angle_rotates_only_its_child(frames):
    q = STANDING_POSE.copy()
    before = {t.child: t for t in frames.link_transforms(q)}
    q[2] += 0.5                                   # lf_kfe_joint
    after = {t.child: t for t in frames.link_transforms(q)}
    changed = {c for c in before if not np.allclose(before[c].rotation, after[c].rotation)}
    assert changed == {'lf_lowerleg'}


def test_compose_and_base_transform():
    a = base_transform((1.0, 0.0, 0.0), (0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)))
    b = base_transform((1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 2.0), 'base_link', 'x')  # normalised
    assert b.rotation == (0.0, 0.0, 0.0, 1.0)
    translation, _ = compose(a, b)
    np.testing.assert_allclose(translation, [1.0, 1.0, 0.0], atol=1e-12)


def test_another_robots_tree_hangs_below_the_project_base_frame():
    """A robot file's model (Go1: root ``base``, Unitree joint names): its joints in the
    project's order, its root below ``base_link`` (the frame odom names) at the identity."""
    from replan_core.robot.robot_file import load_robot_file

    spec = load_robot_file(ROOT / 'config' / 'robots' / 'go1.yaml', ROOT)
    go1 = LinkFrames(str(spec.urdf), spec.joints)
    got = go1.link_transforms(spec.standing_pose)
    assert (got[0].parent, got[0].child) == ('base_link', 'base')
    assert got[0].translation == (0.0, 0.0, 0.0) and got[0].rotation == (0.0, 0.0, 0.0, 1.0)
    assert go1.links[:2] == ('base_link', 'base') and go1.root_link == 'base'
    model = RobotModel(str(spec.urdf), spec.joints, spec.feet)
    base = BaseState(0.0, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))
    joints = JointState(0.0, spec.standing_pose, np.zeros(12), np.zeros(12))
    feet = model.foot_positions(base, joints)
    poses = {t.child: t for t in got}
    for k, foot in enumerate(spec.feet):
        chain, link = [], foot
        while link in poses:
            chain.append(poses[link])
            link = poses[link].parent
        assert link == 'base_link'
        translation, rotation = np.zeros(3), np.eye(3)
        for step in reversed(chain):
            translation = translation + rotation @ np.asarray(step.translation)
            rotation = rotation @ quaternion_to_matrix(np.asarray(step.rotation))
        np.testing.assert_allclose(translation, feet[k], atol=1e-9, err_msg=foot)


def _robot_specs():
    from replan_core.robot.robot_file import load_robot_file, robot_names

    configs = ROOT / 'config'
    return [pytest.param(load_robot_file(configs / 'robots' / f'{name}.yaml', ROOT), id=name)
            for name in robot_names(configs)]


@pytest.mark.parametrize('spec', _robot_specs())
def test_every_robot_file_gives_its_urdf_tree_and_pinocchios_placements(spec):
    """Each robot of config/robots/ (a new file gets this test): one transform per URDF joint,
    every URDF link (and the project's base frame above another root), and every link placed
    where pinocchio's free-flyer model places it, feet included. ANYmal C's URDF names joints
    like links (LF_HAA): the frames are told apart by type."""
    from replan_core.robot.model import link_frame_id

    urdf = ET.parse(spec.urdf).getroot()
    links = {link.get('name') for link in urdf.findall('link')}
    pairs = {(j.find('parent').get('link'), j.find('child').get('link'))
             for j in urdf.findall('joint')}
    frames = LinkFrames(str(spec.urdf), spec.joints)
    extra = set() if spec.root_link == 'base_link' else {('base_link', spec.root_link)}
    rng = np.random.default_rng(5)
    q = spec.standing_pose + rng.uniform(-0.3, 0.3, 12)
    got = frames.link_transforms(q)
    assert {(t.parent, t.child) for t in got} == pairs | extra
    assert len(got) == len(pairs | extra)
    assert set(frames.links) == links | {'base_link'}
    assert len(frames.links) == len(links) + len(extra)          # each link once

    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    position = rng.normal(size=3)
    model = pin.buildModelFromUrdf(str(spec.urdf), pin.JointModelFreeFlyer())
    data = model.createData()
    config = pin.neutral(model)
    config[:3], config[3:7] = position, quat
    robot = RobotModel(str(spec.urdf), spec.joints, spec.feet)
    config[robot.q_index] = q
    pin.framesForwardKinematics(model, data, config)
    placed = {'base_link': (position, quaternion_to_matrix(quat))}
    pending = list(got)
    while pending:                                   # parents before children
        t = pending.pop(0)
        if t.parent not in placed:
            pending.append(t)
            continue
        translation, rotation = placed[t.parent]
        placed[t.child] = (translation + rotation @ np.asarray(t.translation),
                           rotation @ quaternion_to_matrix(np.asarray(t.rotation)))
    for link in links:
        expected = data.oMf[link_frame_id(model, link)]
        np.testing.assert_allclose(placed[link][0], expected.translation, atol=1e-9,
                                   err_msg=link)
        np.testing.assert_allclose(placed[link][1], expected.rotation, atol=1e-9, err_msg=link)
    feet = robot.foot_positions(BaseState(0.0, position, quat, np.zeros(3), np.zeros(3)),
                                JointState(0.0, q, np.zeros(12), np.zeros(12)))
    for k, foot in enumerate(spec.feet):
        np.testing.assert_allclose(placed[foot][0], feet[k], atol=1e-9, err_msg=foot)
