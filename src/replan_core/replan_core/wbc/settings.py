"""The whole-body controller's settings: its gains and limits (``WbcParams``) and those of its
per-tick protocol (``ProtocolParams``), which the wbc node fills from its parameters. Numpy only,
so that the ROS parameter tables read their defaults without loading pinocchio or proxsuite."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class WbcParams:
    """Gains and limits of the whole-body controller (the node fills them from config/wbc.yaml)."""

    com_kp: np.ndarray = field(default_factory=lambda: np.array([150.0, 150.0, 250.0]))  # 1/s^2
    com_kd: np.ndarray = field(default_factory=lambda: np.array([25.0, 25.0, 35.0]))     # 1/s
    trunk_kp: np.ndarray = field(
        default_factory=lambda: np.array([250.0, 250.0, 150.0]))   # 1/s^2, roll pitch yaw
    trunk_kd: np.ndarray = field(default_factory=lambda: np.array([35.0, 35.0, 25.0]))  # 1/s
    swing_kp: np.ndarray = field(default_factory=lambda: np.array([1500.0, 1500.0, 1500.0]))  # N/m
    swing_kd: np.ndarray = field(default_factory=lambda: np.array([50.0, 50.0, 50.0]))  # N s/m
    friction: float = 0.6           # friction coefficient mu; the pyramid uses mu / sqrt(2)
    fz_min: float = 10.0            # N, least normal force of a stance foot
    fz_max: float = 800.0           # N, largest normal force of a stance foot
    weight_force: float = 1.0       # QP weight of the linear (force) rows, 1/N^2
    weight_moment: float = 10.0     # QP weight of the angular (moment) rows, 1/(N m)^2
    regularization: float = 1e-4    # QP weight of |f|^2: spreads the load, keeps H definite
    haptic_velocity: float = 1.0    # m/s, descent of a haptic swing foot after planned touchdown
    # m, a haptic swing aims this far below its foothold: the foot lags its reference by ~1-2
    # cm, and a swing that ends exactly at ground level meets the ground late (the re-plan
    # follows the sensed touchdown, so every step would take longer than planned). A
    # non-haptic swing aims at the foothold: it may miss the ground (paper V.A).
    touchdown_depth: float = 0.015
    fallback_kp: float = 300.0      # N m/rad, joint PD of the safe stand
    fallback_kd: float = 10.0       # N m s/rad
    # Stand-up of a robot that sat down (the sim's damping mode): joint PD along a minimum-jerk
    # path from the sitting posture to the standing one, plus the weight carried by the feet.
    stand_up_time: float = 1.5      # s, sitting -> standing posture
    stand_up_hold: float = 0.5      # s, then held before the base estimate is started over
    stand_up_kp: float = 400.0      # N m/rad
    stand_up_kd: float = 15.0       # N m s/rad
    # A trunk tilted further than this from upright (the angle of its z axis to the vertical)
    # has fallen: no contact plan can right it, and tracking one swings the legs at their torque
    # limits. The joints are then only damped, until the controller is restarted.
    fall_tilt: float = 1.0          # rad (57 deg)
    # N m s/rad, joint damping of a fallen robot. Low on purpose: applied at the control rate
    # through the actuator delay, 5 made the light lower legs chatter at +-100 N m (realistic
    # profile); 1 and 2.5 did not.
    fall_damping: float = 2.0
    qp_max_iter: int = 200
    qp_eps_abs: float = 1e-6


@dataclass
class ProtocolParams:
    """The protocol's settings (the wbc node fills them from its parameters, params.WBC)."""

    control_rate: float = 250.0         # Hz, the sim's control tick rate
    plan_max_age: float = 6.0           # sim s: an older plan pair (or one past its end) -> stand
    stale_ticks: int = 3                # control periods between answered ticks -> stale: stand
    missed_replans_to_stand: int = 2    # due re-plans in a row without plans -> stand
    sat_down_height: float = 0.1        # m shorter legs (median) than standing: sat down
    stand_adopt_age: float = 0.5        # sim s: a stand ends only with a plan at most this old
    stand_adopt_lead: float = 0.1       # sim s: ... whose first swing lifts off this much later
    fall_time: float = 0.1              # sim s tilted beyond fall_tilt (every tick): fallen
