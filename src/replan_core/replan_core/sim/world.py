"""The PyBullet world: load the robot and the terrain, step with joint torques, sense the state.

ROS-free: the sim node and closed-loop unit tests drive it alike. It behaves like a robot's
driver: torques in (clipped to the URDF effort limits), sensed state and contact events out.

Conventions:
- Time advances by control ticks of ``control_period``; each tick runs
  ``control_period / physics_dt`` physics steps with the same torques.
- The base pose is the pose of the URDF link ``base_link`` (PyBullet itself tracks the base's
  inertial frame; the conversion is done here).
- Foot positions are the foot frames of the URDF (the centre of the foot sphere); the ground
  reaction force of a foot is averaged over the physics steps of the tick and summed over its
  contact points; its contact flag is debounced: the normal force must stay above (below)
  ``contact_threshold`` for ``debounce_ticks`` consecutive ticks before the flag rises (falls).
- Feet touching the ground at spawn start with the contact flag set (no touchdown event).

Realism, each element off by default (then the world is the ideal one, bit for bit):
- ``actuator``: the commanded torque passes a transport delay, a first-order lag and the
  torque limits per physics step; joint viscous and Coulomb friction oppose the motion.
- ``contact_stiffness`` / ``contact_damping``: compliant (rubber) feet instead of rigid contact.
- ``imu_truth``: the exact angular velocity and specific force at base_link, for an IMU model
  (``replan_core.sim.sensors``).
"""

from __future__ import annotations

import contextlib
import math
import xml.etree.ElementTree as ET
from collections import deque

import numpy as np
import pybullet
from pybullet_utils import bullet_client

from replan_core.common import rotations
from replan_core.common.types import (
    FOOT_FRAMES,
    GRAVITY,
    JOINT_NAMES,
    STANDING_POSE,
    BaseState,
    ContactState,
    JointState,
)
from replan_core.sim.settings import TERRAIN_DEFAULTS, TERRAINS, ActuatorParams, WorldSettings
from replan_core.sim.urdf_merge import simulator_model

_DEFAULT = WorldSettings()        # the constructor's defaults


class _BulletClient(bullet_client.BulletClient):
    """pybullet_utils' client, each bound function made once: its ``__getattr__`` builds a new
    ``functools.partial`` (and an ``inspect.isbuiltin`` check) at every call, about 6 % of the
    sim node's CPU at ~27 calls a tick. The functions called are the same."""

    def __getattr__(self, name):
        attribute = super().__getattr__(name)
        if name != 'disconnect':        # it resets the client id: never cached
            object.__setattr__(self, name, attribute)
        return attribute


# A link without <inertial> is massless in the controller's model (pinocchio) but PyBullet gives
# it 1 kg and a unit inertia: ANYmal C's root link made its sim trunk 1 kg and 1 kg m^2 heavier
# than the model. Such a link gets a negligible one instead (zero would fix a root in place).
_MASSLESS_LINK_MASS = 1e-6      # kg
_MASSLESS_LINK_INERTIA = 1e-9   # kg m^2
_SPAWN_CONTACT_DISTANCE = 0.002   # m, a foot this close to the ground at spawn is in contact


class SimWorld:
    """A PyBullet world with one torque-controlled quadruped (DIRECT mode, deterministic)."""

    def __init__(self, urdf_path: str, *, physics_dt: float = _DEFAULT.physics_dt,
                 control_period: float = _DEFAULT.control_period,
                 initial_joint_positions: np.ndarray | None = None,
                 initial_base_height: float | None = None,
                 terrain: str = _DEFAULT.terrain.kind, terrain_params: dict | None = None,
                 contact_threshold: float = _DEFAULT.contact_threshold,
                 debounce_ticks: int = _DEFAULT.debounce_ticks,
                 friction: float = _DEFAULT.friction, gui: bool = _DEFAULT.gui,
                 seed: int = _DEFAULT.seed, actuator: ActuatorParams | None = None,
                 contact_stiffness: float = _DEFAULT.contact_stiffness,
                 contact_damping: float = _DEFAULT.contact_damping,
                 joint_names: tuple[str, ...] = JOINT_NAMES,
                 foot_frames: tuple[str, ...] = FOOT_FRAMES,
                 foot_offset: np.ndarray | None = None,
                 foot_radius: float | None = None) -> None:
        """Build the world and spawn the robot at rest, base at x = y = 0, level.

        initial_joint_positions: (12,) rad in JOINT_NAMES order (None: HyQ standing pose).
        initial_base_height: m, base_link z (None: feet just touching the ground below them).
        terrain_params: sizes overriding ``TERRAIN_DEFAULTS`` (m).
        actuator: delay, lag, friction and limits of the joints (None: ideal actuators).
        contact_stiffness: N/m, of the foot contacts; 0 = PyBullet's rigid contact.
        contact_damping: N s/m, of the foot contacts (only with a contact_stiffness).
        joint_names, foot_frames: the model's 12 joints (``JOINT_NAMES`` order) and 4 foot
            links (LEGS order); the defaults are the project's HyQ names, a robot file gives
            another robot's (``robot_file.RobotSpec``).
        foot_offset: (3,) m, the centre of each foot's contact sphere in its foot frame (a
            robot file's ``foot_contact.offset``; ANYmal's sphere sits 2.25 cm above its foot
            frame); None: at the foot frame.
        foot_radius: m, the robot file's ``foot_contact.radius``: a foot whose collision in the
            model is not one sphere (Go2's mesh) gets this sphere at ``foot_offset``; None:
            the model's foot collisions as they are.
        """
        substeps = control_period / physics_dt
        if physics_dt <= 0 or substeps < 1 or abs(substeps - round(substeps)) > 1e-9:
            raise ValueError('control_period must be a positive multiple of physics_dt')
        if terrain not in TERRAINS:
            raise ValueError(f'terrain must be one of {TERRAINS}, got {terrain!r}')
        unknown = set(terrain_params or {}) - set(TERRAIN_DEFAULTS)
        if unknown:
            raise ValueError(f'unknown terrain parameters {sorted(unknown)}')
        if not (math.isfinite(contact_stiffness) and math.isfinite(contact_damping)
                and contact_stiffness >= 0.0 and contact_damping >= 0.0):
            raise ValueError('contact_stiffness and contact_damping must be finite and >= 0')
        if contact_damping > 0.0 and contact_stiffness == 0.0:
            raise ValueError('contact_damping needs a contact_stiffness > 0')
        act = ActuatorParams() if actuator is None else actuator
        self._actuator = act
        self._physics_dt = physics_dt
        self._control_period = control_period
        self._substeps = round(substeps)
        self._threshold = contact_threshold
        self._debounce = max(int(debounce_ticks), 1)
        self._friction = friction
        self._tick = 0

        self._p = _BulletClient(
            connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        p = self._p
        p.resetSimulation()
        p.setGravity(0.0, 0.0, -GRAVITY)
        p.setTimeStep(physics_dt)
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1)
        if gui:
            p.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)

        self._terrain_bodies = self._build_terrain(
            terrain, {**TERRAIN_DEFAULTS, **(terrain_params or {})}, seed)

        # The links fixed to others merged into them (not the feet): fewer bodies, the same
        # motion, a cheaper physics step; mesh feet made the robot file's sphere; no visual
        # meshes without a window (urdf_merge.py). Load high above the terrain so that the
        # ground ray casts below never hit the robot.
        sphere = None if foot_radius is None else (
            float(foot_radius), np.zeros(3) if foot_offset is None else np.asarray(foot_offset))
        urdf_path = simulator_model(urdf_path, keep=foot_frames, foot_sphere=sphere, visuals=gui)
        self._robot = p.loadURDF(urdf_path, basePosition=[0.0, 0.0, 100.0],
                                 flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
        joints, links = {}, {}
        for i in range(p.getNumJoints(self._robot)):
            info = p.getJointInfo(self._robot, i)
            joints[info[1].decode()] = i
            links[info[12].decode()] = i
        links[p.getBodyInfo(self._robot)[0].decode()] = -1
        for name in _links_without_inertial(urdf_path):
            p.changeDynamics(self._robot, links[name], mass=_MASSLESS_LINK_MASS,
                             localInertiaDiagonal=[_MASSLESS_LINK_INERTIA] * 3)
        if len(joint_names) != len(JOINT_NAMES) or len(foot_frames) != len(FOOT_FRAMES):
            raise ValueError(f'{urdf_path}: need {len(JOINT_NAMES)} joint names and '
                             f'{len(FOOT_FRAMES)} foot links')
        missing = [n for n in joint_names if n not in joints]
        missing += [n for n in foot_frames if n not in links]
        if missing:
            raise ValueError(f'{urdf_path} lacks {missing}')
        self._joints = [joints[n] for n in joint_names]
        self._feet = [links[n] for n in foot_frames]
        self._foot_offset = (np.asarray(foot_offset, dtype=float).reshape(3)
                             if foot_offset is not None and np.any(foot_offset) else None)
        self._foot_index = {link: k for k, link in enumerate(self._feet)}
        self._effort_limit = act.torque_limit_scale * np.array(
            [p.getJointInfo(self._robot, j)[10] for j in self._joints])
        # Base inertial frame in the base_link frame (PyBullet poses the base by this frame).
        local_pos, local_quat = p.getDynamicsInfo(self._robot, -1)[3:5]
        self._local_pos, self._local_quat = np.array(local_pos), np.array(local_quat)
        self._local_pos_tuple = tuple(float(c) for c in local_pos)
        self._local_quat_tuple = tuple(float(c) for c in local_quat)

        # Only the commanded torques move the robot: no default velocity motors, no joint
        # damping or friction, no artificial link damping (PyBullet's default is 0.04).
        p.setJointMotorControlArray(self._robot, self._joints, pybullet.VELOCITY_CONTROL,
                                    forces=[0.0] * len(self._joints))
        for link in range(-1, p.getNumJoints(self._robot)):
            p.changeDynamics(self._robot, link, linearDamping=0.0, angularDamping=0.0,
                             jointDamping=0.0, restitution=0.0)
        if act.viscous_damping > 0.0:
            # PyBullet adds -jointDamping * qd to the joint torque before each step (explicit):
            # stable while b dt / I < 2; b = 10 N m s/rad on the lightest joint (the knee, an
            # effective 0.022 kg m^2) gives 0.45 at 1 kHz. The realistic b is 0.1.
            for j in self._joints:
                p.changeDynamics(self._robot, j, jointDamping=act.viscous_damping)
        # Bullet multiplies the two bodies' coefficients: ground 1.0, robot = friction.
        for body in self._terrain_bodies:
            p.changeDynamics(body, -1, lateralFriction=1.0, restitution=0.0)
        for link in range(-1, p.getNumJoints(self._robot)):
            p.changeDynamics(self._robot, link, lateralFriction=friction)
        if contact_stiffness > 0.0:
            # Bullet turns k and c into the contact constraint's ERP = dt k / (dt k + c) and
            # CFM = 1 / (dt k + c): an implicit spring-damper, stable for any k, c at 1 kHz. It
            # needs both values in the same call. The ground keeps Bullet's default (near
            # infinite stiffness), so the combined contact is the foot's.
            for foot in self._feet:
                p.changeDynamics(self._robot, foot, contactStiffness=contact_stiffness,
                                 contactDamping=contact_damping)

        # Actuator dynamics per physics step: a delay line of whole steps (the command at spawn
        # is 0 N m) and the exact discretisation of the lag for a command held over one step.
        self._delay_steps = round(act.delay / physics_dt)
        self._delay_line = deque(np.zeros(len(JOINT_NAMES)) for _ in range(self._delay_steps))
        self._lag_alpha = (1.0 - math.exp(-physics_dt / act.time_constant)
                           if act.time_constant > 0.0 else 1.0)
        self._lagged = np.zeros(len(JOINT_NAMES))
        self._actuator_dynamics = self._delay_steps > 0 or act.time_constant > 0.0

        q0 = STANDING_POSE if initial_joint_positions is None else np.asarray(
            initial_joint_positions, dtype=float).reshape(len(JOINT_NAMES))
        self._abduction_hold = q0[0::3].copy()      # rad, HAA of the spawn pose
        for j, q in zip(self._joints, q0, strict=True):
            p.resetJointState(self._robot, j, float(q), 0.0)
        if initial_base_height is None:
            initial_base_height = self._touching_height()
        self._set_base_pose(np.array([0.0, 0.0, initial_base_height]),
                            np.array([0.0, 0.0, 0.0, 1.0]))
        p.resetBaseVelocity(self._robot, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        # Coulomb friction as the smooth saturation -tau_c clip(qd / v_eps, -1, 1), applied
        # explicitly per physics step from that step's joint velocities. Below v_eps it is a
        # viscous damping tau_c / v_eps, stable in explicit time stepping while
        # (tau_c / v_eps) dt / I < 2 for the lightest joint inertia I: we take the v_eps that
        # gives 0.5 (no overshoot, margin for posture changes and the viscous part), with I
        # from the mass matrix at the initial pose (HyQ's knee, 0.022 kg m^2: v_eps =
        # 0.09 rad/s for 1 N m). The price: a joint loaded below tau_c creeps at
        # load / tau_c x v_eps instead of sticking. Bullet's own velocity motor (target 0,
        # force tau_c) would stick exactly, but its constraint in the LCP costs ~240 us per
        # 4 ms tick here (+80 %), against ~45 us for this.
        self._coulomb = act.coulomb_friction
        self._coulomb_inv_velocity = 0.0        # 1 / v_eps, s/rad
        if self._coulomb > 0.0:
            self._coulomb_inv_velocity = 1.0 / (
                2.0 * self._coulomb * physics_dt * self._max_inverse_joint_inertia())

        self._applied = np.zeros(len(JOINT_NAMES))
        self._wrench_force = np.zeros(3)
        self._pushing = False                # a non-zero wrench is set (checked once per change)
        self._wrench_torque = np.zeros(3)
        self._force = np.zeros((4, 3))
        self._normal = np.zeros(4)
        p.performCollisionDetection()
        self._contact = np.array([self._near_ground(f) for f in self._feet])
        self._pending = np.zeros(4, dtype=int)       # ticks the raw flag has differed
        self._touchdown = np.zeros(4, dtype=bool)
        self._liftoff = np.zeros(4, dtype=bool)
        # Velocity of the base_link origin (world, m/s) at the previous tick, for imu_truth.
        self._previous_velocity = self._origin_motion()[0]
        self._begun: int | None = None     # lead steps run by begin_step, None: not begun
        self._force_sum = np.zeros((4, 3))  # foot forces summed over the period's steps, N
        self._normal_sum = np.zeros(4)

    @classmethod
    def from_settings(cls, urdf_path: str, settings: WorldSettings, *,
                      joint_names: tuple[str, ...] = JOINT_NAMES,
                      foot_frames: tuple[str, ...] = FOOT_FRAMES,
                      foot_offset: np.ndarray | None = None,
                      foot_radius: float | None = None) -> SimWorld:
        """The world of ``settings`` around the model at ``urdf_path``; the model's names and
        foot contact as for the constructor (a robot file's)."""
        pose = settings.initial_joint_positions
        return cls(
            urdf_path, physics_dt=settings.physics_dt, control_period=settings.control_period,
            initial_joint_positions=np.array(pose, dtype=float) if pose else None,
            initial_base_height=settings.initial_base_height or None,
            terrain=settings.terrain.kind, terrain_params=settings.terrain.sizes(),
            contact_threshold=settings.contact_threshold,
            debounce_ticks=settings.debounce_ticks, friction=settings.friction,
            gui=settings.gui, seed=settings.seed, actuator=settings.actuator,
            contact_stiffness=settings.contact_stiffness,
            contact_damping=settings.contact_damping, joint_names=joint_names,
            foot_frames=foot_frames, foot_offset=foot_offset, foot_radius=foot_radius)

    # ------------------------------------------------------------------ properties
    @property
    def time(self) -> float:
        """Sim time (s): ticks times control period (no accumulated rounding)."""
        return self._tick * self._control_period

    @property
    def tick(self) -> int:
        """Number of control ticks done."""
        return self._tick

    @property
    def control_period(self) -> float:
        return self._control_period

    @property
    def effort_limit(self) -> np.ndarray:
        """(12,) N m, the actuator torque limits (URDF limits x torque_limit_scale)."""
        return self._effort_limit.copy()

    @property
    def actuator(self) -> ActuatorParams:
        return self._actuator

    @property
    def coulomb_velocity_scale(self) -> float:
        """rad/s, v_eps of the smooth Coulomb friction (inf when it is off)."""
        return 1.0 / self._coulomb_inv_velocity if self._coulomb_inv_velocity else math.inf

    # ------------------------------------------------------------------ stepping
    def step(self, torques: np.ndarray) -> None:
        """Command joint torques (12,) N m, clipped to the limits, for one control period.

        With actuator dynamics, the command is clipped before the lag, so the lag cannot wind
        up and its output (a convex combination of clipped values) stays within the limits.
        """
        tau = self._checked_torques(torques)
        self.begin_step()
        self._finish_step(tau)

    @property
    def begun(self) -> bool:
        """True between ``begin_step`` and ``finish_step``: the period's lead steps are done."""
        return self._begun is not None

    @property
    def lead_steps(self) -> int:
        """Physics steps at the start of a control period that no command sent at its start
        can reach: the actuator delay in whole steps (at most one period)."""
        return min(self._delay_steps, self._substeps)

    def begin_step(self) -> None:
        """Run the physics steps of the next control period that the actuator delay keeps
        from the coming command (``lead_steps``): the torques of those steps are already on
        the delay line. ``finish_step`` then runs the rest; ``begin_step`` + ``finish_step``
        is exactly ``step``, so a simulator can run these steps while the controller computes.
        A second call before ``finish_step`` does nothing."""
        if self._begun is not None:
            return
        self._previous_velocity = self._origin_motion()[0]
        self._force_sum = np.zeros((4, 3))
        self._normal_sum = np.zeros(4)
        lead = self.lead_steps
        for _ in range(lead):
            self._physics_step(self._delay_line.popleft())
        self._begun = lead

    def finish_step(self, torques: np.ndarray) -> None:
        """The rest of the control period begun with ``begin_step`` (which it calls if it was
        not), under the command ``torques`` (12,) N m: as ``step``."""
        self._finish_step(self._checked_torques(torques))

    def _checked_torques(self, torques: np.ndarray) -> np.ndarray:
        tau = np.asarray(torques, dtype=float)
        if tau.shape != (len(JOINT_NAMES),):
            raise ValueError(f'expected {len(JOINT_NAMES)} torques, got shape {tau.shape}')
        if not np.all(np.isfinite(tau)):
            raise ValueError('torques contain NaN or inf')
        return np.clip(tau, -self._effort_limit, self._effort_limit)

    def _finish_step(self, tau: np.ndarray) -> None:
        self.begin_step()
        lead = self._begun
        # The command enters the delay line once per physics step; the lead steps took their
        # torques out already, so it goes in for them now, in the same order.
        for _ in range(lead):
            self._delay_line.append(tau)
        for _ in range(self._substeps - lead):
            actual = tau
            if self._delay_steps:
                self._delay_line.append(tau)
                actual = self._delay_line.popleft()
            self._physics_step(actual)
        self._begun = None
        self._tick += 1
        self._force = self._force_sum / self._substeps       # mean over the tick, N
        self._normal = self._normal_sum / self._substeps
        self._update_contact_flags()

    def _physics_step(self, commanded: np.ndarray) -> None:
        """One physics step under the torque ``commanded`` (N m) as it leaves the delay."""
        p, robot = self._p, self._robot
        actual = commanded
        if self._lag_alpha < 1.0:
            self._lagged = self._lagged + self._lag_alpha * (commanded - self._lagged)
            actual = self._lagged
        # The effort reported is the actuator torque of the tick's last physics step.
        self._applied = actual
        if self._coulomb:
            # Joint friction on top of the actuator torque (not part of the effort).
            # tau_c * clip(qd / v_eps, -1, 1) on the 12 joints at once; fmin / fmax take the
            # non-NaN operand as Python's min(1.0, x) / max(-1.0, x) did, so every value,
            # NaN included, is what the per-joint expression gave.
            velocity = np.fromiter((s[1] for s in p.getJointStates(robot, self._joints)),
                                   float, len(self._joints))
            scale = np.fmax(-1.0, np.fmin(1.0, velocity * self._coulomb_inv_velocity))
            forces = (actual - self._coulomb * scale).tolist()
        else:
            forces = actual.tolist()
        # Torques and external forces act for one stepSimulation only: set them every step.
        p.setJointMotorControlArray(robot, self._joints, pybullet.TORQUE_CONTROL, forces=forces)
        if self._pushing:
            origin = self._base_pose()[0]
            p.applyExternalForce(robot, -1, self._wrench_force.tolist(), origin.tolist(),
                                 pybullet.WORLD_FRAME)
            p.applyExternalTorque(robot, -1, self._wrench_torque.tolist(),
                                  pybullet.WORLD_FRAME)
        p.stepSimulation()
        self._add_foot_forces(self._force_sum, self._normal_sum)

    def _update_contact_flags(self) -> None:
        raw = self._normal > self._threshold
        differs = raw != self._contact
        self._pending = np.where(differs, self._pending + 1, 0)
        flip = self._pending >= self._debounce
        self._touchdown = flip & raw
        self._liftoff = flip & ~raw
        self._contact = np.where(flip, raw, self._contact)
        self._pending[flip] = 0

    def _add_foot_forces(self, force: np.ndarray, normal: np.ndarray) -> None:
        """Add the ground's force on each foot (world, N) and its normal magnitude (N)."""
        for c in self._p.getContactPoints(bodyA=self._robot):
            k = self._foot_index.get(c[3])
            if k is None:                 # trunk or leg touching the ground: not a foot
                continue
            # c[7] is the normal on B pointing to A: the push of the ground on the foot; the
            # friction impulses along lateralFrictionDir1/2 act on A with the same sign
            # (checked in test_sim_world: the GRFs balance a horizontal push). Plain floats:
            # this runs per contact point and physics step.
            fn, f1, f2 = c[9], c[10], c[12]
            n, d1, d2 = c[7], c[11], c[13]
            row = force[k]
            row[0] += fn * n[0] + f1 * d1[0] + f2 * d2[0]
            row[1] += fn * n[1] + f1 * d1[1] + f2 * d2[1]
            row[2] += fn * n[2] + f1 * d1[2] + f2 * d2[2]
            normal[k] += fn

    # ------------------------------------------------------------------ sensing
    def base_state(self) -> BaseState:
        """Pose of base_link in the world and its twist (world frame) at the current tick."""
        pos, quat, com = self._base_pose()
        v_com, omega = self._p.getBaseVelocity(self._robot)
        # Rigid-body velocity transfer v_origin = v_com + omega x (origin - com); plain floats:
        # numpy costs more than the arithmetic on 3-vectors, at every tick.
        rx, ry, rz = pos[0] - com[0], pos[1] - com[1], pos[2] - com[2]
        wx, wy, wz = omega
        v_origin = np.array([v_com[0] + wy * rz - wz * ry, v_com[1] + wz * rx - wx * rz,
                             v_com[2] + wx * ry - wy * rx])
        return BaseState(stamp=self.time, position=pos, quaternion=quat,
                         linear_velocity=v_origin, angular_velocity=np.array(omega))

    def imu_truth(self) -> tuple[np.ndarray, np.ndarray]:
        """What a perfect IMU at the base_link origin, with base_link axes, measures now.

        Returns the angular velocity (3,) rad/s and the specific force R^T (a - g) (3,) m/s^2
        (+9.81 on z at rest), where a is the mean acceleration of the origin over the last tick
        (velocity difference over the control period; 0 before the first tick).
        """
        (vx, vy, vz), (wx, wy, wz), quat = self._origin_motion()
        px, py, pz = self._previous_velocity
        inv_dt = 1.0 / self._control_period
        specific_force = ((vx - px) * inv_dt, (vy - py) * inv_dt, (vz - pz) * inv_dt + GRAVITY)
        to_body = rotations.conjugate(quat)
        return (np.array(rotations.rotate(to_body, (wx, wy, wz))),
                np.array(rotations.rotate(to_body, specific_force)))

    def joint_state(self) -> JointState:
        """Joint positions, velocities and the actuator torques (after delay, lag and clipping;
        at the end of the tick), which joint friction does not include."""
        states = self._p.getJointStates(self._robot, self._joints)
        return JointState(stamp=self.time,
                          position=np.array([s[0] for s in states]),
                          velocity=np.array([s[1] for s in states]),
                          effort=self._applied.copy())

    def contact_state(self) -> ContactState:
        """Feet positions, ground reaction forces, debounced flags and edges of this tick."""
        # One call, one forward kinematics pass for the four feet (getLinkState ran it per
        # foot): the same link frames.
        feet = np.array([state[4] for state in self._p.getLinkStates(
            self._robot, self._feet, computeForwardKinematics=True)])
        return ContactState(stamp=self.time, foot_position=feet, force=self._force.copy(),
                            contact=self._contact.copy(), touchdown=self._touchdown.copy(),
                            liftoff=self._liftoff.copy())

    # ------------------------------------------------------------------ inputs
    def set_external_wrench(self, force: np.ndarray, torque: np.ndarray) -> None:
        """Wrench on the trunk (N, N m, world axes) at the base origin, every step until changed."""
        f = np.asarray(force, dtype=float).reshape(3)
        t = np.asarray(torque, dtype=float).reshape(3)
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(t))):
            raise ValueError('wrench contains NaN or inf')
        self._wrench_force, self._wrench_torque = f.copy(), t.copy()
        self._pushing = bool(np.any(f) or np.any(t))

    def damping_torques(self, gain: float, abduction_stiffness: float = 0.0) -> np.ndarray:
        """Torques (N m) of the controller-dead mode: joint damping -gain * qd, and the
        abduction (HAA) joints held at the spawn pose's angle with ``abduction_stiffness``
        (N m/rad). Damping alone lets the legs splay sideways as the robot sits down: caught
        with one foot in the air and a sideways velocity, it rolled over onto its back."""
        joints = self.joint_state()
        torques = -gain * joints.velocity
        torques[0::3] += abduction_stiffness * (self._abduction_hold - joints.position[0::3])
        return torques

    def close(self) -> None:
        """Disconnect from the physics server (idempotent)."""
        if self._p is not None:
            with contextlib.suppress(pybullet.error):
                self._p.disconnect()
            self._p = None

    # ------------------------------------------------------------------ internals
    def _max_inverse_joint_inertia(self) -> float:
        """Largest diagonal entry of the inverse mass matrix over the joints (1/(kg m^2)), at
        the current pose with a free base: the lightest joint's effective inertia."""
        p, robot = self._p, self._robot
        movable = [i for i in range(p.getNumJoints(robot))
                   if p.getJointInfo(robot, i)[2] != pybullet.JOINT_FIXED]
        q = [s[0] for s in p.getJointStates(robot, movable)]
        mass_matrix = np.array(p.calculateMassMatrix(robot, q))
        dofs = [6 + movable.index(j) for j in self._joints]      # after the base's 6
        return float(np.max(np.diag(np.linalg.inv(mass_matrix))[dofs]))

    def _origin_motion(self) -> tuple[tuple[float, float, float], tuple[float, float, float],
                                      tuple[float, float, float, float]]:
        """Velocity of the base_link origin and angular velocity (world, m/s, rad/s), and the
        base_link quaternion. Plain floats: it runs at every tick."""
        p = self._p
        com_quat = p.getBasePositionAndOrientation(self._robot)[1]
        v, omega = p.getBaseVelocity(self._robot)
        lx, ly, lz, lw = self._local_quat_tuple
        cx, cy, cz, cw = com_quat
        # base_link orientation = com_quat * conjugate(local_quat)
        quat = (-cw * lx + cx * lw - cy * lz + cz * ly,
                -cw * ly + cx * lz + cy * lw - cz * lx,
                -cw * lz - cx * ly + cy * lx + cz * lw,
                cw * lw + cx * lx + cy * ly + cz * lz)
        # origin - com = -R local_pos; v_origin = v_com + omega x (origin - com)
        rx, ry, rz = rotations.rotate(quat, self._local_pos_tuple)
        wx, wy, wz = omega
        return ((v[0] - (wy * rz - wz * ry), v[1] - (wz * rx - wx * rz),
                 v[2] - (wx * ry - wy * rx)), (wx, wy, wz), quat)

    # Pose conversions in numpy: pybullet.multiplyTransforms computes in single precision.
    def _base_pose(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position and quaternion of base_link in the world, and the position of the base's
        inertial frame (what pybullet reports)."""
        com_pos, com_quat = self._p.getBasePositionAndOrientation(self._robot)
        com_pos = np.array(com_pos)
        # The local frame as floats: the same IEEE operations as on its numpy scalars,
        # without their cost.
        quat = rotations.multiply(com_quat, rotations.conjugate(self._local_quat_tuple))
        quat /= math.sqrt(quat[0] ** 2 + quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
        return com_pos - np.array(rotations.rotate(quat, self._local_pos_tuple)), quat, com_pos

    def _set_base_pose(self, pos: np.ndarray, quat: np.ndarray) -> None:
        com_pos = pos + np.array(rotations.rotate(quat, self._local_pos))
        com_quat = rotations.multiply(quat, self._local_quat)
        self._p.resetBasePositionAndOrientation(self._robot, com_pos.tolist(),
                                                (com_quat / np.linalg.norm(com_quat)).tolist())

    def _ground_height(self, xy: np.ndarray) -> np.ndarray:
        """Terrain height (m) under each (x, y), by ray casts (the robot is far above)."""
        starts = [[x, y, 50.0] for x, y in xy]
        ends = [[x, y, -50.0] for x, y in xy]
        hits = self._p.rayTestBatch(starts, ends)
        return np.array([h[3][2] if h[0] >= 0 else 0.0 for h in hits])

    def _touching_height(self) -> float:
        """Base height (m) putting the lowest foot sphere on the terrain below it, base level."""
        self._set_base_pose(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
        states = [self._p.getLinkState(self._robot, link, computeForwardKinematics=True)
                  for link in self._feet]
        feet = np.array([state[4] for state in states])
        if self._foot_offset is not None:       # the sphere's centre, not the foot frame
            feet += np.array([rotations.quaternion_to_matrix(np.array(state[5]))
                              @ self._foot_offset for state in states])
        radius = np.array([self._foot_radius(link) for link in self._feet])
        # Cast with the robot far above: with the feet under the hips (Go1, ANYmal) the rays
        # would hit the robot's own legs and spawn it centimetres high.
        self._set_base_pose(np.array([0.0, 0.0, 100.0]), np.array([0.0, 0.0, 0.0, 1.0]))
        ground = self._ground_height(feet[:, :2])
        return float(np.max(ground + radius - feet[:, 2]))

    def _foot_radius(self, link: int) -> float:
        shapes = self._p.getCollisionShapeData(self._robot, link)
        spheres = [s[3][0] for s in shapes if s[2] == pybullet.GEOM_SPHERE]
        return float(spheres[0]) if spheres else 0.0

    def _near_ground(self, link: int) -> bool:
        return any(self._p.getClosestPoints(self._robot, body, _SPAWN_CONTACT_DISTANCE,
                                            linkIndexA=link)
                   for body in self._terrain_bodies)

    def _build_terrain(self, terrain: str, prm: dict, seed: int) -> list[int]:
        """Static terrain bodies; the robot spawns at x = y = 0 on the z = 0 level."""
        p = self._p
        bodies = []

        def box(center, half):
            shape = p.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half)
            visual = p.createVisualShape(pybullet.GEOM_BOX, halfExtents=half,
                                         rgbaColor=[0.6, 0.6, 0.55, 1.0])
            return p.createMultiBody(0.0, shape, visual, basePosition=center)

        def plane(z):
            shape = p.createCollisionShape(pybullet.GEOM_PLANE)
            # A plane has no visual in PyBullet: show a thin 40 m square instead.
            visual = p.createVisualShape(pybullet.GEOM_BOX, halfExtents=[20.0, 20.0, 0.001],
                                         visualFramePosition=[0.0, 0.0, -0.001],
                                         rgbaColor=[0.8, 0.8, 0.8, 1.0])
            return p.createMultiBody(0.0, shape, visual, basePosition=[0.0, 0.0, z])

        if terrain == 'step_down':
            # Ground at -step_height; a platform with its top at z = 0 up to x = step_x.
            h, x0 = prm['step_height'], prm['step_x']
            bodies.append(plane(-h))
            length = 20.0
            bodies.append(box([x0 - length / 2, 0.0, -h / 2], [length / 2, length / 2, h / 2]))
        elif terrain == 'step_up':
            h, x0, lx = prm['step_height'], prm['step_x'], prm['step_length']
            bodies.append(plane(0.0))
            bodies.append(box([x0 + lx / 2, 0.0, h / 2], [lx / 2, prm['width'] / 2, h / 2]))
        elif terrain == 'rough':
            bodies.append(plane(0.0))
            res, amp = prm['rough_resolution'], prm['rough_amplitude']
            rows = max(round(prm['rough_length'] / res) + 1, 2)   # along x
            cols = max(round(prm['width'] / res) + 1, 2)          # along y
            heights = np.random.default_rng(seed).uniform(0.0, amp, size=rows * cols)
            shape = p.createCollisionShape(
                pybullet.GEOM_HEIGHTFIELD, meshScale=[res, res, 1.0],
                heightfieldData=heights.tolist(), numHeightfieldRows=rows,
                numHeightfieldColumns=cols)
            # PyBullet centres a heightfield on its bounding box, heights included.
            center_z = (heights.min() + heights.max()) / 2
            body = p.createMultiBody(0.0, shape, -1, basePosition=[
                prm['rough_start_x'] + (rows - 1) * res / 2, 0.0, center_z])
            p.changeVisualShape(body, -1, rgbaColor=[0.6, 0.55, 0.45, 1.0])
            bodies.append(body)
        else:
            bodies.append(plane(0.0))
        return bodies


def _links_without_inertial(urdf_path: str) -> list[str]:
    """Names of the links of a URDF that have no ``<inertial>`` (massless in pinocchio)."""
    return [link.get('name') for link in ET.parse(urdf_path).getroot().iter('link')
            if link.find('inertial') is None]
