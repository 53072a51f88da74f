"""Unit tests of replan_core.robot.model: free flyer, world velocities, joint order."""

import os
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from replan_core.common.rotations import quaternion_to_matrix
from replan_core.common.types import JOINT_NAMES, LEGS, STANDING_POSE, BaseState, JointState
from replan_core.robot.model import RobotModel, joint_id, link_frame_id
from replan_core.robot.robot_file import load_robot_file

ROOT = Path(__file__).resolve().parents[4]
ERD_HYQ = (Path(sys.prefix) / 'lib' / f'python{sys.version_info.major}.{sys.version_info.minor}'
           / 'site-packages' / 'cmeel.prefix' / 'share' / 'example-robot-data' / 'robots'
           / 'hyq_description' / 'robots' / 'hyq_no_sensors.urdf')


def urdf_path() -> str:
    """The project URDF (REPLAN_URDF or urdf/hyq.urdf), else example-robot-data's HyQ."""
    for candidate in (os.environ.get('REPLAN_URDF'), ROOT / 'urdf' / 'hyq.urdf', ERD_HYQ):
        if candidate and Path(candidate).is_file():
            return str(candidate)
    pytest.skip('no HyQ URDF available')


@pytest.fixture(scope='module')
def robot():
    return RobotModel(urdf_path())


def random_state(rng: np.random.Generator) -> tuple[BaseState, JointState]:
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    base = BaseState(0.0, rng.normal(size=3), quat, rng.normal(size=3), rng.normal(size=3))
    joints = JointState(0.0, STANDING_POSE + 0.3 * rng.normal(size=12), rng.normal(size=12),
                        np.zeros(12))
    return base, joints


def advance(base: BaseState, joints: JointState, dt: float) -> tuple[BaseState, JointState]:
    """Integrate a state by dt with its world-frame velocities (exact rotation update)."""
    rotation = quaternion_to_matrix(base.quaternion)
    rotation = pin.exp3(base.angular_velocity * dt) @ rotation      # world-frame omega
    quat = pin.Quaternion(rotation).coeffs()                        # x, y, z, w
    new_base = BaseState(base.stamp + dt, base.position + base.linear_velocity * dt, quat,
                         base.linear_velocity, base.angular_velocity)
    new_joints = JointState(joints.stamp + dt, joints.position + joints.velocity * dt,
                            joints.velocity, joints.effort)
    return new_base, new_joints


def test_names_and_mass(robot):
    assert robot.joint_names == JOINT_NAMES
    assert 70.0 < robot.total_mass < 110.0
    # The mapping must pick each named joint's own index in pinocchio's vectors.
    for i, name in enumerate(JOINT_NAMES):
        joint = robot.model.joints[joint_id(robot.model, name)]
        assert robot.q_index[i] == joint.idx_q
        assert robot.v_index[i] == joint.idx_v
    assert np.all(robot.effort_limit > 0)


def test_joint_order_mapping(robot):
    """Bending only rf_kfe moves only the rf foot, whatever pinocchio's internal order."""
    base = BaseState(0.0, np.array([0.0, 0.0, 0.6]), np.array([0, 0, 0, 1.0]),
                     np.zeros(3), np.zeros(3))
    joints = JointState(0.0, STANDING_POSE.copy(), np.zeros(12), np.zeros(12))
    feet0 = robot.foot_positions(base, joints)
    joints.position[JOINT_NAMES.index('rf_kfe_joint')] += 0.2
    feet1 = robot.foot_positions(base, joints)
    moved = np.linalg.norm(feet1 - feet0, axis=1) > 1e-6
    assert moved.tolist() == [False, True, False, False]


def test_foot_positions_standing(robot):
    base = BaseState(0.0, np.array([1.0, -2.0, 0.6]), np.array([0, 0, 0, 1.0]),
                     np.zeros(3), np.zeros(3))
    joints = JointState(0.0, STANDING_POSE.copy(), np.zeros(12), np.zeros(12))
    feet = robot.foot_positions(base, joints)
    hips = robot.hip_positions(base)
    # Left feet on the left (+y), front feet in front, all below the hips, symmetric stance.
    assert np.all(feet[[0, 2], 1] > feet[[1, 3], 1])
    assert np.all(feet[[0, 1], 0] > feet[[2, 3], 0])
    assert np.all(feet[:, 2] < hips[:, 2] - 0.4)
    np.testing.assert_allclose(feet[:, 2], feet[0, 2], atol=1e-9)
    np.testing.assert_allclose(hips[:, 2], 0.6, atol=1e-9)
    np.testing.assert_allclose(feet[0, 1] - base.position[1], base.position[1] - feet[1, 1],
                               atol=1e-9)


def test_hip_positions_follow_base_pose(robot):
    yaw = 0.7
    base = BaseState(0.0, np.array([0.3, 0.1, 0.5]),
                     np.array([0, 0, np.sin(yaw / 2), np.cos(yaw / 2)]), np.zeros(3), np.zeros(3))
    hips = robot.hip_positions(base)
    rz = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    np.testing.assert_allclose(hips, base.position + robot.hip_offsets @ rz.T, atol=1e-12)
    # HAA joints: left legs at +y in the base frame, front legs at +x.
    offsets = robot.hip_offsets
    assert np.all(offsets[[0, 2], 1] > 0) and np.all(offsets[[1, 3], 1] < 0)
    assert np.all(offsets[[0, 1], 0] > 0) and np.all(offsets[[2, 3], 0] < 0)


def test_com_velocity_matches_finite_differences(robot):
    rng = np.random.default_rng(6)
    dt = 1e-6
    for _ in range(5):
        base, joints = random_state(rng)
        _, vcom = robot.com_state(base, joints)
        plus = robot.com_state(*advance(base, joints, dt))[0]
        minus = robot.com_state(*advance(base, joints, -dt))[0]
        np.testing.assert_allclose(vcom, (plus - minus) / (2 * dt), atol=1e-5)


def test_foot_velocity_matches_jacobian(robot):
    """Foot Jacobians (world axes) times pinocchio v equal finite differences of the feet."""
    rng = np.random.default_rng(7)
    dt = 1e-6
    base, joints = random_state(rng)
    jac = robot.foot_jacobians(base, joints)
    _, v = robot.configuration(base, joints)
    velocity = jac @ v
    plus = robot.foot_positions(*advance(base, joints, dt))
    minus = robot.foot_positions(*advance(base, joints, -dt))
    np.testing.assert_allclose(velocity, (plus - minus) / (2 * dt), atol=1e-5)


def test_update_matches_queries(robot):
    rng = np.random.default_rng(8)
    base, joints = random_state(rng)
    com, vcom = robot.com_state(base, joints)
    feet = robot.foot_positions(base, joints)
    robot.update(base, joints)
    np.testing.assert_allclose(robot.data.com[0], com, atol=1e-12)
    np.testing.assert_allclose(robot.data.vcom[0], vcom, atol=1e-12)
    np.testing.assert_allclose(
        [robot.data.oMf[f].translation for f in robot.foot_frame_ids], feet, atol=1e-12)


@pytest.mark.parametrize('name', ['hyq', 'anymal_c', 'go1', 'b1', 'anymal_b', 'a1', 'go2'])
def test_any_robot_file_gives_a_model_in_the_project_order(name):
    """The model of each robot file, built with its own joint and foot names: hips and feet
    come out in LEGS order (front left ahead and to the left, and so on), the standing feet
    below the hips, and the joint limits in JOINT_NAMES order."""
    root = Path(__file__).resolve().parents[4]
    spec = load_robot_file(root / 'config' / 'robots' / f'{name}.yaml', root)
    robot = RobotModel(str(spec.urdf), spec.joints, spec.feet)
    assert robot.joint_names == spec.joints
    hips = robot.hip_offsets
    signs = {'lf': (1, 1), 'rf': (1, -1), 'lh': (-1, 1), 'rh': (-1, -1)}
    for leg, (sx, sy) in signs.items():
        i = LEGS.index(leg)
        assert np.sign(hips[i, 0]) == sx and np.sign(hips[i, 1]) == sy, (leg, hips[i])
    base = BaseState(0.0, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))
    joints = JointState(0.0, spec.standing_pose, np.zeros(12), np.zeros(12))
    feet = robot.foot_positions(base, joints)
    assert np.all(feet[:, 2] < hips[:, 2] - 0.1), feet
    np.testing.assert_allclose(feet[:, :2], hips[:, :2], atol=0.2)   # under the hips
    assert np.all(robot.position_lower < robot.position_upper)
    if name != 'hyq':
        with pytest.raises(ValueError, match='missing joints/frames'):
            RobotModel(str(spec.urdf))       # the project's HyQ names: only HyQ has them


def test_a_link_and_a_joint_of_one_name_are_told_apart_by_type():
    """ANYmal C's URDF has a joint and a link named LF_HAA: the link's frame and the joint are
    found by name and type, a name of neither kind is refused."""
    spec = load_robot_file(ROOT / 'config' / 'robots' / 'anymal_c.yaml', ROOT)
    model = pin.buildModelFromUrdf(str(spec.urdf))
    with pytest.raises(ValueError, match='Several frames match'):
        model.getFrameId('LF_HAA')
    link = model.frames[link_frame_id(model, 'LF_HAA')]
    assert link.name == 'LF_HAA' and link.type == pin.FrameType.BODY
    assert model.names[joint_id(model, 'LF_HAA')] == 'LF_HAA'
    assert model.getFrameId('LF_HAA', pin.FrameType.JOINT) != link_frame_id(model, 'LF_HAA')
    with pytest.raises(ValueError, match="no link 'LF_HAA_joint'"):
        link_frame_id(model, 'LF_HAA_joint')
    with pytest.raises(ValueError, match="no joint 'LF_FOOT'"):
        joint_id(model, 'LF_FOOT')
