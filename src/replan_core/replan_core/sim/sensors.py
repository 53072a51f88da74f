"""Sensor models between the simulator's truth and what the controller sees: IMU and joints.

Each sensor owns its random streams, derived from ``SeedSequence([seed, sensor, component])``
(one stream per noise component), so the same seed gives the same samples, and switching one
component on or off does not change the draws of any other. A component whose parameter is 0
draws nothing and adds nothing: all-zero parameters return the truth exactly.

Suggested realistic values (``REALISTIC_IMU``, ``REALISTIC_JOINTS``) are given with their
sources; the dataclass defaults are the ideal (noise-free) sensors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from replan_core.common.types import ImuReading, JointState

# Sensor index in the seed sequence; replan_core.robot.variant uses 2 for its mass errors.
_IMU_STREAM = 0
_JOINT_STREAM = 1


def _stream(seed: int, sensor: int, component: int) -> np.random.Generator:
    if seed < 0:
        raise ValueError(f'seed must be >= 0, got {seed}')
    return np.random.default_rng(np.random.SeedSequence([int(seed), sensor, component]))


def _check_non_negative(params: object) -> None:
    for name, value in vars(params).items():
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f'{type(params).__name__}.{name} must be finite and >= 0')


@dataclass(frozen=True)
class ImuNoiseParams:
    """Continuous-time IMU noise model (the Kalibr / Allan-variance convention), per axis."""

    gyro_noise_density: float = 0.0          # rad/s/sqrt(Hz), white noise
    gyro_bias_random_walk: float = 0.0       # rad/s^2/sqrt(Hz), bias drift
    gyro_initial_bias: float = 0.0           # rad/s, std of the bias at start
    accel_noise_density: float = 0.0         # m/s^2/sqrt(Hz), white noise
    accel_bias_random_walk: float = 0.0      # m/s^3/sqrt(Hz), bias drift
    accel_initial_bias: float = 0.0          # m/s^2, std of the bias at start

    def __post_init__(self) -> None:
        _check_non_negative(self)


# LORD (now HBK) MicroStrain 3DM-GX5-25, a MEMS AHRS used on legged robots. The figures are
# quoted from memory of its datasheet (gyro range 300 deg/s, accelerometer 8 g), not from a
# copy at hand; the conversions are:
# - gyro noise density 0.005 deg/s/sqrt(Hz) x pi/180 = 8.73e-5 rad/s/sqrt(Hz);
# - accelerometer noise density 100 ug/sqrt(Hz) x 9.80665e-6 = 9.81e-4 m/s^2/sqrt(Hz);
# - bias instability B (the floor of the Allan deviation): gyro 8 deg/h = 3.88e-5 rad/s,
#   accelerometer 0.04 mg = 3.92e-4 m/s^2. A datasheet gives no rate random walk K; we take
#   the K whose Allan deviation K sqrt(tau / 3) reaches B at tau = 1000 s (where a MEMS
#   floor typically ends): K = B sqrt(3 / 1000 s) -> gyro 2.1e-6 rad/s^2/sqrt(Hz),
#   accelerometer 2.1e-5 m/s^3/sqrt(Hz). Over a 60 s run the gyro bias then drifts by about
#   K sqrt(60 s) = 1.6e-5 rad/s (3.4 deg/h), below B, as in-run drift should be;
# - initial bias error (after the factory calibration): gyro 0.04 deg/s = 6.98e-4 rad/s,
#   accelerometer 2 mg = 1.96e-2 m/s^2, used as the std of the bias at start.
REALISTIC_IMU = ImuNoiseParams(
    gyro_noise_density=math.radians(0.005),
    gyro_bias_random_walk=math.radians(8.0 / 3600.0) * math.sqrt(3.0 / 1000.0),
    gyro_initial_bias=math.radians(0.04),
    accel_noise_density=100e-6 * 9.80665,
    accel_bias_random_walk=0.04e-3 * 9.80665 * math.sqrt(3.0 / 1000.0),
    accel_initial_bias=2e-3 * 9.80665,
)


class ImuSensor:
    """A 3-axis gyro and accelerometer sampled every ``dt``: truth + bias + white noise.

    Discretisation: white noise std = density / sqrt(dt) per sample; the bias is drawn once
    (std = initial bias) and then takes a random-walk step of std = random walk x sqrt(dt) at
    every sample, before the sample is formed.
    """

    def __init__(self, params: ImuNoiseParams, dt: float, seed: int = 0) -> None:
        if not dt > 0.0:
            raise ValueError(f'dt must be > 0, got {dt}')
        self.params = params
        self.dt = dt
        sqrt_dt = math.sqrt(dt)
        self._gyro_white = params.gyro_noise_density / sqrt_dt       # rad/s
        self._gyro_walk = params.gyro_bias_random_walk * sqrt_dt     # rad/s per sample
        self._accel_white = params.accel_noise_density / sqrt_dt     # m/s^2
        self._accel_walk = params.accel_bias_random_walk * sqrt_dt   # m/s^2 per sample
        rngs = [_stream(seed, _IMU_STREAM, k) for k in range(6)]
        (self._rng_gyro_white, self._rng_gyro_walk, rng_gyro_bias,
         self._rng_accel_white, self._rng_accel_walk, rng_accel_bias) = rngs
        self.gyro_bias = (rng_gyro_bias.normal(0.0, params.gyro_initial_bias, 3)
                          if params.gyro_initial_bias > 0.0 else np.zeros(3))     # rad/s
        self.accel_bias = (rng_accel_bias.normal(0.0, params.accel_initial_bias, 3)
                           if params.accel_initial_bias > 0.0 else np.zeros(3))   # m/s^2

    def measure(self, stamp: float, angular_velocity_body: np.ndarray,
                specific_force_body: np.ndarray) -> ImuReading:
        """One sample from the true angular velocity (rad/s) and specific force (m/s^2),
        both (3,) in the IMU (base_link) axes."""
        gyro = np.array(angular_velocity_body, dtype=float)
        accel = np.array(specific_force_body, dtype=float)
        if self._gyro_walk > 0.0:
            self.gyro_bias = self.gyro_bias + self._rng_gyro_walk.normal(0.0, self._gyro_walk, 3)
        if self._accel_walk > 0.0:
            self.accel_bias = self.accel_bias + self._rng_accel_walk.normal(
                0.0, self._accel_walk, 3)
        if self.params.gyro_initial_bias > 0.0 or self._gyro_walk > 0.0:
            gyro += self.gyro_bias
        if self.params.accel_initial_bias > 0.0 or self._accel_walk > 0.0:
            accel += self.accel_bias
        if self._gyro_white > 0.0:
            gyro += self._rng_gyro_white.normal(0.0, self._gyro_white, 3)
        if self._accel_white > 0.0:
            accel += self._rng_accel_white.normal(0.0, self._accel_white, 3)
        return ImuReading(stamp=stamp, angular_velocity=gyro, linear_acceleration=accel)


@dataclass(frozen=True)
class JointSensorParams:
    """Joint encoders and torque sensors; the defaults are exact."""

    encoder_counts_per_rev: int = 0     # counts per joint revolution; 0 = no quantisation
    position_noise: float = 0.0         # rad, std, on top of the quantisation
    velocity_noise: float = 0.0         # rad/s, std (velocity from differentiated encoders)
    torque_noise: float = 0.0           # N m, std (load cell)

    def __post_init__(self) -> None:
        if int(self.encoder_counts_per_rev) != self.encoder_counts_per_rev:
            raise ValueError('encoder_counts_per_rev must be an integer')
        _check_non_negative(self)


# HyQ's joints carried a relative encoder (Avago AEDA-3300) with 80 000 counts per revolution
# after quadrature, beside a 12-bit absolute encoder for the start-up position (Semini et al.,
# "Design of HyQ", 2011; quoted from memory): a step of 2 pi / 80000 = 7.9e-5 rad, so the
# quantisation alone is 2.3e-5 rad rms and no further position noise is added. Velocity: the
# difference of two such positions at 1 kHz has a std of 7.9e-5 / sqrt(6) / 1 ms = 0.032 rad/s
# before any filtering; 0.02 rad/s for the lightly filtered estimate. Torque: HyQ measures the
# cylinder force with a load cell (hfe, kfe) and a torque sensor (haa); a few N of noise on a
# lever arm of ~0.04 m and the amplifier give about 0.2-0.5 N m (an estimate, not a datasheet
# figure): 0.3 N m.
REALISTIC_JOINTS = JointSensorParams(encoder_counts_per_rev=80_000, position_noise=0.0,
                                     velocity_noise=0.02, torque_noise=0.3)


class JointSensor:
    """Encoders (quantised position + noise), velocity estimates and torque sensors."""

    def __init__(self, params: JointSensorParams, dt: float, seed: int = 0) -> None:
        if not dt > 0.0:
            raise ValueError(f'dt must be > 0, got {dt}')
        self.params = params
        self.dt = dt        # s; the model is white, dt only documents the sampling
        counts = int(params.encoder_counts_per_rev)
        self.resolution = 2.0 * math.pi / counts if counts > 0 else 0.0   # rad per count
        self._rng_position, self._rng_velocity, self._rng_torque = (
            _stream(seed, _JOINT_STREAM, k) for k in range(3))

    def measure(self, state: JointState) -> JointState:
        """The sensed joint state (a new object; ``state`` is left untouched)."""
        p = self.params
        position = np.array(state.position, dtype=float)
        velocity = np.array(state.velocity, dtype=float)
        effort = np.array(state.effort, dtype=float)
        if self.resolution > 0.0:
            position = np.round(position / self.resolution) * self.resolution
        if p.position_noise > 0.0:
            position += self._rng_position.normal(0.0, p.position_noise, position.shape)
        if p.velocity_noise > 0.0:
            velocity += self._rng_velocity.normal(0.0, p.velocity_noise, velocity.shape)
        if p.torque_noise > 0.0:
            effort += self._rng_torque.normal(0.0, p.torque_noise, effort.shape)
        return JointState(stamp=state.stamp, position=position, velocity=velocity,
                          effort=effort)
