"""SimWorld: landing and touchdown events, standing, pushes, determinism, inputs, terrain."""

import os
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from replan_core.common.types import FOOT_FRAMES, JOINT_NAMES
from replan_core.robot.model import joint_id, link_frame_id
from replan_core.sim.settings import (
    TERRAIN_DEFAULTS,
    ActuatorParams,
    TerrainSettings,
    WorldSettings,
)
from replan_core.sim.world import STANDING_POSE, SimWorld

URDF = os.environ.get(
    'REPLAN_URDF', str(Path(__file__).resolve().parents[4] / 'urdf' / 'hyq.urdf'))
G = 9.81
FOOT_RADIUS = 0.02175       # m, urdf/hyq.urdf
STAND_HEIGHT = 0.5775 + FOOT_RADIUS   # m, base_link above flat ground in the standing pose


@pytest.fixture(scope='module')
def model():
    m = pin.buildModelFromUrdf(URDF, pin.JointModelFreeFlyer())
    # pinocchio orders joints by name (lf lh rf rh): index of each JOINT_NAMES joint in q[7:].
    idx = np.array([m.joints[joint_id(m, n)].idx_q - 7 for n in JOINT_NAMES])
    return m, m.createData(), idx


@pytest.fixture
def world_factory():
    worlds = []

    def make(**kwargs):
        worlds.append(SimWorld(URDF, **kwargs))
        return worlds[-1]

    yield make
    for w in worlds:
        w.close()


def pin_q(world, idx) -> np.ndarray:
    b, j = world.base_state(), world.joint_state()
    q = np.zeros(19)
    q[:3], q[3:7] = b.position, b.quaternion
    q[7:][idx] = j.position
    return q


def pin_v(world, idx) -> np.ndarray:
    """pinocchio free-flyer velocity: base twist in the base frame, then the joints."""
    b, j = world.base_state(), world.joint_state()
    R = pin.Quaternion(b.quaternion[3], *b.quaternion[:3]).toRotationMatrix()
    v = np.zeros(18)
    v[:3], v[3:6] = R.T @ b.linear_velocity, R.T @ b.angular_velocity
    v[6:][idx] = j.velocity
    return v


def standing_torques(world, model) -> np.ndarray:
    """Joint PD to the standing pose plus the torques holding a quarter of the weight per foot."""
    m, d, idx = model
    q = pin_q(world, idx)
    pin.computeJointJacobians(m, d, q)
    pin.framesForwardKinematics(m, d, q)
    weight = pin.computeTotalMass(m) * G
    tau = np.zeros(12)
    for foot in FOOT_FRAMES:
        J = pin.getFrameJacobian(m, d, link_frame_id(m, foot), pin.LOCAL_WORLD_ALIGNED)[:3, 6:]
        tau += (-J.T @ np.array([0.0, 0.0, weight / 4]))[idx]
    j = world.joint_state()
    return tau + 300.0 * (STANDING_POSE - j.position) - 10.0 * j.velocity


def test_spawn_standing_feet_touching(world_factory):
    w = world_factory()
    b, c = w.base_state(), w.contact_state()
    assert w.time == 0.0
    assert b.position[2] == pytest.approx(STAND_HEIGHT, abs=1e-3)
    np.testing.assert_allclose(c.foot_position[:, 2], FOOT_RADIUS, atol=1e-6)
    assert c.contact.all()                       # spawned standing: in contact, no events
    assert not c.touchdown.any() and not c.liftoff.any()


@pytest.mark.parametrize('name', ['anymal_c', 'go1', 'b1', 'go2'])
def test_any_robot_file_spawns_standing_with_its_feet_touching(name):
    """Another robot, from its robot file (its own joint and foot names, its standing pose,
    its contact sphere): spawned with the lowest point of the lowest foot sphere on the
    ground, at the standing height the model gives (robot_facts). The spawn's ray casts must
    miss the robot's own legs (feet under the hips): before, they hit them and Go1 spawned
    high; and ANYmal's sphere sits 2.25 cm above its foot frame: taken for the frame, ANYmal
    spawned 2.1 cm high and dropped."""
    from replan_core.robot.robot_file import load_robot_file, robot_facts
    root = Path(__file__).resolve().parents[4]
    spec = load_robot_file(root / 'config' / 'robots' / f'{name}.yaml', root)
    w = SimWorld(str(spec.urdf), joint_names=spec.joints, foot_frames=spec.feet,
                 initial_joint_positions=spec.standing_pose, foot_offset=spec.foot_offset,
                 foot_radius=spec.foot_radius)
    try:
        c = w.contact_state()
        radius = np.array([w._foot_radius(link) for link in w._feet])
        # The model's sphere (the file says the URDF's), or the file's in place of a mesh (Go2).
        np.testing.assert_allclose(radius, spec.foot_radius)
        # The sphere centre is about the offset above the frame (which tilts with the shank).
        sole = c.foot_position[:, 2] + spec.foot_offset[2] - radius
        assert min(sole) == pytest.approx(0.0, abs=3e-3)
        assert w.base_state().position[2] == pytest.approx(
            robot_facts(spec).standing_height, abs=1e-4)
    finally:
        w.close()


@pytest.mark.parametrize('name', ['hyq', 'anymal_c', 'go1', 'b1', 'anymal_b', 'a1', 'go2'])
def test_sim_mass_and_inertia_equal_the_model(name):
    """The sim's robot weighs what the controller's model (pinocchio) says, and its links
    merged (urdf_merge.py: ANYmal C 77 -> 16 PyBullet links) turn as the model does: the
    mass, centre of mass and rotational inertia of the whole robot at its standing pose, about
    the base origin, agree. A link without an <inertial> (ANYmal C's root) is massless in both;
    PyBullet's default for it, 1 kg and a unit inertia, made ANYmal C's simulated trunk 1 kg
    heavier and far harder to turn."""
    from replan_core.robot.robot_file import load_robot_file
    root = Path(__file__).resolve().parents[4]
    spec = load_robot_file(root / 'config' / 'robots' / f'{name}.yaml', root)
    model = pin.buildModelFromUrdf(str(spec.urdf), pin.JointModelFreeFlyer())
    data = model.createData()
    q = pin.neutral(model)
    for joint, angle in zip(spec.joints, spec.standing_pose, strict=True):
        q[model.joints[joint_id(model, joint)].idx_q] = angle
    mass_matrix = pin.crba(model, data, q)
    pin.centerOfMass(model, data, q)
    w = SimWorld(str(spec.urdf), joint_names=spec.joints, foot_frames=spec.feet,
                 initial_joint_positions=spec.standing_pose, foot_offset=spec.foot_offset,
                 foot_radius=spec.foot_radius)
    try:
        p, robot = w._p, w._robot
        assert p.getNumJoints(robot) == 16        # 12 moving links and the 4 feet
        origin = w.base_state().position
        masses, centres, inertias = [], [], []
        for link in range(-1, p.getNumJoints(robot)):
            mass, _, diagonal = p.getDynamicsInfo(robot, link)[:3]
            if link == -1:
                centre, quat = p.getBasePositionAndOrientation(robot)
            else:
                centre, quat = p.getLinkState(robot, link, computeForwardKinematics=True)[:2]
            rotation = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
            masses.append(mass)
            centres.append(np.array(centre) - origin)        # base frame: spawned level
            inertias.append(rotation @ np.diag(diagonal) @ rotation.T)
        total = sum(masses)
        about_origin = sum(i + m * (float(r @ r) * np.eye(3) - np.outer(r, r))
                           for m, r, i in zip(masses, centres, inertias, strict=True))
        assert total == pytest.approx(data.mass[0], abs=1e-4)
        np.testing.assert_allclose(sum(m * r for m, r in zip(masses, centres, strict=True))
                                   / total, data.com[0], atol=1e-5)
        # The free-flyer's angular block of the mass matrix: the inertia about the base origin.
        np.testing.assert_allclose(about_origin, mass_matrix[3:6, 3:6], atol=2e-5 * total)
    finally:
        w.close()


def test_drop_lands_with_touchdown_events(world_factory):
    w = world_factory(initial_base_height=STAND_HEIGHT + 0.15)
    assert not w.contact_state().contact.any()
    touchdown_time = np.full(4, np.nan)
    for _ in range(150):                         # 0.6 s, zero torque
        w.step(np.zeros(12))
        c = w.contact_state()
        first = c.touchdown & np.isnan(touchdown_time)
        touchdown_time[first] = w.time
    # The feet hit the ground after 0.175 s (0.15 m fall); with zero torque the legs first fold
    # and carry little force, which rises above the threshold when the joints reach their limits.
    assert np.all(np.isfinite(touchdown_time)), touchdown_time
    assert np.all((touchdown_time > 0.17) & (touchdown_time < 0.45)), touchdown_time
    assert w.base_state().position[2] > 0.1      # landed on the ground, not through it


def test_standing_does_not_fall(world_factory, model):
    w = world_factory()
    for _ in range(500):                         # 2 s
        w.step(standing_torques(w, model))
    b, c = w.base_state(), w.contact_state()
    assert b.position[2] == pytest.approx(STAND_HEIGHT, abs=0.02)
    assert abs(b.position[0]) < 0.02 and abs(b.position[1]) < 0.02
    assert np.linalg.norm(b.quaternion[:3]) < 0.02           # level within ~2 deg
    assert c.contact.all()
    weight = pin.computeTotalMass(model[0]) * G
    np.testing.assert_allclose(c.force.sum(axis=0), [0.0, 0.0, weight], atol=0.02 * weight)


def test_ground_reaction_balances_a_push(world_factory, model):
    """Standing and pushed sideways, the summed GRFs carry the weight and oppose the push."""
    w = world_factory()
    w.set_external_wrench(np.array([100.0, -60.0, 0.0]), np.zeros(3))
    for _ in range(750):                         # 3 s, settles under the push
        w.step(standing_torques(w, model))
    total = w.contact_state().force.sum(axis=0)
    np.testing.assert_allclose(total[:2], [-100.0, 60.0], atol=10.0)


def test_push_changes_momentum_by_impulse(world_factory, model):
    """Robot in the air, zero torque: a push F for d changes the momentum by (F - M g) d."""
    m, d, idx = model
    mass = pin.computeTotalMass(m)
    w = world_factory(initial_base_height=5.0)

    def momentum():
        pin.centerOfMass(m, d, pin_q(w, idx), pin_v(w, idx))
        return mass * d.vcom[0].copy()

    for _ in range(5):
        w.step(np.zeros(12))
    p0 = momentum()
    force = np.array([400.0, -250.0, 300.0])
    duration = 0.2
    w.set_external_wrench(force, np.zeros(3))
    for _ in range(round(duration / w.control_period)):
        w.step(np.zeros(12))
    w.set_external_wrench(np.zeros(3), np.zeros(3))
    change = momentum() - p0 - np.array([0.0, 0.0, -mass * G * duration])
    assert not w.contact_state().contact.any()
    np.testing.assert_allclose(change, force * duration, rtol=0.10)
    np.testing.assert_allclose(change, force * duration, rtol=0.01)   # in fact within 0.1 %


def test_state_matches_pinocchio(world_factory, model):
    """Feet from contact_state equal pinocchio's FK of base_state + joint_state in motion."""
    m, d, idx = model
    w = world_factory(initial_base_height=STAND_HEIGHT + 0.1)
    rng = np.random.default_rng(1)
    for _ in range(40):
        w.step(rng.uniform(-60.0, 60.0, 12))
        pin.framesForwardKinematics(m, d, pin_q(w, idx))
        feet = np.array([d.oMf[link_frame_id(m, f)].translation for f in FOOT_FRAMES])
        np.testing.assert_allclose(w.contact_state().foot_position, feet, atol=1e-9)
    # Base twist convention: velocity of the base_link origin, world axes. Semi-implicit Euler
    # over 4 physics steps: the finite difference differs from the mean by ~g dt / 2.
    b0 = w.base_state()
    w.step(np.zeros(12))
    b1 = w.base_state()
    np.testing.assert_allclose((b1.position - b0.position) / w.control_period,
                               (b0.linear_velocity + b1.linear_velocity) / 2, atol=1e-2)


def test_deterministic(world_factory, model):
    """Two worlds with the same torque sequence give bit-identical states."""
    rng = np.random.default_rng(7)
    noise = rng.normal(0.0, 20.0, size=(200, 12))
    records = []
    for _ in range(2):
        w = world_factory(initial_base_height=STAND_HEIGHT + 0.02)
        rec = []
        for k in range(200):
            w.step(standing_torques(w, model) + noise[k])
            b, j, c = w.base_state(), w.joint_state(), w.contact_state()
            rec.append(np.concatenate([b.position, b.quaternion, b.linear_velocity,
                                       b.angular_velocity, j.position, j.velocity, j.effort,
                                       c.foot_position.ravel(), c.force.ravel(), c.contact,
                                       c.touchdown, c.liftoff]))
        records.append(np.array(rec))
    assert np.array_equal(records[0], records[1])


def test_torque_clipping_and_bad_input(world_factory):
    w = world_factory()
    tau = np.linspace(-400.0, 400.0, 12)
    w.step(tau)
    np.testing.assert_array_equal(w.joint_state().effort, np.clip(tau, -150.0, 150.0))
    np.testing.assert_array_equal(w.effort_limit, 150.0)
    tick = w.tick
    bad = np.zeros(12)
    bad[3] = np.nan
    with pytest.raises(ValueError):
        w.step(bad)
    with pytest.raises(ValueError):
        w.step(np.full(12, np.inf))
    with pytest.raises(ValueError):
        w.step(np.zeros(11))
    with pytest.raises(ValueError):
        w.set_external_wrench(np.array([np.nan, 0.0, 0.0]), np.zeros(3))
    assert w.tick == tick
    assert w.time == pytest.approx(tick * 0.004)


def test_damping_torques(world_factory):
    w = world_factory(initial_base_height=STAND_HEIGHT + 0.1)
    for _ in range(10):
        w.step(np.full(12, 20.0))
    np.testing.assert_array_equal(w.damping_torques(40.0), -40.0 * w.joint_state().velocity)


def test_damping_sits_down_gently(world_factory):
    """Controller dead: damping alone lowers the trunk without a crash."""
    w = world_factory()
    for _ in range(750):                         # 3 s
        w.step(w.damping_torques(40.0))
    b = w.base_state()
    assert 0.1 < b.position[2] < STAND_HEIGHT
    assert np.linalg.norm(b.linear_velocity) < 0.1


@pytest.mark.parametrize(('terrain', 'params', 'ground'), [
    ('step_up', {'step_x': -1.0, 'step_length': 3.0, 'step_height': 0.12}, 0.12),
    ('step_down', {'step_x': 1.5, 'step_height': 0.2}, 0.0),
    ('step_down', {'step_x': -1.0, 'step_height': 0.2}, -0.2),
])
def test_step_terrain_spawn_height(world_factory, terrain, params, ground):
    w = world_factory(terrain=terrain, terrain_params=params)
    assert w.base_state().position[2] == pytest.approx(ground + STAND_HEIGHT, abs=1e-3)
    assert w.contact_state().contact.all()


def test_rough_terrain_seeded(world_factory):
    params = {'rough_start_x': -1.0, 'rough_amplitude': 0.05}
    heights = [world_factory(terrain='rough', terrain_params=params, seed=s)
               .base_state().position[2] for s in (3, 3, 4)]
    assert heights[0] == heights[1]
    assert heights[0] != heights[2]
    assert STAND_HEIGHT <= heights[0] <= STAND_HEIGHT + 0.05 + 1e-6


def test_bad_configuration():
    with pytest.raises(ValueError):
        SimWorld(URDF, terrain='lava')
    with pytest.raises(ValueError):
        SimWorld(URDF, control_period=0.0045)


# ---------------------------------------------------------------------- realism options
def record(world, model, ticks, noise_seed=7):
    """States of ``ticks`` ticks under the standing torques plus seeded noise."""
    noise = np.random.default_rng(noise_seed).normal(0.0, 20.0, size=(ticks, 12))
    rows = []
    for k in range(ticks):
        world.step(standing_torques(world, model) + noise[k])
        b, j, c = world.base_state(), world.joint_state(), world.contact_state()
        rows.append(np.concatenate([b.position, b.quaternion, b.linear_velocity,
                                    b.angular_velocity, j.position, j.velocity, j.effort,
                                    c.force.ravel(), c.contact]))
    return np.array(rows)


def test_realism_defaults_change_nothing(world_factory, model):
    """Every realism option at its default gives the ideal world, bit for bit."""
    plain = record(world_factory(initial_base_height=STAND_HEIGHT + 0.02), model, 150)
    explicit = record(world_factory(initial_base_height=STAND_HEIGHT + 0.02,
                                    actuator=ActuatorParams(), contact_stiffness=0.0,
                                    contact_damping=0.0), model, 150)
    assert np.array_equal(plain, explicit)


def test_actuator_lag_reaches_63_percent_after_time_constant(world_factory):
    T, dt = 0.005, 0.001
    w = world_factory(initial_base_height=5.0, physics_dt=dt, control_period=dt,
                      actuator=ActuatorParams(time_constant=T))
    effort = []
    for _ in range(20):
        w.step(np.full(12, 10.0))
        effort.append(w.joint_state().effort[0])
    first = int(np.argmax(np.array(effort) >= 0.632 * 10.0)) + 1     # physics steps
    assert first == round(T / dt)
    np.testing.assert_allclose(effort[first - 1], 10.0 * (1.0 - np.exp(-1.0)), rtol=1e-12)
    assert np.all(np.diff(effort) > 0.0) and effort[-1] < 10.0


def test_actuator_effort_is_the_value_at_the_end_of_the_tick(world_factory):
    T = 0.01
    w = world_factory(initial_base_height=5.0, actuator=ActuatorParams(time_constant=T))
    w.step(np.full(12, 10.0))
    np.testing.assert_allclose(w.joint_state().effort, 10.0 * (1.0 - np.exp(-0.004 / T)),
                               rtol=1e-12)


def test_actuator_delay(world_factory):
    dt = 0.001
    w = world_factory(initial_base_height=5.0, physics_dt=dt, control_period=dt,
                      actuator=ActuatorParams(delay=0.003))
    effort = []
    for _ in range(6):
        w.step(np.full(12, 10.0))
        effort.append(w.joint_state().effort[0])
    assert effort == [0.0, 0.0, 0.0, 10.0, 10.0, 10.0]


def test_actuator_limits_scaled_and_no_windup(world_factory):
    w = world_factory(initial_base_height=5.0,
                      actuator=ActuatorParams(time_constant=0.003, delay=0.002,
                                              torque_limit_scale=0.5))
    np.testing.assert_array_equal(w.effort_limit, 75.0)
    for _ in range(20):
        w.step(np.full(12, 400.0))
        assert np.all(w.joint_state().effort <= 75.0)
    np.testing.assert_allclose(w.joint_state().effort, 75.0, rtol=1e-6)
    w.step(np.zeros(12))              # clipped before the lag: it falls at once, no wind-up
    w.step(np.zeros(12))
    assert np.all(w.joint_state().effort < 75.0 * np.exp(-0.004 / 0.003))


def knee_coast(world_factory, actuator, ticks=100):
    """Robot in the air: spin the knees up (2 N m for 5 ticks), then command 0 N m.
    Returns the front-left knee velocity (rad/s) at each coasting tick."""
    w = world_factory(initial_base_height=5.0, actuator=actuator)
    kick = np.zeros(12)
    kick[[2, 5]] = -2.0            # front knees flex with negative angles
    for _ in range(5):
        w.step(kick)
    v = []
    for _ in range(ticks):
        w.step(np.zeros(12))
        v.append(w.joint_state().velocity[2])
    return np.array(v)


def test_joint_friction(world_factory):
    free = knee_coast(world_factory, ActuatorParams())
    viscous = knee_coast(world_factory, ActuatorParams(viscous_damping=0.5))
    coulomb = knee_coast(world_factory, ActuatorParams(coulomb_friction=1.0))
    v0 = free[0]
    assert v0 < -0.5 and np.all(free < 0.5 * v0)         # no friction: it keeps turning
    # Viscous: an exponential decay, monotonic, never reversing.
    assert np.all(np.diff(np.abs(viscous)) < 0.0) and np.all(viscous <= 0.0)
    assert abs(viscous[-1]) < 0.01 * abs(v0)
    # Coulomb: a constant deceleration tau_c / I (knee, I ~ 0.022 kg m^2) down to v_eps, then
    # a fast decay to rest, never reversing.
    slowing = np.diff(coulomb[:4])
    np.testing.assert_allclose(slowing, slowing[0], rtol=0.1)
    assert slowing[0] == pytest.approx(1.0 / 0.022 * 0.004, rel=0.2)
    assert np.all(coulomb <= 0.0) and np.all(np.abs(coulomb[50:]) < 1e-4)


def test_imu_truth_at_rest_and_in_free_fall(world_factory, model):
    w = world_factory()
    omega, f = w.imu_truth()                  # spawned at rest, level
    np.testing.assert_allclose(omega, 0.0, atol=1e-12)
    np.testing.assert_allclose(f, [0.0, 0.0, G], atol=1e-12)
    for _ in range(900):                      # 3.6 s standing: settled, tilted by ~0.7 deg
        w.step(standing_torques(w, model))
    v_start = w.base_state().linear_velocity
    measured, rotations = [], []
    for _ in range(100):
        w.step(standing_torques(w, model))
        omega, f = w.imu_truth()
        b = w.base_state()
        R = pin.Quaternion(b.quaternion[3], *b.quaternion[:3]).toRotationMatrix()
        np.testing.assert_allclose(omega, 0.0, atol=1e-3)
        np.testing.assert_allclose(f, R.T @ [0.0, 0.0, G], atol=2e-2)   # contact jitter
        measured.append(f)
        rotations.append(R)
    # The velocity differences telescope over the 0.4 s: gravity plus the slow creep left
    # (the standing PD still drifts by ~1 mm/s).
    creep = (w.base_state().linear_velocity - v_start) / (100 * w.control_period)
    expected = np.mean([R.T @ (creep + np.array([0.0, 0.0, G])) for R in rotations], axis=0)
    np.testing.assert_allclose(np.mean(measured, axis=0), expected, atol=1e-4)
    assert np.linalg.norm(np.mean(measured, axis=0)) == pytest.approx(G, abs=3e-3)
    air = world_factory(initial_base_height=5.0)
    for _ in range(10):
        air.step(np.zeros(12))
    np.testing.assert_allclose(air.imu_truth()[1], 0.0, atol=1e-9)   # free fall reads 0


def test_imu_truth_push_and_rotation(world_factory, model):
    mass = pin.computeTotalMass(model[0])
    w = world_factory(initial_base_height=5.0)
    force = np.array([400.0, -250.0, 0.0])
    w.set_external_wrench(force, np.array([0.0, 0.0, 30.0]))
    for _ in range(25):
        w.step(np.zeros(12))
    omega, f = w.imu_truth()
    b = w.base_state()
    R = pin.Quaternion(b.quaternion[3], *b.quaternion[:3]).toRotationMatrix()
    np.testing.assert_allclose(omega, R.T @ b.angular_velocity, atol=1e-12)
    assert omega[2] > 0.1                     # yawing left under the +z torque
    # Pushed at the base origin with limp legs: the origin accelerates somewhat more than the
    # whole robot's CoM (F / M); the sign and size must be right.
    f_world = R @ f
    np.testing.assert_allclose(f_world[:2], force[:2] / mass, rtol=0.3)


def test_compliant_feet_sink_and_stay_stable(world_factory, model):
    k, c = 1e5, 600.0
    rigid = world_factory()
    soft = world_factory(contact_stiffness=k, contact_damping=c)
    z = {}
    for name, w in (('rigid', rigid), ('soft', soft)):
        heights, vz = [], []
        for _ in range(500):                  # 2 s
            w.step(standing_torques(w, model))
            b = w.base_state()
            heights.append(b.position[2])
            vz.append(b.linear_velocity[2])
        assert np.max(np.abs(vz[-100:])) < 1e-3, name          # settled, no oscillation
        assert w.contact_state().contact.all()
        z[name] = heights[-1]
    weight = pin.computeTotalMass(model[0]) * G
    sink = z['rigid'] - z['soft']
    assert sink == pytest.approx(weight / 4 / k, rel=0.3)      # about 2 mm
    feet = soft.contact_state().foot_position[:, 2]
    assert np.all(feet < FOOT_RADIUS - 1e-3) and np.all(feet > FOOT_RADIUS - 4e-3)


def test_bad_realism_configuration():
    with pytest.raises(ValueError):
        ActuatorParams(time_constant=-0.001)
    with pytest.raises(ValueError):
        ActuatorParams(torque_limit_scale=0.0)
    with pytest.raises(ValueError):
        SimWorld(URDF, contact_damping=100.0)            # damping without stiffness
    with pytest.raises(ValueError):
        SimWorld(URDF, contact_stiffness=-1.0)


def _world_vector(world) -> np.ndarray:
    joints, base, contacts = world.joint_state(), world.base_state(), world.contact_state()
    return np.concatenate([joints.position, joints.velocity, joints.effort, base.position,
                           base.quaternion, base.linear_velocity, world.imu_truth()[1],
                           contacts.force.ravel(), contacts.contact])


@pytest.mark.parametrize('actuator', [
    None,                                                    # ideal: no lead steps
    ActuatorParams(time_constant=0.003, delay=0.002, coulomb_friction=1.0),   # 2 of 4
    ActuatorParams(delay=0.006),                             # beyond a period: all 4
])
def test_begin_and_finish_step_are_exactly_step(world_factory, actuator):
    # The sim node runs the lead physics steps while the controller computes the command:
    # the trajectory must be bit for bit the one of step(), pushes and friction included.
    whole, split = world_factory(actuator=actuator), world_factory(actuator=actuator)
    expected_lead = 0 if actuator is None else min(round(actuator.delay / 0.001), 4)
    assert split.lead_steps == expected_lead
    rng = np.random.default_rng(3)
    for k in range(150):
        torques = rng.normal(0.0, 20.0, 12)
        if k == 40:
            for world in (whole, split):
                world.set_external_wrench(np.array([0.0, 60.0, 0.0]), np.zeros(3))
        whole.step(torques)
        before = _world_vector(split)
        split.begin_step()
        split.begin_step()                          # a second call does nothing
        assert split.begun
        moved = not np.array_equal(
            np.concatenate([split.joint_state().position, split.base_state().position]),
            np.concatenate([before[:12], before[36:39]]))
        assert moved == (expected_lead > 0)
        split.finish_step(torques)
        assert not split.begun
        np.testing.assert_array_equal(_world_vector(split), _world_vector(whole))
    assert split.tick == whole.tick == 150


def test_from_settings_builds_the_world_of_the_keywords(world_factory):
    # The sim node builds its world from WorldSettings: the same world, bit for bit, as the
    # constructor's keywords, spawn pose, terrain, contacts and actuators included.
    pose = STANDING_POSE + 0.05
    actuator = ActuatorParams(time_constant=0.003, delay=0.002, coulomb_friction=1.0)
    settings = WorldSettings(
        physics_dt=0.0005, control_period=0.004, initial_joint_positions=tuple(pose),
        initial_base_height=0.7, terrain=TerrainSettings(kind='step_up', step_x=0.3,
                                                         step_height=0.05),
        seed=3, friction=0.6, contact_stiffness=1.0e5, contact_damping=600.0,
        contact_threshold=25.0, debounce_ticks=3, actuator=actuator)
    built = SimWorld.from_settings(URDF, settings, joint_names=JOINT_NAMES,
                                   foot_frames=FOOT_FRAMES)
    keywords = world_factory(
        physics_dt=0.0005, control_period=0.004, initial_joint_positions=pose,
        initial_base_height=0.7, terrain='step_up',
        terrain_params={'step_x': 0.3, 'step_height': 0.05}, seed=3, friction=0.6,
        contact_stiffness=1.0e5, contact_damping=600.0, contact_threshold=25.0,
        debounce_ticks=3, actuator=actuator)
    try:
        assert built.actuator == actuator and built.control_period == 0.004
        torques = np.random.default_rng(5).normal(0.0, 20.0, (60, 12))
        for tau in torques:
            built.step(tau)
            keywords.step(tau)
        np.testing.assert_array_equal(_world_vector(built), _world_vector(keywords))
    finally:
        built.close()


def test_default_settings_build_the_constructors_default_world(world_factory):
    built = SimWorld.from_settings(URDF, WorldSettings())
    try:
        np.testing.assert_array_equal(_world_vector(built), _world_vector(world_factory()))
        assert built.actuator == ActuatorParams() and built.control_period == 0.004
    finally:
        built.close()
    assert TerrainSettings().sizes() == TERRAIN_DEFAULTS
    with pytest.raises(ValueError, match='terrain must be one of'):
        TerrainSettings(kind='ice')


def test_finish_step_rejects_bad_torques_and_goes_on(world_factory):
    world = world_factory(actuator=ActuatorParams(delay=0.002))
    world.begin_step()
    with pytest.raises(ValueError, match='NaN'):
        world.finish_step(np.full(12, np.nan))
    world.finish_step(np.zeros(12))              # the begun period ends with safe torques
    assert world.tick == 1


def test_pybullet_functions_bound_once(world_factory):
    """The client binds each pybullet function once (a cut of the per-call partial), never
    ``disconnect``, which resets the client id."""
    world = world_factory()
    client = world._p
    assert client.getJointStates is client.getJointStates
    assert 'disconnect' not in vars(client)


def test_batched_queries_give_the_per_call_values(world_factory, model):
    """One getLinkStates call gives the feet the per-foot getLinkState calls gave, and the
    joint friction on the 12 joints at once the per-joint ``min`` / ``max`` expression,
    NaN and signed zeros included: the cuts keep runs bit-exact."""
    world = world_factory()
    p, robot = world._p, world._robot
    for _ in range(20):
        world.step(standing_torques(world, model) + 30.0)
        single = np.array([p.getLinkState(robot, link, computeForwardKinematics=True)[4]
                           for link in world._feet])
        assert world.contact_state().foot_position.tobytes() == single.tobytes()
    velocity = np.concatenate([np.random.default_rng(0).normal(0.0, 3.0, 200),
                               [np.nan, np.inf, -np.inf, 0.0, -0.0, 1.0, -1.0]])
    torque = np.random.default_rng(1).normal(0.0, 50.0, len(velocity))
    tau_c, inv_v = 2.3, 1.7
    per_joint = [f - tau_c * max(-1.0, min(1.0, s * inv_v))
                 for f, s in zip(torque.tolist(), velocity.tolist(), strict=True)]
    batched = torque - tau_c * np.fmax(-1.0, np.fmin(1.0, velocity * inv_v))
    assert np.array(per_joint).tobytes() == batched.tobytes()
