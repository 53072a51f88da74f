"""The state estimator's settings, ``EstimatorParams`` (the wbc node fills them from its
``estimator.<field>`` parameters). No pinocchio or scipy, so that the ROS parameter tables read
their defaults without loading them."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class EstimatorParams:
    """Tuning of the state estimator (the node fills it from its parameter file)."""

    # contact estimation (from joint torques and the model)
    contact_force_threshold: float = 40.0  # N, estimated normal force for a touchdown
    # N, a foot in contact loses it only below this force (hysteresis): in the crawl the foot
    # diagonal to the swing leg carries 30-50 N, and one threshold made its flag flicker
    contact_release_threshold: float = 15.0
    contact_debounce_ticks: int = 2        # ticks the estimate must stay above/below
    # 1/s, gain K of the momentum observer of the foot forces (its time constant is 1 / K);
    # 0 takes the static estimate f = J^-T (h - tau), which leaves out the legs' inertia
    contact_observer_gain: float = 150.0
    jacobian_damping: float = 0.02         # m, damped least squares of J^-T near a stretched knee
    foot_radius: float = 0.02175           # m, foot frame (sphere centre) above ground at spawn
    # attitude filter (Mahony): roll/pitch follow the accelerometer with a time constant 1/gain
    attitude_gain: float = 0.5             # 1/s, roll/pitch correction (time constant 2 s)
    gyro_bias_gain: float = 0.02           # 1/s^2, integral gain of the gyro bias estimate
    gyro_bias_limit: float = 0.05          # rad/s, largest gyro bias the estimate may take
    accel_gate: float = 2.0                # m/s^2, no tilt correction when ||f| - g| exceeds it
    # Kalman filter noises (white-noise densities are per sqrt(s): variance grows with dt)
    accel_noise: float = 0.3               # m/s^2/sqrt(Hz), accelerometer in the velocity
    base_position_noise: float = 0.001     # m/sqrt(s), extra random walk of the base position
    foot_stance_noise: float = 0.005       # m/sqrt(s), a stance foot's random walk (slip, roll)
    foot_swing_noise: float = 5.0          # m/sqrt(s), a foot not in contact is free
    foot_position_noise: float = 0.003     # m, kinematic foot position (encoders, model)
    foot_velocity_noise: float = 0.03      # m/s, base velocity from one stance leg
    swing_velocity_noise: float = 10.0     # m/s, same from a swing leg (ignored in effect)
    initial_position_noise: float = 0.01   # m, standard deviation of the initial base position
    initial_velocity_noise: float = 0.05   # m/s, same for the initial (zero) velocity
