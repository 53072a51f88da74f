"""Transforms of every link of the robot, as robot_state_publisher computes them.

For each URDF joint (revolute and fixed) the pose of its child link in its parent link, from
the measured joint angles; plus the base's pose in ``odom`` from a base state. A viewer that
has the URDF (``/robot_description``) draws the robot from these (Foxglove's 3D panel, RViz).
Pure: numpy and pinocchio, no ROS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from replan_core.common.types import BASE_FRAME, JOINT_NAMES, WORLD_FRAME
from replan_core.robot.model import joint_id


@dataclass(frozen=True)
class Transform:
    """Pose of ``child`` in ``parent``: translation (m) and unit quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


class LinkFrames:
    """Kinematic tree of a URDF, built once; ``link_transforms`` per state.

    As robot_state_publisher: each joint's child link in its parent link is the joint origin
    (constant) times the rotation about the joint axis by its angle. Pinocchio gives the
    origins and axes once; per state it is a few numpy operations on all joints at once
    (calling pinocchio per link from Python cost 0.33 ms per state, 10x more).
    """

    def __init__(self, urdf_path: str, joint_names: tuple[str, ...] = JOINT_NAMES) -> None:
        """joint_names: the model's 12 actuated joints in ``JOINT_NAMES`` order (a robot
        file's; the default is the project's HyQ)."""
        # Fixed base: the root link sits at the identity, so every transform below is relative
        # and the base pose enters only through ``base_transform``.
        model = pin.buildModelFromUrdf(str(urdf_path))
        data = model.createData()
        missing = [n for n in joint_names if not model.existJointName(n)]
        if missing:
            raise ValueError(f'{urdf_path}: missing joints {missing}')
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        q_of_joint = {joint_id(model, n): i for i, n in enumerate(joint_names)}
        names, translations, rotations, movable, index, axes = [], [], [], [], [], []
        # (parent link, child link) of each URDF joint: a link's BODY frame has the joint's
        # frame as parent, whose parent is the parent link's BODY frame. Frames are taken by
        # index, never by name: a URDF may name a joint like a link (ANYmal C's LF_HAA).
        for frame_index, frame in enumerate(model.frames):
            if frame.type != pin.FrameType.BODY:
                continue
            joint = model.frames[frame.parentFrame]
            if joint.type not in (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT):
                continue
            parent = model.frames[joint.parentFrame]
            if parent.type != pin.FrameType.BODY:
                continue
            origin = data.oMf[joint.parentFrame].actInv(data.oMf[frame_index])
            names.append((parent.name, frame.name))
            translations.append(np.array(origin.translation))
            rotations.append(pin.Quaternion(origin.rotation).coeffs().copy())
            if joint.type == pin.FrameType.JOINT:
                if not np.allclose(frame.placement.homogeneous, np.eye(4)):
                    raise ValueError(f'{urdf_path}: link {frame.name} is not at its joint')
                if frame.parentJoint not in q_of_joint:
                    raise ValueError(f'{urdf_path}: joint {joint.name} is not actuated')
                movable.append(len(names) - 1)
                index.append(q_of_joint[frame.parentJoint])
                axes.append(np.array(data.joints[frame.parentJoint].S[3:6]).ravel())
        self._names = tuple(names)
        self._translations = np.array(translations)
        self._origins = np.array(rotations)            # (n, 4) x, y, z, w at zero angles
        self._movable = np.array(movable, dtype=int)
        self._angle_index = np.array(index, dtype=int)
        self._axes = np.array(axes)                    # (m, 3) unit axes, child frame
        self.root_link = next(f.name for f in model.frames if f.type == pin.FrameType.BODY)
        if self.root_link != BASE_FRAME:
            # The topics' base frame is the project's (odom -> base_link): the model's root
            # hangs below it at the identity, so a viewer finds every link.
            self._names = ((BASE_FRAME, self.root_link), *self._names)
            self._translations = np.vstack([np.zeros(3), self._translations])
            self._origins = np.vstack([[0.0, 0.0, 0.0, 1.0], self._origins])
            self._movable = self._movable + 1

    @property
    def links(self) -> tuple[str, ...]:
        """Every link name, the root first (the project's base frame above another root)."""
        return (self._names[0][0] if self.root_link != BASE_FRAME else self.root_link,
                *(child for _, child in self._names))

    def link_transforms(self, joint_positions: np.ndarray) -> list[Transform]:
        """Child link in parent link for every URDF joint; ``joint_positions`` (rad) in
        ``JOINT_NAMES`` order."""
        half = 0.5 * np.asarray(joint_positions, dtype=float)[self._angle_index]
        motion = np.column_stack([self._axes * np.sin(half)[:, None], np.cos(half)])
        rotations = self._origins.copy()
        rotations[self._movable] = quaternion_product(self._origins[self._movable], motion)
        return [Transform(parent, child, tuple(t.tolist()), tuple(r.tolist()))
                for (parent, child), t, r in zip(self._names, self._translations, rotations,
                                                 strict=True)]


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Hamilton product of (n, 4) quaternions (x, y, z, w)."""
    av, aw = a[:, :3], a[:, 3:]
    bv, bw = b[:, :3], b[:, 3:]
    return np.column_stack([aw * bv + bw * av + np.cross(av, bv),
                            aw * bw - np.sum(av * bv, axis=1, keepdims=True)])


def base_transform(position, quaternion, parent: str = WORLD_FRAME,
                   child: str = BASE_FRAME) -> Transform:
    """``odom -> base_link`` from a base position (m) and quaternion (x, y, z, w)."""
    q = np.asarray(quaternion, dtype=float)
    q = q / np.linalg.norm(q)
    return Transform(parent, child, tuple(float(v) for v in position),
                     tuple(float(v) for v in q))


def compose(a: Transform, b: Transform) -> tuple[np.ndarray, np.ndarray]:
    """(translation, rotation matrix) of ``a`` followed by ``b`` (b's parent is a's child)."""
    ra = pin.Quaternion(np.array(a.rotation)).toRotationMatrix()
    rb = pin.Quaternion(np.array(b.rotation)).toRotationMatrix()
    return np.asarray(a.translation) + ra @ np.asarray(b.translation), ra @ rb
