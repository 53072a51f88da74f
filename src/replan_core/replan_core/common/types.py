"""Data exchanged between the core modules (and, through replan_ros.messages, the nodes).

Conventions used everywhere in the project:
- Legs are indexed 0..3 in the order of ``LEGS`` (LF, RF, LH, RH); arrays with one row per leg
  follow that order.
- Joints are ordered leg-major as in ``JOINT_NAMES`` (haa, hfe, kfe for each leg).
- Positions are in metres in the world frame ``odom`` (z up); times are sim-time seconds.
- Quaternions are (x, y, z, w), as in geometry_msgs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

LEGS: tuple[str, ...] = ('lf', 'rf', 'lh', 'rh')
JOINTS_PER_LEG: tuple[str, ...] = ('haa', 'hfe', 'kfe')
JOINT_NAMES: tuple[str, ...] = tuple(
    f'{leg}_{joint}_joint' for leg in LEGS for joint in JOINTS_PER_LEG)
FOOT_FRAMES: tuple[str, ...] = tuple(f'{leg}_foot' for leg in LEGS)
GRAVITY = 9.81  # m/s^2, magnitude (pinocchio's model.gravity is (0, 0, -9.81))
WORLD_FRAME = 'odom'
BASE_FRAME = 'base_link'
# HyQ's standing pose (rad, JOINT_NAMES order), as config/sim.yaml: the sim spawns in it when
# none is given, and a controller stands a robot that sat down back up into it.
STANDING_POSE = np.array([-0.2, 0.75, -1.5, -0.2, 0.75, -1.5,
                          -0.2, -0.75, 1.5, -0.2, -0.75, 1.5])


@dataclass
class BaseState:
    """Floating-base state: pose in the world, twist expressed in the world frame."""

    stamp: float                      # s, sim time
    position: np.ndarray              # (3,) m
    quaternion: np.ndarray            # (4,) x, y, z, w
    linear_velocity: np.ndarray       # (3,) m/s, world frame
    angular_velocity: np.ndarray      # (3,) rad/s, world frame


@dataclass
class JointState:
    """Joint positions, velocities and efforts in ``JOINT_NAMES`` order."""

    stamp: float                      # s, sim time
    position: np.ndarray              # (12,) rad
    velocity: np.ndarray              # (12,) rad/s
    effort: np.ndarray                # (12,) N m


@dataclass
class ImuReading:
    """One IMU sample at the base (``base_link`` origin and axes), as a MEMS IMU reports it.

    ``linear_acceleration`` is the specific force (acceleration minus gravity, body axes): a
    robot at rest reads about +9.81 m/s^2 along its z axis. Noise and bias are included.
    """

    stamp: float                      # s, sim time
    angular_velocity: np.ndarray      # (3,) rad/s, gyro, base frame
    linear_acceleration: np.ndarray   # (3,) m/s^2, accelerometer (specific force), base frame


@dataclass
class ContactState:
    """Sensed contact of the four feet at one control tick (the simulator's contact sensing).

    ``contact`` is the debounced contact flag; ``touchdown``/``liftoff`` are True only at the
    tick where that flag rises/falls: they are the haptic touchdown and lift-off events.
    """

    stamp: float                      # s, sim time
    foot_position: np.ndarray         # (4, 3) m, world
    force: np.ndarray                 # (4, 3) N, ground reaction force on each foot, world
    contact: np.ndarray               # (4,) bool
    touchdown: np.ndarray             # (4,) bool
    liftoff: np.ndarray               # (4,) bool


@dataclass
class Step:
    """One planned swing of one leg."""

    leg: int                          # 0..3, index into LEGS
    liftoff_time: float               # s, absolute sim time
    touchdown_time: float             # s, absolute sim time (planned)
    target: np.ndarray                # (3,) m, world: the foothold
    step_height: float                # m, swing apex above the higher of start and target
    haptic: bool                      # True: the swing ends at sensed contact, not at the plan
    replan: bool                      # True: this step's touchdown triggers the next re-plan
    yaw: float                        # rad, trunk yaw reference from this touchdown on


@dataclass
class FootholdPlan:
    """Footholds and contact schedule from one re-plan (Algorithm 1, compFootholds)."""

    start_time: float                 # s, sim time of the trigger (touchdown) it was made at
    initial_feet: np.ndarray          # (4, 3) m, world: actual feet at start_time, all in stance
    initial_yaw: float                # rad, trunk yaw reference at start_time
    steps: list[Step] = field(default_factory=list)
    # The touchdown rule (touchdown.StepTracker) travels with the plan, so the gait node and the
    # controller cannot disagree on it: a haptic touchdown counts from this fraction of the
    # planned swing on, and is forced this long (s) after the planned touchdown.
    min_swing_fraction: float = 0.5
    max_extension: float = 0.3
    # s of sim time from the trigger until the plan takes effect (the planners' solve time):
    # the controller tracks the old plan until then, and no step of this plan lifts off
    # before it, in either tracker (docs/ARCHITECTURE.md, "Re-plan protocol").
    latency: float = 0.0


@dataclass
class ComPlan:
    """CoM trajectory sampled every ``dt``: piecewise cubic with constant jerk (eq. 2).

    Row k holds the state at ``start_time + k * dt``, k = 0..N. Between samples the jerk is
    constant, so ``sample`` is exact, not an approximation.
    """

    start_time: float                 # s, sim time of the state it was planned from
    dt: float                         # s
    position: np.ndarray              # (N+1, 3) m, world; z is the constant CoM height
    velocity: np.ndarray              # (N+1, 3) m/s
    acceleration: np.ndarray          # (N+1, 3) m/s^2

    @property
    def end_time(self) -> float:
        return self.start_time + (len(self.position) - 1) * self.dt

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at sim time ``t`` (clamped to the horizon)."""
        n = len(self.position) - 1
        tau = min(max(t - self.start_time, 0.0), n * self.dt)
        k = min(int(tau / self.dt), n - 1)
        s = tau - k * self.dt
        p, v, a = self.position[k], self.velocity[k], self.acceleration[k]
        jerk = (self.acceleration[k + 1] - a) / self.dt          # constant over the interval
        return (p + v * s + a * s**2 / 2 + jerk * s**3 / 6,      # eq. (2) at a fraction of dt
                v + a * s + jerk * s**2 / 2,
                a + jerk * s)
