"""Sensor models: exact when off, noise and bias statistics, seeding, quantisation."""

import math

import numpy as np
import pytest

from replan_core.common.types import JointState
from replan_core.sim.sensors import (
    REALISTIC_IMU,
    REALISTIC_JOINTS,
    ImuNoiseParams,
    ImuSensor,
    JointSensor,
    JointSensorParams,
)

DT = 0.004                      # s, the control period
OMEGA = np.array([0.1, -0.2, 0.3])
FORCE = np.array([0.5, -0.4, 9.81])


def joint_state(rng: np.random.Generator) -> JointState:
    return JointState(stamp=1.0, position=rng.uniform(-2.0, 2.0, 12),
                      velocity=rng.normal(0.0, 1.0, 12), effort=rng.normal(0.0, 50.0, 12))


def imu_samples(params: ImuNoiseParams, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    sensor = ImuSensor(params, DT, seed)
    readings = [sensor.measure(k * DT, OMEGA, FORCE) for k in range(n)]
    return (np.array([r.angular_velocity for r in readings]),
            np.array([r.linear_acceleration for r in readings]))


def test_zero_parameters_give_the_truth():
    reading = ImuSensor(ImuNoiseParams(), DT, 3).measure(0.5, OMEGA, FORCE)
    assert reading.stamp == 0.5
    assert np.array_equal(reading.angular_velocity, OMEGA)
    assert np.array_equal(reading.linear_acceleration, FORCE)
    truth = joint_state(np.random.default_rng(0))
    sensed = JointSensor(JointSensorParams(), DT, 3).measure(truth)
    for name in ('position', 'velocity', 'effort'):
        assert np.array_equal(getattr(sensed, name), getattr(truth, name))
    assert sensed.stamp == truth.stamp and sensed.position is not truth.position


def test_white_noise_std_matches_density():
    params = ImuNoiseParams(gyro_noise_density=1e-3, accel_noise_density=2e-3)
    gyro, accel = imu_samples(params, 20000)
    np.testing.assert_allclose((gyro - OMEGA).std(axis=0), 1e-3 / math.sqrt(DT), rtol=0.1)
    np.testing.assert_allclose((accel - FORCE).std(axis=0), 2e-3 / math.sqrt(DT), rtol=0.1)
    np.testing.assert_allclose((gyro - OMEGA).mean(axis=0), 0.0,
                               atol=4 * 1e-3 / math.sqrt(DT) / math.sqrt(20000))


def test_bias_random_walk_variance_grows_linearly():
    rw = 1e-3                   # rad/s^2/sqrt(Hz)
    params = ImuNoiseParams(gyro_bias_random_walk=rw)
    runs = np.array([imu_samples(params, 100, seed)[0] - OMEGA for seed in range(300)])
    for n in (25, 50, 100):     # ensemble variance over 300 seeds x 3 axes after n samples
        variance = runs[:, n - 1, :].var()
        assert variance == pytest.approx(n * rw**2 * DT, rel=0.15), n


def test_initial_bias_std():
    params = ImuNoiseParams(gyro_initial_bias=0.01, accel_initial_bias=0.1)
    biases = [ImuSensor(params, DT, seed) for seed in range(1000)]
    assert np.std([s.gyro_bias for s in biases]) == pytest.approx(0.01, rel=0.1)
    assert np.std([s.accel_bias for s in biases]) == pytest.approx(0.1, rel=0.1)
    # The bias is constant without a random walk: the white-noise-free samples repeat.
    gyro, _ = imu_samples(params, 3, seed=5)
    assert np.array_equal(gyro[0], gyro[2]) and not np.array_equal(gyro[0], OMEGA)


def test_same_seed_same_samples_and_independent_streams():
    gyro_a, accel_a = imu_samples(REALISTIC_IMU, 50, seed=11)
    gyro_b, accel_b = imu_samples(REALISTIC_IMU, 50, seed=11)
    gyro_c, _ = imu_samples(REALISTIC_IMU, 50, seed=12)
    assert np.array_equal(gyro_a, gyro_b) and np.array_equal(accel_a, accel_b)
    assert not np.array_equal(gyro_a, gyro_c)
    # Switching the gyro noise off leaves the accelerometer's draws as they were.
    accel_only = ImuNoiseParams(**{**vars(REALISTIC_IMU), 'gyro_noise_density': 0.0,
                                   'gyro_bias_random_walk': 0.0, 'gyro_initial_bias': 0.0})
    gyro_d, accel_d = imu_samples(accel_only, 50, seed=11)
    assert np.array_equal(accel_d, accel_a) and np.array_equal(gyro_d, np.tile(OMEGA, (50, 1)))
    # The same for the joint sensor: velocity noise off, the torque noise is unchanged.
    truth = joint_state(np.random.default_rng(1))
    full = JointSensor(REALISTIC_JOINTS, DT, 4)
    torque_only = JointSensor(JointSensorParams(torque_noise=REALISTIC_JOINTS.torque_noise),
                              DT, 4)
    for _ in range(5):
        a, b = full.measure(truth), torque_only.measure(truth)
        assert np.array_equal(a.effort, b.effort)
        assert np.array_equal(b.velocity, truth.velocity)


def test_encoder_quantisation_step():
    counts = 4096
    step = 2.0 * math.pi / counts
    sensor = JointSensor(JointSensorParams(encoder_counts_per_rev=counts), DT, 0)
    truth = JointState(stamp=0.0, position=np.linspace(-1.0, 1.0, 12) + 1e-5,
                       velocity=np.zeros(12), effort=np.zeros(12))
    sensed = sensor.measure(truth).position
    assert sensor.resolution == step
    np.testing.assert_allclose(sensed / step, np.round(sensed / step), atol=1e-9)
    assert np.all(np.abs(sensed - truth.position) <= step / 2 + 1e-12)
    # A sweep through one step changes the reading by exactly one step.
    sweep = np.linspace(0.0, 3 * step, 12)
    levels = np.unique(sensor.measure(JointState(0.0, sweep, np.zeros(12),
                                                 np.zeros(12))).position)
    np.testing.assert_allclose(np.diff(levels), step, rtol=1e-12)


def test_joint_noise_std():
    params = JointSensorParams(position_noise=1e-3, velocity_noise=0.05, torque_noise=0.5)
    sensor = JointSensor(params, DT, 2)
    truth = joint_state(np.random.default_rng(3))
    sensed = [sensor.measure(truth) for _ in range(2000)]       # 24000 samples each
    for name, std in (('position', 1e-3), ('velocity', 0.05), ('effort', 0.5)):
        error = np.array([getattr(s, name) for s in sensed]) - getattr(truth, name)
        assert error.std() == pytest.approx(std, rel=0.1), name


def test_realistic_values_and_validation():
    # 3DM-GX5-25 conversions (see sensors.py).
    assert REALISTIC_IMU.gyro_noise_density == pytest.approx(8.727e-5, rel=1e-3)
    assert REALISTIC_IMU.accel_noise_density == pytest.approx(9.807e-4, rel=1e-3)
    assert REALISTIC_JOINTS.encoder_counts_per_rev == 80_000
    with pytest.raises(ValueError):
        ImuNoiseParams(gyro_noise_density=-1.0)
    with pytest.raises(ValueError):
        JointSensorParams(encoder_counts_per_rev=100.5)
    with pytest.raises(ValueError):
        ImuSensor(ImuNoiseParams(), 0.0, 0)
    with pytest.raises(ValueError):
        JointSensor(JointSensorParams(), DT, -1)
