"""replan_core.estimation.estimator in the PyBullet world: IMU synthesised from the
simulator's truth.

The IMU is built here from the ground truth of each tick (gyro R^T w, accelerometer
R^T (a - g) with a the finite difference of the base_link origin velocity), with white noise and
a constant bias from a seeded generator; the joints get encoder and torque noise. The controller
is fed the ground truth (these tests check the estimator, not the loop), except in
``test_closed_loop_on_the_estimate``.
"""

import math
import time
from pathlib import Path

import numpy as np
import pytest

from replan_core.common.rotations import quaternion_to_matrix, yaw_of
from replan_core.common.types import STANDING_POSE, BaseState, ImuReading, JointState
from replan_core.estimation.estimator import StateEstimator
from replan_core.estimation.settings import EstimatorParams
from replan_core.wbc.controller import SwingReference, WholeBodyController

ROOT = Path(__file__).resolve().parents[4]
DT = 0.004                                  # s, control period
G_WORLD = np.array([0.0, 0.0, -9.81])       # m/s^2
GYRO_BIAS = np.array([0.002, -0.002, 0.002])   # rad/s, a decent MEMS gyro after calibration
ACCEL_BIAS = np.array([0.03, -0.03, 0.03])     # m/s^2


class Sensors:
    """Noisy IMU and joint samples from the simulator's truth (seeded)."""

    def __init__(self, seed: int = 7, gyro_noise: float = 0.005, accel_noise: float = 0.05,
                 q_noise: float = 2e-4, qd_noise: float = 0.02, tau_noise: float = 0.5) -> None:
        self.rng = np.random.default_rng(seed)
        self.gyro_noise, self.accel_noise = gyro_noise, accel_noise   # rad/s, m/s^2 (1 sigma)
        self.q_noise, self.qd_noise, self.tau_noise = q_noise, qd_noise, tau_noise
        self._previous_velocity = None

    def imu(self, base: BaseState) -> ImuReading:
        rotation = quaternion_to_matrix(base.quaternion)
        if self._previous_velocity is None:
            accel_world = np.zeros(3)
        else:
            accel_world = (base.linear_velocity - self._previous_velocity) / DT
        self._previous_velocity = np.array(base.linear_velocity, dtype=float)
        gyro = rotation.T @ base.angular_velocity + GYRO_BIAS
        accel = rotation.T @ (accel_world - G_WORLD) + ACCEL_BIAS
        return ImuReading(base.stamp, gyro + self.gyro_noise * self.rng.normal(size=3),
                          accel + self.accel_noise * self.rng.normal(size=3))

    def joints(self, joints: JointState) -> JointState:
        n = len(joints.position)
        return JointState(joints.stamp, joints.position + self.q_noise * self.rng.normal(size=n),
                          joints.velocity + self.qd_noise * self.rng.normal(size=n),
                          joints.effort + self.tau_noise * self.rng.normal(size=n))


def run(world, robot, estimator, reference, duration, sensors=None, use_estimate=False):
    """Close the loop for ``duration`` s; ``reference(t, base, contact)`` gives the WBC's
    (com_ref, yaw, stance, swing). Returns per tick (t, true base, true contacts, estimated
    base, estimated contacts, update time s)."""
    sensors = sensors or Sensors()
    wbc = WholeBodyController(robot)
    log = []
    for _ in range(round(duration / DT)):
        base, joints, contact = world.base_state(), world.joint_state(), world.contact_state()
        imu, measured = sensors.imu(base), sensors.joints(joints)
        start = time.perf_counter()
        est_base, est_contact = estimator.update(imu, measured)
        elapsed = time.perf_counter() - start
        log.append((world.time, base, contact, est_base, est_contact, elapsed))
        if use_estimate:
            base, joints, contact = est_base, measured, est_contact
        com_ref, yaw, stance, swing = reference(world.time, base, contact)
        result = wbc.compute(base, joints, contact.contact, com_ref, yaw, stance, swing)
        assert not result.fallback, result.message
        world.step(result.torque)
    return log


def roll_pitch(quaternion) -> np.ndarray:
    x, y, z, w = quaternion
    return np.array([np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
                     np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))])


def velocity_rmse(log) -> float:
    errors = np.array([e.linear_velocity - b.linear_velocity for _, b, _, e, *_ in log])
    return float(np.sqrt(np.mean(np.sum(errors**2, axis=1))))


def print_timing(name, log) -> None:
    us = 1e6 * np.array([entry[-1] for entry in log[1:]])
    print(f'\n{name}: StateEstimator.update median {np.median(us):.0f} us, '
          f'p99 {np.percentile(us, 99):.0f} us over {len(us)} ticks')


def hold(com) -> tuple:
    return lambda t, b, c: ((com, np.zeros(3), np.zeros(3)), 0.0, np.ones(4, bool), ())


def initial_com(world, robot) -> np.ndarray:
    return robot.com_state(world.base_state(), world.joint_state())[0]


def assert_finite(base, contact) -> None:
    for array in (base.position, base.quaternion, base.linear_velocity, base.angular_velocity,
                  contact.foot_position, contact.force):
        assert np.all(np.isfinite(array))


# ------------------------------------------------------------------------------------- tests
def test_standing(world, robot):
    """5 s standing: height within 1 cm, roll/pitch within 0.01 rad, velocity RMSE < 2 cm/s,
    four contacts and no edge; the GRF from joint torques within 15 % of PyBullet's."""
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    log = run(world, robot, estimator, hold(initial_com(world, robot)), 5.0)
    print_timing('standing', log)
    for _, base, _, est, est_contact, _ in log:
        assert abs(est.position[2] - base.position[2]) < 0.01
        assert np.abs(roll_pitch(est.quaternion) - roll_pitch(base.quaternion)).max() < 0.01
        assert est_contact.contact.all()
        assert not est_contact.touchdown.any() and not est_contact.liftoff.any()
        assert_finite(est, est_contact)
    assert velocity_rmse(log) < 0.02
    final_error = log[-1][3].position - log[-1][1].position
    assert np.linalg.norm(final_error[:2]) < 0.02          # m, drift over 5 s
    # Tick 0 has no torque applied yet (and no force in the sim); the momentum observer
    # follows the step of tick 1 with its time constant 1 / K: compare after 5 of them.
    settled = 1 + math.ceil(5.0 / (EstimatorParams().contact_observer_gain * DT))
    for _, _, contact, _, est_contact, _ in log[settled:]:
        true_fz, est_fz = contact.force[:, 2], est_contact.force[:, 2]
        assert np.all(np.abs(est_fz - true_fz) < 0.15 * true_fz)
    assert estimator.rejected_samples == 0


def test_leg_lift_edges_follow_the_simulator(world, robot):
    """lf lifted by the controller (CoM first shifted into the other three feet), then lowered:
    lift-off and touchdown edges within 2 ticks of the simulator's; a swing foot is free."""
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    com0 = initial_com(world, robot)
    feet0 = world.contact_state().foot_position.copy()
    goal = com0.copy()
    goal[:2] += 0.6 * (feet0[[1, 2, 3], :2].mean(axis=0) - com0[:2])
    t_lift, t_down = 1.6, 2.0

    def reference(t, base, contact):
        s = min(t / 1.5, 1.0)
        com_ref = (com0 + (goal - com0) * s**3 * (10 - 15 * s + 6 * s * s), np.zeros(3),
                   np.zeros(3))
        stance, swing = np.ones(4, bool), ()
        if t >= t_lift and not (t > t_down and contact.contact[0]):
            # Up 8 cm, then down at 0.25 m/s until the sensed contact.
            height = 0.08 if t < t_down else 0.08 - 0.25 * (t - t_down)
            stance[0] = False
            swing = (SwingReference(0, feet0[0] + [0.0, 0.0, height], np.zeros(3),
                                    np.zeros(3)),)
        return com_ref, 0.0, stance, swing

    log = run(world, robot, estimator, reference, 3.0)
    print_timing('leg lift', log)

    def edge_ticks(index, kind):
        return [k for k, entry in enumerate(log) if getattr(entry[index], kind)[0]]

    for kind in ('liftoff', 'touchdown'):
        true, est = edge_ticks(2, kind), edge_ticks(4, kind)
        assert len(true) == 1 and len(est) == 1, (kind, true, est)
        assert abs(true[0] - est[0]) <= 2
    # No other foot saw an edge.
    for *_, est_contact, _ in log:
        assert not est_contact.touchdown[1:].any() and not est_contact.liftoff[1:].any()
    # The lifted foot is at its height relative to the base, and the base did not follow it.
    lifted = [k for k, (t, *_) in enumerate(log) if t_lift + 0.3 <= t < t_down]
    for k in lifted:
        _, base, contact, est, est_contact, _ = log[k]
        assert abs(est.position[2] - base.position[2]) < 0.01
        assert np.linalg.norm(est_contact.foot_position[0] - contact.foot_position[0]) < 0.015
        assert abs(est_contact.force[0, 2]) < 25.0          # N, the free foot
    assert velocity_rmse(log) < 0.03


class _StuckTorques:
    """Two estimators fed the same samples, in which lf's measured torques stay at their last
    value before ``t_lift`` (a swinging leg whose load seems to stay: its estimated force keeps
    above the release threshold). ``update`` gives the first, told the legs the controller
    swings, and keeps the second's base (not told) in ``blind``."""

    def __init__(self, aware: StateEstimator, blind: StateEstimator, t_lift: float,
                 t_down: float) -> None:
        self.aware, self.blind, self.t_lift, self.t_down = aware, blind, t_lift, t_down
        self.stuck, self.blind_log = None, []

    def update(self, imu, joints):
        swinging = np.zeros(4, dtype=bool)
        if self.t_lift < imu.stamp < self.t_down:
            swinging[0] = True
            effort = joints.effort.copy()
            effort[0:3] = self.stuck
            joints = JointState(joints.stamp, joints.position, joints.velocity, effort)
        else:
            self.stuck = joints.effort[0:3].copy()
        self.blind_log.append(self.blind.update(imu, joints))
        return self.aware.update(imu, joints, swinging)


def test_a_swinging_leg_anchors_nothing_whatever_force_it_shows(world, robot):
    """lf lifted 8 cm and moved 10 cm forward and back while its measured torques stay those of
    its stance: the estimator told that the controller swings lf keeps the base velocity
    within 3 cm/s; one not told takes the moving foot for an anchor and the base velocity
    follows the foot."""
    t_lift, t_down = 1.6, 2.4
    pair = _StuckTorques(StateEstimator(robot, EstimatorParams(), DT),
                         StateEstimator(robot, EstimatorParams(), DT), t_lift, t_down)
    com0 = initial_com(world, robot)
    feet0 = world.contact_state().foot_position.copy()
    goal = com0.copy()
    goal[:2] += 0.6 * (feet0[[1, 2, 3], :2].mean(axis=0) - com0[:2])
    omega = 2 * np.pi * 2.5

    def reference(t, base, contact):
        s = min(t / 1.5, 1.0)
        com_ref = (com0 + (goal - com0) * s**3 * (10 - 15 * s + 6 * s * s), np.zeros(3),
                   np.zeros(3))
        stance, swing = np.ones(4, bool), ()
        if t_lift <= t < t_down:
            rise = min((t - t_lift) / 0.1, 1.0)
            offset = np.array([0.1 * np.sin(omega * (t - t_lift)), 0.0, 0.08 * rise])
            velocity = np.array([0.1 * omega * np.cos(omega * (t - t_lift)), 0.0, 0.0])
            stance[0] = False
            swing = (SwingReference(0, feet0[0] + offset, velocity, np.zeros(3)),)
        return com_ref, 0.0, stance, swing

    log = run(world, robot, pair, reference, 2.4)
    swung = [k for k, (t, *_) in enumerate(log) if t_lift + 0.1 <= t < t_down - 0.01]
    assert all(not log[k][2].contact[0] for k in swung)          # truly free ...
    assert all(pair.blind_log[k][1].contact[0] for k in swung)   # ... and shown loaded

    def worst(bases):
        return max(np.linalg.norm(bases[k].linear_velocity - log[k][1].linear_velocity)
                   for k in swung)

    aware = worst([entry[3] for entry in log])
    blind = worst([base for base, _ in pair.blind_log])
    print(f'\nlf swinging with its stance torques: base velocity error at most {aware:.3f} m/s '
          f'(told), {blind:.3f} m/s (not told)')
    assert aware < 0.03                                           # m/s
    assert blind > 5 * aware


class _Pair:
    """Two estimators fed the same samples; ``update`` returns the first's result and keeps
    the second's estimated forces in ``other_forces``."""

    def __init__(self, first: StateEstimator, second: StateEstimator) -> None:
        self.first, self.second, self.other_forces = first, second, []

    def update(self, imu, joints):
        self.other_forces.append(self.second.update(imu, joints)[1].force.copy())
        return self.first.update(imu, joints)


def test_a_swinging_leg_shows_no_force_with_the_momentum_observer(world, robot):
    """lf lifted and swung 8 cm back and forth at 3 Hz (peak 28 m/s^2): the momentum observer's
    force on the free foot stays small, where the static estimate f = J^-T (h - tau), which
    leaves out the leg's inertia, shows a force several times larger (what made ANYmal C's
    swinging legs look like touchdowns)."""
    pair = _Pair(StateEstimator(robot, EstimatorParams(), DT),
                 StateEstimator(robot, EstimatorParams(contact_observer_gain=0.0), DT))
    com0 = initial_com(world, robot)
    feet0 = world.contact_state().foot_position.copy()
    goal = com0.copy()
    goal[:2] += 0.6 * (feet0[[1, 2, 3], :2].mean(axis=0) - com0[:2])
    t_lift, omega = 1.6, 2 * np.pi * 3.0

    def reference(t, base, contact):
        s = min(t / 1.5, 1.0)
        com_ref = (com0 + (goal - com0) * s**3 * (10 - 15 * s + 6 * s * s), np.zeros(3),
                   np.zeros(3))
        stance, swing = np.ones(4, bool), ()
        if t >= t_lift:
            rise = min((t - t_lift) / 0.2, 1.0)
            phase = max(t - t_lift - 0.2, 0.0)
            offset = np.array([0.08 * np.sin(omega * phase), 0.0, 0.08 * rise])
            velocity = np.array([0.08 * omega * np.cos(omega * phase) * (phase > 0), 0.0, 0.0])
            acceleration = np.array([-0.08 * omega**2 * np.sin(omega * phase), 0.0, 0.0])
            stance[0] = False
            swing = (SwingReference(0, feet0[0] + offset, velocity, acceleration),)
        return com_ref, 0.0, stance, swing

    log = run(world, robot, pair, reference, 3.0)
    swinging = [k for k, (t, *_) in enumerate(log) if t >= t_lift + 0.4]
    assert all(not log[k][2].contact[0] for k in swinging)      # truly free
    observer = max(abs(log[k][4].force[0, 2]) for k in swinging)
    static = max(abs(pair.other_forces[k][0, 2]) for k in swinging)
    print(f'\nfree swinging foot: |fz| max {observer:.1f} N (observer), {static:.1f} N (static)')
    assert observer < 10.0                                      # N
    assert static > 3.0 * observer
    assert not any(log[k][4].contact[0] for k in swinging)


def test_lateral_sway(world, robot):
    """CoM sine 5 cm / 0.25 Hz for 8 s: velocity RMSE < 5 cm/s, xy drift < 2 cm, height < 1 cm."""
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    com0 = initial_com(world, robot)
    amplitude, omega = 0.05, 2 * np.pi * 0.25
    offset = np.array([0.0, amplitude, 0.0])

    def reference(t, base, contact):
        return ((com0 + offset * np.sin(omega * t), offset * omega * np.cos(omega * t),
                 -offset * omega**2 * np.sin(omega * t)), 0.0, np.ones(4, bool), ())

    log = run(world, robot, estimator, reference, 8.0)
    print_timing('sway', log)
    assert velocity_rmse(log) < 0.05
    true_y = np.array([b.position[1] for _, b, *_ in log])
    assert true_y.max() - true_y.min() > 0.05                 # it really swayed
    for _, base, _, est, est_contact, _ in log:
        assert np.linalg.norm(est.position[:2] - base.position[:2]) < 0.02
        assert abs(est.position[2] - base.position[2]) < 0.01
        assert np.abs(roll_pitch(est.quaternion) - roll_pitch(base.quaternion)).max() < 0.015
        assert est_contact.contact.all()


def test_closed_loop_on_the_estimate(world, robot):
    """The controller fed only the estimate (base state and contacts) keeps HyQ standing."""
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    com_ref = initial_com(world, robot)
    log = run(world, robot, estimator, hold(com_ref), 4.0, use_estimate=True)
    final = log[-1][1]
    assert abs(final.position[2] - log[0][1].position[2]) < 0.02
    assert np.linalg.norm(final.position[:2]) < 0.03
    assert np.abs(roll_pitch(final.quaternion)).max() < 0.02
    assert all(entry[4].contact.all() for entry in log)


def test_non_finite_samples_keep_the_estimate(world, robot):
    """NaN/inf in the IMU or the joints: finite outputs, counted, and the estimate goes on."""
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    sensors = Sensors(seed=3)
    wbc = WholeBodyController(robot)
    com_ref = (initial_com(world, robot), np.zeros(3), np.zeros(3))
    bad_ticks = {100: 'gyro', 101: 'accel', 150: 'q', 151: 'qd', 152: 'tau', 200: 'all'}
    errors = []
    for k in range(400):
        base, joints, contact = world.base_state(), world.joint_state(), world.contact_state()
        imu, measured = sensors.imu(base), sensors.joints(joints)
        kind = bad_ticks.get(k)
        if kind in ('gyro', 'all'):
            imu.angular_velocity[1] = np.nan
        if kind in ('accel', 'all'):
            imu.linear_acceleration[2] = np.inf
        if kind in ('q', 'all'):
            measured.position[4] = np.nan
        if kind == 'qd':
            measured.velocity[0] = -np.inf
        if kind == 'tau':
            measured.effort = np.full(12, np.nan)
        est, est_contact = estimator.update(imu, measured)
        assert_finite(est, est_contact)
        assert est_contact.contact.all()
        errors.append(np.linalg.norm(est.position - base.position))
        result = wbc.compute(base, joints, contact.contact, com_ref, 0.0, np.ones(4, bool))
        world.step(result.torque)
    assert estimator.rejected_samples == len(bad_ticks)
    assert max(errors) < 0.02
    # Wrong shapes are bad samples too, not exceptions.
    est, _ = estimator.update(ImuReading(world.time, np.zeros(2), np.zeros(3)),
                              JointState(world.time, np.zeros(5), np.zeros(12), np.zeros(12)))
    assert np.all(np.isfinite(est.position))
    assert estimator.rejected_samples == len(bad_ticks) + 1


def test_first_sample_before_any_torque(robot):
    """At spawn (no command yet, zero torques) all feet start in contact, without edges; the
    initial attitude comes from the accelerometer, yaw and x, y from the arguments."""
    roll = 0.05
    estimator = StateEstimator(robot, EstimatorParams(), DT, initial_xy=(1.0, -2.0),
                               initial_yaw=0.7)
    accel = 9.81 * np.array([0.0, np.sin(roll), np.cos(roll)])
    joints = JointState(0.0, STANDING_POSE.copy(), np.zeros(12), np.zeros(12))
    base, contact = estimator.update(ImuReading(0.0, np.zeros(3), accel), joints)
    assert contact.contact.all() and not contact.touchdown.any() and not contact.liftoff.any()
    assert roll_pitch(base.quaternion)[0] == pytest.approx(roll, abs=1e-9)
    assert yaw_of(base.quaternion) == pytest.approx(0.7, abs=0.01)
    np.testing.assert_allclose(base.position[:2], [1.0, -2.0], atol=0.05)
    # The stance feet rest on z = 0 (their sphere centres one radius above it), on average.
    assert contact.foot_position[:, 2].mean() == pytest.approx(EstimatorParams().foot_radius)
    # A repeated stamp (the lock-step republishes a tick) gives the same answer again.
    again, _ = estimator.update(ImuReading(0.0, np.ones(3), accel), joints)
    np.testing.assert_array_equal(again.position, base.position)


def test_stretched_leg_stays_finite(robot):
    """Singular legs (knees straight): the damped inverse gives finite, bounded forces."""
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    stretched = STANDING_POSE.copy()
    stretched[2::3] = 0.0                                   # every knee straight
    joints = JointState(0.0, stretched, np.zeros(12), np.full(12, 30.0))
    imu = ImuReading(0.0, np.zeros(3), np.array([0.0, 0.0, 9.81]))
    for k in range(5):
        joints.stamp = imu.stamp = k * DT
        base, contact = estimator.update(imu, joints)
        assert_finite(base, contact)
        assert np.abs(contact.force).max() < 1e5


def test_yaw_is_not_corrected(robot):
    """Yaw integrates the gyro only (no magnetometer): a yaw rate turns it, roll/pitch stay."""
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    joints = JointState(0.0, STANDING_POSE.copy(), np.zeros(12), np.zeros(12))
    for k in range(250):
        joints.stamp = k * DT
        base, _ = estimator.update(
            ImuReading(k * DT, np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 9.81])), joints)
    assert yaw_of(base.quaternion) == pytest.approx(0.1 * 249 * DT, abs=1e-3)
    assert np.abs(roll_pitch(base.quaternion)).max() < 1e-6
    np.testing.assert_allclose(base.angular_velocity, [0.0, 0.0, 0.1], atol=1e-6)


def test_construction_errors(robot):
    with pytest.raises(ValueError):
        StateEstimator(robot, EstimatorParams(), DT, initial_xy=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        StateEstimator(robot, EstimatorParams(), 0.0)
    with pytest.raises(ValueError):
        StateEstimator(robot, EstimatorParams(contact_debounce_ticks=0), DT)


def test_restart_starts_the_position_over_from_the_feet(world, robot):
    """A drifted height (as after a stand-up from sitting, the feet carrying nothing while the
    legs moved) is gone the tick after ``restart``; x, y and the attitude are kept."""
    estimator = StateEstimator(robot, EstimatorParams(), DT, initial_xy=(0.3, -0.2))
    sensors = Sensors()
    log = run(world, robot, estimator, hold(initial_com(world, robot)), 1.0, sensors)
    before = log[-1][3]
    estimator._x[2] += 0.5          # the drift (no public way to make one: it is a failure)
    reference = hold(initial_com(world, robot))
    _, base, _, drifted, _, _ = run(world, robot, estimator, reference, DT, sensors)[-1]
    assert drifted.position[2] > base.position[2] + 0.4
    estimator.restart()
    _, base, _, est, contact, _ = run(world, robot, estimator, reference, DT, sensors)[-1]
    assert abs(est.position[2] - base.position[2]) < 0.01
    np.testing.assert_allclose(est.position[:2], before.position[:2], atol=0.01)
    np.testing.assert_allclose(est.quaternion, before.quaternion, atol=1e-3)
    assert not est.linear_velocity.any() and contact.contact.all()
    assert not contact.touchdown.any() and not contact.liftoff.any()


class RecordingSensors(Sensors):
    """Sensors that keep every sample they gave (to feed other estimators the same ticks)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.samples = []

    def imu(self, base):
        sample = super().imu(base)
        self.samples.append([sample, None])
        return sample

    def joints(self, joints):
        sample = super().joints(joints)
        self.samples[-1][1] = sample
        return sample


def test_the_observer_starts_over_after_a_gap(world, robot):
    """Standing, 10 ticks missed (dt 44 ms: one observer step would move its estimate by 6.6
    times its error): the estimated forces stay within 15 % of PyBullet's, no edge; a gain of
    1 / dt or more, or a negative one, is refused."""
    sensors = RecordingSensors(seed=5)
    log = run(world, robot, StateEstimator(robot, EstimatorParams(), DT),
              hold(initial_com(world, robot)), 1.5, sensors)
    truth = [entry[2] for entry in log]
    samples = sensors.samples
    gap = 300
    estimator = StateEstimator(robot, EstimatorParams(), DT)
    for k, (imu, joints) in enumerate(samples):
        if gap <= k < gap + 10:
            continue
        _, contact = estimator.update(imu, joints)
        if k >= gap + 10:
            true_fz = truth[k].force[:, 2]
            assert np.all(np.abs(contact.force[:, 2] - true_fz) < 0.15 * true_fz), k
            assert contact.contact.all() and not contact.touchdown.any()
            assert not contact.liftoff.any()
    for gain in (1.0 / DT, -1.0, float('nan')):
        with pytest.raises(ValueError, match='contact_observer_gain'):
            StateEstimator(robot, EstimatorParams(contact_observer_gain=gain), DT)


def test_prepared_covariance_step_changes_nothing(world, robot):
    """prepare_next between updates (as the controller calls it after its command) gives bit
    for bit the results of the same updates without it, through a lift-off and touchdown (a
    stance change and a foot reset: the prepared step is not used there), a non-finite sample,
    a repeated stamp, a missed tick and a restart; and it is used on most ticks."""
    com0 = initial_com(world, robot)
    feet0 = world.contact_state().foot_position.copy()
    goal = com0.copy()
    goal[:2] += 0.6 * (feet0[[1, 2, 3], :2].mean(axis=0) - com0[:2])

    def reference(t, base, contact):
        s = min(t / 1.0, 1.0)
        com_ref = (com0 + (goal - com0) * s**3 * (10 - 15 * s + 6 * s * s), np.zeros(3),
                   np.zeros(3))
        stance, swing = np.ones(4, bool), ()
        if t >= 1.1 and not (t > 1.4 and contact.contact[0]):
            height = 0.06 if t < 1.4 else 0.06 - 0.25 * (t - 1.4)
            stance[0] = False
            swing = (SwingReference(0, feet0[0] + [0.0, 0.0, height], np.zeros(3),
                                    np.zeros(3)),)
        return com_ref, 0.0, stance, swing

    sensors = RecordingSensors(seed=11)
    run(world, robot, StateEstimator(robot, EstimatorParams(), DT), reference, 2.0, sensors)
    samples = sensors.samples
    samples[300][1].velocity[2] = np.nan                      # a rejected joint sample
    samples.insert(200, samples[199])                          # the lock-step's republish
    del samples[400]                                           # a missed tick: dt = 8 ms

    plain = StateEstimator(robot, EstimatorParams(), DT)
    prepared = StateEstimator(robot, EstimatorParams(), DT)
    prepared_ticks = 0
    edges = 0
    for k, (imu, joints) in enumerate(samples):
        if k == 450:
            plain.restart()
            prepared.restart()
        expected = plain.update(imu, joints)
        got = prepared.update(imu, joints)
        for a, b in zip(expected, got, strict=True):
            for name in ('position', 'quaternion', 'linear_velocity', 'angular_velocity',
                         'foot_position', 'force', 'contact', 'touchdown', 'liftoff'):
                if hasattr(a, name):
                    assert np.array_equal(getattr(a, name), getattr(b, name)), (k, name)
        assert np.array_equal(plain.covariance, prepared.covariance), k
        edges += int(got[1].touchdown.any() or got[1].liftoff.any())
        # The next sample's stamp, as the controller knows it; before the missed tick, the
        # stamp that does not come.
        next_stamp = samples[min(k + 1, len(samples) - 1)][0].stamp
        if k == 398:
            next_stamp = imu.stamp + DT
        prepared_ticks += int(prepared.prepare_next(next_stamp))
    assert edges >= 2                                          # the lift-off and touchdown
    assert prepared.rejected_samples == plain.rejected_samples == 1
    assert plain.prepared_used == 0
    # Used on most ticks; not at the two edges, the rejected sample and the missed tick.
    assert 0.9 * prepared_ticks < prepared.prepared_used <= prepared_ticks - 4


def test_observer_mass_rows_are_the_symmetric_matrix(robot):
    """The legs' rows of M read from crba's upper triangle by one index are, bit for bit, the
    rows of triu(M) + triu(M, 1)^T (the form they replace), -0.0 entries included."""
    est = StateEstimator(robot, EstimatorParams())
    nv = robot.model.nv
    rng = np.random.default_rng(3)
    for _ in range(20):
        upper = np.triu(rng.normal(size=(nv, nv)))
        upper[rng.random((nv, nv)) < 0.2] = -0.0
        upper = np.asfortranarray(upper)          # pinocchio's (Eigen's) layout
        reference = (np.triu(upper) + np.triu(upper, 1).T)[est._leg_rows]
        assert (upper[est._m_rows_index] + 0.0).tobytes() == reference.tobytes()
