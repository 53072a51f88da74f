"""Pinocchio model of the robot (``urdf/hyq.urdf``), built once and shared by the core modules.

Conventions handled here so that no other module has to:
- pinocchio's free-flyer configuration is ``q = [x y z qx qy qz qw, joints...]`` and its base
  velocity ``v[:6]`` is expressed in the LOCAL (base) frame, while ``types.BaseState`` carries
  world-frame velocities: ``configuration`` rotates them into the base frame;
- the joint order of the pinocchio model (depth-first over the URDF tree, e.g. lf, lh, rf, rh)
  may differ from ``types.JOINT_NAMES``: joints are mapped by name, and every array exchanged
  with the rest of the project is in ``JOINT_NAMES`` order.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from replan_core.common.rotations import quaternion_to_matrix
from replan_core.common.types import (
    FOOT_FRAMES,
    JOINT_NAMES,
    LEGS,
    BaseState,
    JointState,
)


def link_frame_id(model: pin.Model, name: str) -> int:
    """Index of the frame of the URDF link ``name`` (a BODY frame); ValueError if none.

    By name and type: a URDF may give a joint the name of a link (ANYmal C's joint and link
    ``LF_HAA``), and pinocchio's look-up by name alone then refuses ("Several frames match").
    """
    if not model.existFrame(name, pin.FrameType.BODY):
        raise ValueError(f'no link {name!r} in the model')
    return model.getFrameId(name, pin.FrameType.BODY)


def joint_id(model: pin.Model, name: str) -> int:
    """Index of the joint ``name`` (``model.joints``); ValueError if none.

    The joints have their own name table (``model.names``, joints only), so a link or frame
    of the same name is never taken.
    """
    if not model.existJointName(name):
        raise ValueError(f'no joint {name!r} in the model')
    return model.getJointId(name)


def unit_quaternion_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion given as floats (x, y, z, w).

    ``rotations.quaternion_to_matrix`` without its normalisation and numpy arithmetic: for a
    quaternion normalised already, a tenth of its cost per call.
    """
    return np.array((
        (1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y))))


class RobotModel:
    """Pinocchio model (free-flyer root) and one data, built once from a URDF.

    The methods taking a state recompute the kinematics they need in ``self.data``; the whole-body
    controller calls ``update`` once per tick and reads the results from ``self.data``.
    """

    def __init__(self, urdf_path: str, joint_names: tuple[str, ...] = JOINT_NAMES,
                 foot_frames: tuple[str, ...] = FOOT_FRAMES) -> None:
        """joint_names: the model's 12 actuated joints in the project's order (``JOINT_NAMES``
        order: LEGS, then HAA HFE KFE); foot_frames: its 4 foot frames in LEGS order. The
        defaults are the project's HyQ names; a robot file gives another robot's
        (``robot_file.RobotSpec.joints`` and ``.feet``)."""
        self.urdf_path = str(urdf_path)
        if len(joint_names) != 3 * len(LEGS) or len(foot_frames) != len(LEGS):
            raise ValueError(f'{self.urdf_path}: need {3 * len(LEGS)} joint names and '
                             f'{len(LEGS)} foot frames, got {len(joint_names)} and '
                             f'{len(foot_frames)}')
        self.model = pin.buildModelFromUrdf(self.urdf_path, pin.JointModelFreeFlyer())
        self.data = self.model.createData()
        model = self.model
        self._joint_names = tuple(joint_names)
        missing = [n for n in joint_names if not model.existJointName(n)]
        missing += [f for f in foot_frames if not model.existFrame(f, pin.FrameType.BODY)]
        if missing:
            raise ValueError(f'{self.urdf_path}: missing joints/frames {missing}')
        joint_ids = [joint_id(model, n) for n in joint_names]
        # Index of each joint in pinocchio's q and v vectors (all revolute: nq=nv=1).
        self.q_index = np.array([model.joints[j].idx_q for j in joint_ids], dtype=int)
        self.v_index = np.array([model.joints[j].idx_v for j in joint_ids], dtype=int)
        # v indices of each leg's three joints, (4, 3), leg-major as LEGS.
        self.leg_v_index = self.v_index.reshape(len(LEGS), 3)
        self.foot_frame_ids = tuple(link_frame_id(model, f) for f in foot_frames)
        self._haa_joint_ids = tuple(joint_ids[3 * i] for i in range(len(LEGS)))
        self._total_mass = float(pin.computeTotalMass(model))
        self.effort_limit = np.asarray(model.effortLimit, dtype=float)[self.v_index].copy()
        self.position_lower = np.asarray(model.lowerPositionLimit)[self.q_index].copy()
        self.position_upper = np.asarray(model.upperPositionLimit)[self.q_index].copy()
        # HAA origins in the base frame: joint placements do not depend on q of the joint itself,
        # so any configuration with the base at the identity gives them.
        q0 = pin.neutral(model)
        pin.forwardKinematics(model, self.data, q0)
        self._hip_offsets = np.array(
            [self.data.oMi[j].translation for j in self._haa_joint_ids], dtype=float)
        self._q = pin.neutral(model)
        self._v = np.zeros(model.nv)
        # (3, 3) base to world rotation of the last ``configuration`` (or ``update``) call.
        self.rotation = np.eye(3)

    # ----------------------------------------------------------------------------- properties
    @property
    def total_mass(self) -> float:
        """Total mass of the robot, kg."""
        return self._total_mass

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The model's actuated joint names, in the project's order (``types.JOINT_NAMES``
        order)."""
        return self._joint_names

    @property
    def hip_offsets(self) -> np.ndarray:
        """(4, 3) HAA joint origins in the base frame, LEGS order, m."""
        return self._hip_offsets.copy()

    # ------------------------------------------------------------------------- conversions
    def configuration(self, base: BaseState,
                      joints: JointState) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio ``(q, v)`` of a state; ``v[:6]`` in the base frame (LOCAL convention).

        Returns internal buffers, overwritten by the next call: copy them to keep them.
        """
        q, v = self._q, self._v
        # On floats: numpy's call overhead on a 4-vector costs more than the arithmetic.
        x, y, z, w = np.asarray(base.quaternion, dtype=float).tolist()
        norm = math.sqrt(x * x + y * y + z * z + w * w)
        if norm > 0.0:
            x, y, z, w = x / norm, y / norm, z / norm, w / norm
        else:                                      # a zero quaternion gives NaNs, as numpy did
            x = y = z = w = math.nan
        rotation = unit_quaternion_matrix(x, y, z, w)
        self.rotation = rotation
        q[0:3] = base.position
        q[3:7] = (x, y, z, w)
        q[self.q_index] = joints.position
        # [v_lin; omega] @ R = [R^T v_lin; R^T omega]: both base-frame vectors in one product.
        v[0:6] = (np.array((np.asarray(base.linear_velocity, dtype=float),
                            np.asarray(base.angular_velocity, dtype=float))) @ rotation).ravel()
        v[self.v_index] = joints.velocity
        return q, v

    def to_joint_order(self, vector_v: np.ndarray) -> np.ndarray:
        """Pick the actuated entries of a pinocchio v-sized vector, in JOINT_NAMES order."""
        return np.asarray(vector_v)[self.v_index]

    # ---------------------------------------------------------------------------- queries
    def com_state(self, base: BaseState,
                  joints: JointState) -> tuple[np.ndarray, np.ndarray]:
        """CoM position (3,) and velocity (3,) in the world frame."""
        q, v = self.configuration(base, joints)
        pin.centerOfMass(self.model, self.data, q, v, False)
        return self.data.com[0].copy(), self.data.vcom[0].copy()

    def foot_positions(self, base: BaseState, joints: JointState) -> np.ndarray:
        """(4, 3) foot frame origins in the world, LEGS order."""
        q, _ = self.configuration(base, joints)
        pin.forwardKinematics(self.model, self.data, q)
        return np.array([pin.updateFramePlacement(self.model, self.data, f).translation
                         for f in self.foot_frame_ids])

    def hip_positions(self, base: BaseState) -> np.ndarray:
        """(4, 3) HAA joint origins in the world, LEGS order."""
        rotation = quaternion_to_matrix(base.quaternion)
        return np.asarray(base.position, dtype=float) + self._hip_offsets @ rotation.T

    def foot_jacobians(self, base: BaseState, joints: JointState) -> np.ndarray:
        """(4, 3, nv) translational foot Jacobians, world axes (LOCAL_WORLD_ALIGNED).

        Columns are in pinocchio's v order; use ``leg_v_index`` to pick a leg's joints.
        """
        q, _ = self.configuration(base, joints)
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return np.array([
            pin.getFrameJacobian(self.model, self.data, f, pin.LOCAL_WORLD_ALIGNED)[:3]
            for f in self.foot_frame_ids])

    def update(self, base: BaseState, joints: JointState) -> tuple[np.ndarray, np.ndarray]:
        """All per-tick terms in one pass into ``self.data``; returns ``(q, v)``.

        After it: ``data.com[0]``, ``data.vcom[0]``, ``data.M`` (upper triangle filled),
        ``data.nle``, joint Jacobians (frame Jacobians via ``getFrameJacobian``), frame
        placements, ``data.Ig`` (centroidal composite inertia, world axes at the CoM).
        """
        q, v = self.configuration(base, joints)
        pin.computeAllTerms(self.model, self.data, q, v)   # kinematics, M, nle, J, com, vcom, Ag
        pin.updateFramePlacements(self.model, self.data)
        return q, v
