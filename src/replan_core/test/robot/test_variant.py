"""robot_variant: payload and leg mass errors in a URDF copy that PyBullet and SimWorld load."""

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pybullet
import pytest
from pybullet_utils import bullet_client

from replan_core.robot.variant import PAYLOAD_LINK, mass_summary, perturbed_urdf
from replan_core.sim.world import SimWorld

URDF = os.environ.get(
    'REPLAN_URDF', str(Path(__file__).resolve().parents[4] / 'urdf' / 'hyq.urdf'))
NOMINAL_MASS = 86.756           # kg, urdf/hyq.urdf
OFFSET = (0.10, 0.05, 0.05)     # m, base_link frame


def inertials(path: str) -> dict:
    """Link name -> (mass, [ixx, ixy, ixz, iyy, iyz, izz])."""
    out = {}
    for link in ET.parse(path).getroot().iter('link'):
        inertial = link.find('inertial')
        if inertial is not None:
            inertia = inertial.find('inertia')
            out[link.get('name')] = (float(inertial.find('mass').get('value')),
                                     np.array([float(inertia.get(k)) for k in
                                               ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz')]))
    return out


def pybullet_masses(path: str) -> dict:
    """Link name -> mass (kg) as PyBullet loads the file (the base as 'base_link')."""
    client = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(path, flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
        masses = {'base_link': client.getDynamicsInfo(body, -1)[0]}
        for i in range(client.getNumJoints(body)):
            masses[client.getJointInfo(body, i)[12].decode()] = client.getDynamicsInfo(body, i)[0]
        return masses
    finally:
        client.disconnect()


def test_no_perturbation_returns_the_original(tmp_path):
    assert perturbed_urdf(URDF, payload_mass=0.0, payload_offset=OFFSET, leg_mass_error=0.0,
                          seed=3, out_dir=str(tmp_path)) == URDF
    assert list(tmp_path.iterdir()) == []
    assert mass_summary(URDF)['total'] == pytest.approx(NOMINAL_MASS, abs=1e-9)


def test_payload_and_leg_masses(tmp_path):
    error = 0.1
    path = perturbed_urdf(URDF, payload_mass=5.0, payload_offset=OFFSET, leg_mass_error=error,
                          seed=3, out_dir=str(tmp_path))
    assert Path(path).parent == tmp_path
    nominal, variant = inertials(URDF), inertials(path)
    assert variant[PAYLOAD_LINK][0] == 5.0
    assert variant['base_link'][0] == nominal['base_link'][0]           # the trunk is exact
    ratios = []
    for name, (mass, inertia) in nominal.items():
        if name == 'base_link' or mass == 0.0:
            continue
        ratio = variant[name][0] / mass
        assert 1.0 - error <= ratio <= 1.0 + error, name
        np.testing.assert_allclose(variant[name][1], ratio * inertia, rtol=1e-12)
        ratios.append(ratio)
    assert len(ratios) == 12 and len(set(ratios)) == 12                  # one draw per link
    expected = (nominal['base_link'][0] + 5.0
                + sum(variant[n][0] for n in nominal if n != 'base_link'))
    assert mass_summary(path)['total'] == pytest.approx(expected, abs=1e-9)
    # The same arguments give the same file; another seed other masses.
    again = perturbed_urdf(URDF, payload_mass=5.0, payload_offset=OFFSET, leg_mass_error=error,
                           seed=3, out_dir=str(tmp_path))
    other = perturbed_urdf(URDF, payload_mass=5.0, payload_offset=OFFSET, leg_mass_error=error,
                           seed=4, out_dir=str(tmp_path))
    assert again == path and other != path
    assert inertials(other)['lf_upperleg'][0] != variant['lf_upperleg'][0]


def test_pybullet_and_pinocchio_load_the_variant(tmp_path):
    path = perturbed_urdf(URDF, payload_mass=5.0, payload_offset=OFFSET, leg_mass_error=0.1,
                          seed=0, out_dir=str(tmp_path))
    total = mass_summary(path)['total']
    masses = pybullet_masses(path)
    assert masses[PAYLOAD_LINK] == pytest.approx(5.0)      # a fixed link keeps its own mass
    assert sum(masses.values()) == pytest.approx(total, abs=1e-9)
    assert pin.computeTotalMass(pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())) == \
        pytest.approx(total, abs=1e-9)


def test_simworld_runs_the_variant(tmp_path):
    path = perturbed_urdf(URDF, payload_mass=5.0, payload_offset=OFFSET, leg_mass_error=0.1,
                          seed=0, out_dir=str(tmp_path))
    world = SimWorld(path)                      # finds all joints and feet by name
    try:
        assert world.contact_state().contact.all()
        for _ in range(100):                    # the robot settles (or sits) under gravity
            world.step(world.damping_torques(40.0))
        total = mass_summary(path)['total']
        assert world.contact_state().force[:, 2].sum() > 0.5 * total * 9.81
    finally:
        world.close()


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError):
        perturbed_urdf(URDF, payload_mass=-1.0, out_dir=str(tmp_path))
    with pytest.raises(ValueError):
        perturbed_urdf(URDF, leg_mass_error=1.5, out_dir=str(tmp_path))
    with pytest.raises(ValueError):
        perturbed_urdf(URDF, payload_mass=1.0, payload_offset=(0.0, np.nan, 0.0),
                       out_dir=str(tmp_path))


def test_another_robots_trunk_is_its_root_and_the_links_fixed_to_it(tmp_path):
    """Go1: the payload hangs on its root ``base``; the trunk (``trunk``, rotors, sensors,
    fixed to ``base``) keeps its masses, only the legs' are off."""
    from replan_core.robot.robot_file import load_robot_file

    root = Path(__file__).resolve().parents[4]
    spec = load_robot_file(root / 'config' / 'robots' / 'go1.yaml', root)
    path = perturbed_urdf(str(spec.urdf), payload_mass=0.75, payload_offset=OFFSET,
                          leg_mass_error=0.1, seed=0, out_dir=str(tmp_path), base_link='base')
    nominal, variant = inertials(str(spec.urdf)), inertials(path)
    joint = next(j for j in ET.parse(path).getroot().findall('joint')
                 if j.find('child').get('link') == PAYLOAD_LINK)
    assert joint.find('parent').get('link') == 'base'
    for name in ('trunk', 'FL_hip_rotor', 'imu_link'):
        assert variant[name][0] == nominal[name][0], name
    changed = {n for n in nominal if variant[n][0] != nominal[n][0]}
    assert {'FL_thigh', 'RR_calf'} <= changed and 'trunk' not in changed
    with pytest.raises(ValueError, match='has no link base_link'):
        perturbed_urdf(str(spec.urdf), payload_mass=1.0, out_dir=str(tmp_path))
    # Its meshes (package://example-robot-data/...) are found from the copy's place too:
    # PyBullet refused the copy before.
    meshes = [e.get('filename') for e in ET.parse(path).getroot().iter('mesh')]
    assert meshes and all(Path(m).is_file() for m in meshes)
    world = SimWorld(path, joint_names=spec.joints, foot_frames=spec.feet,
                     initial_joint_positions=spec.standing_pose)
    world.close()
