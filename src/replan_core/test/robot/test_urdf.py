"""urdf/hyq.urdf loads in PyBullet and pinocchio: same names, masses, limits and kinematics."""

import os
from pathlib import Path

import numpy as np
import pinocchio as pin
import pybullet
import pytest
from pybullet_utils import bullet_client

from replan_core.common.types import BASE_FRAME, FOOT_FRAMES, JOINT_NAMES
from replan_core.robot.model import joint_id, link_frame_id

URDF = os.environ.get(
    'REPLAN_URDF', str(Path(__file__).resolve().parents[4] / 'urdf' / 'hyq.urdf'))

TOTAL_MASS = 60.96 + 4 * (2.93 + 2.638 + 0.881)     # kg, HyQ's published figures
HAA = (-1.2217304764, 0.436332312999)               # rad
HFE_FRONT = (-0.872664625997, 1.2217304764)
HFE_HIND = (-1.2217304764, 0.872664625997)
KFE_FRONT = (-2.44346095279, -0.349065850399)
KFE_HIND = (0.349065850399, 2.44346095279)
EFFORT = 150.0                                      # N m


def expected_limits(name: str) -> tuple[float, float]:
    front = name[1] == 'f'
    if name.endswith('haa_joint'):
        return HAA
    if name.endswith('hfe_joint'):
        return HFE_FRONT if front else HFE_HIND
    return KFE_FRONT if front else KFE_HIND


@pytest.fixture(scope='module')
def pin_model():
    model = pin.buildModelFromUrdf(URDF, pin.JointModelFreeFlyer())
    return model, model.createData()


@pytest.fixture(scope='module')
def bullet():
    client = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
    body = client.loadURDF(URDF, flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
    yield client, body
    client.disconnect()


def bullet_indices(client, body) -> tuple[dict[str, int], dict[str, int]]:
    joints, links = {}, {}
    for i in range(client.getNumJoints(body)):
        info = client.getJointInfo(body, i)
        joints[info[1].decode()] = i
        links[info[12].decode()] = i
    return joints, links


def test_pinocchio_model(pin_model):
    model, _ = pin_model
    assert model.nq == 19
    assert model.nv == 18
    assert pin.computeTotalMass(model) == pytest.approx(TOTAL_MASS, abs=1e-9)
    assert pin.computeTotalMass(model) == pytest.approx(86.756, abs=1e-6)
    for frame in (*FOOT_FRAMES, BASE_FRAME):
        assert model.existFrame(frame, pin.FrameType.BODY), frame
    for name in JOINT_NAMES:
        assert model.existJointName(name), name
        jid = joint_id(model, name)
        iq, iv = model.joints[jid].idx_q, model.joints[jid].idx_v
        lower, upper = expected_limits(name)
        assert model.lowerPositionLimit[iq] == pytest.approx(lower)
        assert model.upperPositionLimit[iq] == pytest.approx(upper)
        assert model.effortLimit[iv] == pytest.approx(EFFORT)
    # base_link is the trunk: the free-flyer body carries the 60.96 kg trunk itself.
    assert model.inertias[1].mass == pytest.approx(60.96)
    np.testing.assert_allclose(model.inertias[1].lever, [0.056, 0.0215, 0.00358])


def test_pybullet_model(bullet):
    client, body = bullet
    assert client.getNumJoints(body) == 16           # 12 revolute + 4 fixed feet
    assert client.getBodyInfo(body)[0].decode() == BASE_FRAME
    joints, links = bullet_indices(client, body)
    assert client.getDynamicsInfo(body, -1)[0] == pytest.approx(60.96)
    total = sum(client.getDynamicsInfo(body, i)[0] for i in range(-1, client.getNumJoints(body)))
    assert total == pytest.approx(TOTAL_MASS, abs=1e-9)
    for name in JOINT_NAMES:
        info = client.getJointInfo(body, joints[name])
        assert info[2] == pybullet.JOINT_REVOLUTE
        lower, upper = expected_limits(name)
        assert info[8] == pytest.approx(lower)
        assert info[9] == pytest.approx(upper)
        assert info[10] == pytest.approx(EFFORT)
    for foot in FOOT_FRAMES:
        assert foot in links
        assert client.getJointInfo(body, links[foot])[2] == pybullet.JOINT_FIXED


def test_standing_pose_height(pin_model):
    """HyQ's standing pose puts the trunk 0.599 m above flat ground (feet are r=0.02175 spheres)."""
    model, data = pin_model
    q = pin.neutral(model)
    standing = dict(haa=-0.2, hfe=0.75, kfe=-1.5)
    for name in JOINT_NAMES:
        sign = 1.0 if name[1] == 'f' or name.endswith('haa_joint') else -1.0
        q[model.joints[joint_id(model, name)].idx_q] = sign * standing[name[3:6]]
    pin.framesForwardKinematics(model, data, q)
    z = [data.oMf[link_frame_id(model, f)].translation[2] for f in FOOT_FRAMES]
    np.testing.assert_allclose(z, -0.5775, atol=1e-3)
    assert 0.55 < -z[0] + 0.02175 < 0.61


def test_foot_positions_agree(pin_model, bullet):
    """Random base poses and joint angles: PyBullet and pinocchio feet agree to 1e-6 m."""
    model, data = pin_model
    client, body = bullet
    joints, links = bullet_indices(client, body)
    # PyBullet places the base at its inertial (CoM, principal axes) frame, not the link frame.
    local_pos, local_orn = client.getDynamicsInfo(body, -1)[3:5]
    rng = np.random.default_rng(5)
    for _ in range(5):
        pos = rng.uniform(-1.0, 1.0, 3)
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)                  # x, y, z, w
        qj = {n: rng.uniform(*expected_limits(n)) for n in JOINT_NAMES}

        com_pos, com_orn = client.multiplyTransforms(pos, quat, local_pos, local_orn)
        client.resetBasePositionAndOrientation(body, com_pos, com_orn)
        for n, v in qj.items():
            client.resetJointState(body, joints[n], v)
        q = pin.neutral(model)
        q[:3], q[3:7] = pos, quat
        for n, v in qj.items():
            q[model.joints[joint_id(model, n)].idx_q] = v
        pin.framesForwardKinematics(model, data, q)
        for foot in FOOT_FRAMES:
            p_bullet = np.array(client.getLinkState(
                body, links[foot], computeForwardKinematics=True)[4])
            np.testing.assert_allclose(
                p_bullet, data.oMf[link_frame_id(model, foot)].translation, atol=1e-6)
