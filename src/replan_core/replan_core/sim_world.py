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
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pybullet
from pybullet_utils import bullet_client

from replan_core import rotations
from replan_core.types import FOOT_FRAMES, JOINT_NAMES, BaseState, ContactState, JointState

GRAVITY = 9.81                    # m/s^2
TERRAINS = ('flat', 'step_down', 'step_up', 'rough')
# HyQ's standing pose (rad, JOINT_NAMES order), as config/sim.yaml; used when none is given.
STANDING_POSE = np.array([-0.2, 0.75, -1.5, -0.2, 0.75, -1.5,
                          -0.2, -0.75, 1.5, -0.2, -0.75, 1.5])
_TERRAIN_DEFAULTS = {
    'step_x': 0.6,            # m, x of the step edge (step_down, step_up)
    'step_height': 0.1,       # m, drop (step_down) or rise (step_up)
    'step_length': 2.0,       # m, step_up box length along x
    'width': 4.0,             # m, extent along y (step_up, rough)
    'rough_start_x': 0.6,     # m, where the heightfield begins
    'rough_length': 4.0,      # m, extent along x
    'rough_amplitude': 0.03,  # m, heights uniform in [0, amplitude]
    'rough_resolution': 0.05,  # m, cell size
}
_SPAWN_CONTACT_DISTANCE = 0.002   # m, a foot this close to the ground at spawn is in contact


class SimWorld:
    """A PyBullet world with one torque-controlled quadruped (DIRECT mode, deterministic)."""

    def __init__(self, urdf_path: str, *, physics_dt: float = 0.001,
                 control_period: float = 0.004,
                 initial_joint_positions: np.ndarray | None = None,
                 initial_base_height: float | None = None,
                 terrain: str = 'flat', terrain_params: dict | None = None,
                 contact_threshold: float = 30.0, debounce_ticks: int = 2,
                 friction: float = 0.8, gui: bool = False, seed: int = 0) -> None:
        """Build the world and spawn the robot at rest, base at x = y = 0, level.

        initial_joint_positions: (12,) rad in JOINT_NAMES order (None: HyQ standing pose).
        initial_base_height: m, base_link z (None: feet just touching the ground below them).
        terrain_params: sizes overriding ``_TERRAIN_DEFAULTS`` (m).
        """
        substeps = control_period / physics_dt
        if physics_dt <= 0 or substeps < 1 or abs(substeps - round(substeps)) > 1e-9:
            raise ValueError('control_period must be a positive multiple of physics_dt')
        if terrain not in TERRAINS:
            raise ValueError(f'terrain must be one of {TERRAINS}, got {terrain!r}')
        unknown = set(terrain_params or {}) - set(_TERRAIN_DEFAULTS)
        if unknown:
            raise ValueError(f'unknown terrain parameters {sorted(unknown)}')
        self._physics_dt = physics_dt
        self._control_period = control_period
        self._substeps = round(substeps)
        self._threshold = contact_threshold
        self._debounce = max(int(debounce_ticks), 1)
        self._friction = friction
        self._tick = 0

        self._p = bullet_client.BulletClient(
            connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        p = self._p
        p.resetSimulation()
        p.setGravity(0.0, 0.0, -GRAVITY)
        p.setTimeStep(physics_dt)
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1)
        if gui:
            p.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)

        self._terrain_bodies = self._build_terrain(
            terrain, {**_TERRAIN_DEFAULTS, **(terrain_params or {})}, seed)

        # Load high above the terrain so that the ground ray casts below never hit the robot.
        self._robot = p.loadURDF(urdf_path, basePosition=[0.0, 0.0, 100.0],
                                 flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
        joints, links = {}, {}
        for i in range(p.getNumJoints(self._robot)):
            info = p.getJointInfo(self._robot, i)
            joints[info[1].decode()] = i
            links[info[12].decode()] = i
        missing = [n for n in (*JOINT_NAMES, *FOOT_FRAMES) if n not in joints and n not in links]
        if missing:
            raise ValueError(f'{urdf_path} lacks {missing}')
        self._joints = [joints[n] for n in JOINT_NAMES]
        self._feet = [links[n] for n in FOOT_FRAMES]
        self._foot_index = {link: k for k, link in enumerate(self._feet)}
        self._effort_limit = np.array(
            [p.getJointInfo(self._robot, j)[10] for j in self._joints])
        # Base inertial frame in the base_link frame (PyBullet poses the base by this frame).
        local_pos, local_quat = p.getDynamicsInfo(self._robot, -1)[3:5]
        self._local_pos, self._local_quat = np.array(local_pos), np.array(local_quat)

        # Only the commanded torques move the robot: no default velocity motors, no joint
        # damping or friction, no artificial link damping (PyBullet's default is 0.04).
        p.setJointMotorControlArray(self._robot, self._joints, pybullet.VELOCITY_CONTROL,
                                    forces=[0.0] * len(self._joints))
        for link in range(-1, p.getNumJoints(self._robot)):
            p.changeDynamics(self._robot, link, linearDamping=0.0, angularDamping=0.0,
                             jointDamping=0.0, restitution=0.0)
        # Bullet multiplies the two bodies' coefficients: ground 1.0, robot = friction.
        for body in self._terrain_bodies:
            p.changeDynamics(body, -1, lateralFriction=1.0, restitution=0.0)
        for link in range(-1, p.getNumJoints(self._robot)):
            p.changeDynamics(self._robot, link, lateralFriction=friction)

        q0 = STANDING_POSE if initial_joint_positions is None else np.asarray(
            initial_joint_positions, dtype=float).reshape(len(JOINT_NAMES))
        for j, q in zip(self._joints, q0, strict=True):
            p.resetJointState(self._robot, j, float(q), 0.0)
        if initial_base_height is None:
            initial_base_height = self._touching_height()
        self._set_base_pose(np.array([0.0, 0.0, initial_base_height]),
                            np.array([0.0, 0.0, 0.0, 1.0]))
        p.resetBaseVelocity(self._robot, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])

        self._applied = np.zeros(len(JOINT_NAMES))
        self._wrench_force = np.zeros(3)
        self._wrench_torque = np.zeros(3)
        self._force = np.zeros((4, 3))
        self._normal = np.zeros(4)
        p.performCollisionDetection()
        self._contact = np.array([self._near_ground(f) for f in self._feet])
        self._pending = np.zeros(4, dtype=int)       # ticks the raw flag has differed
        self._touchdown = np.zeros(4, dtype=bool)
        self._liftoff = np.zeros(4, dtype=bool)

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
        """(12,) N m, the URDF torque limits in JOINT_NAMES order."""
        return self._effort_limit.copy()

    # ------------------------------------------------------------------ stepping
    def step(self, torques: np.ndarray) -> None:
        """Apply joint torques (12,) N m, clipped to the limits, for one control period."""
        tau = np.asarray(torques, dtype=float)
        if tau.shape != (len(JOINT_NAMES),):
            raise ValueError(f'expected {len(JOINT_NAMES)} torques, got shape {tau.shape}')
        if not np.all(np.isfinite(tau)):
            raise ValueError('torques contain NaN or inf')
        tau = np.clip(tau, -self._effort_limit, self._effort_limit)
        self._applied = tau
        p, robot = self._p, self._robot
        forces = tau.tolist()
        force_sum = np.zeros((4, 3))
        normal_sum = np.zeros(4)
        push = bool(np.any(self._wrench_force) or np.any(self._wrench_torque))
        for _ in range(self._substeps):
            # Torques and external forces act for one stepSimulation only: set them every step.
            p.setJointMotorControlArray(robot, self._joints, pybullet.TORQUE_CONTROL,
                                        forces=forces)
            if push:
                origin = self._base_pose()[0]
                p.applyExternalForce(robot, -1, self._wrench_force.tolist(), origin.tolist(),
                                     pybullet.WORLD_FRAME)
                p.applyExternalTorque(robot, -1, self._wrench_torque.tolist(),
                                      pybullet.WORLD_FRAME)
            p.stepSimulation()
            self._add_foot_forces(force_sum, normal_sum)
        self._tick += 1
        self._force = force_sum / self._substeps       # mean over the tick, N
        self._normal = normal_sum / self._substeps
        self._update_contact_flags()

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

    def joint_state(self) -> JointState:
        """Joint positions, velocities and the torques actually applied (after clipping)."""
        states = self._p.getJointStates(self._robot, self._joints)
        return JointState(stamp=self.time,
                          position=np.array([s[0] for s in states]),
                          velocity=np.array([s[1] for s in states]),
                          effort=self._applied.copy())

    def contact_state(self) -> ContactState:
        """Feet positions, ground reaction forces, debounced flags and edges of this tick."""
        feet = np.array([self._p.getLinkState(self._robot, link, computeForwardKinematics=True)[4]
                         for link in self._feet])
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

    def damping_torques(self, gain: float) -> np.ndarray:
        """Joint damping torques -gain * qd (N m) for the controller-dead mode."""
        return -gain * self.joint_state().velocity

    def close(self) -> None:
        """Disconnect from the physics server (idempotent)."""
        if self._p is not None:
            with contextlib.suppress(pybullet.error):
                self._p.disconnect()
            self._p = None

    # ------------------------------------------------------------------ internals
    # Pose conversions in numpy: pybullet.multiplyTransforms computes in single precision.
    def _base_pose(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position and quaternion of base_link in the world, and the position of the base's
        inertial frame (what pybullet reports)."""
        com_pos, com_quat = self._p.getBasePositionAndOrientation(self._robot)
        com_pos = np.array(com_pos)
        quat = rotations.multiply(com_quat, rotations.conjugate(self._local_quat))
        quat /= math.sqrt(quat[0] ** 2 + quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
        return com_pos - np.array(rotations.rotate(quat, self._local_pos)), quat, com_pos

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
        feet = np.array([self._p.getLinkState(self._robot, link, computeForwardKinematics=True)[4]
                         for link in self._feet])
        radius = np.array([self._foot_radius(link) for link in self._feet])
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
