"""Quaternions (x, y, z, w, the ROS and pybullet order) and the rotations built from them.

One implementation for the core and the message conversions. The per-tick functions work on
plain floats: on 3-vectors numpy's call overhead costs more than the arithmetic.
"""

from __future__ import annotations

import math

import numpy as np


def quaternion_to_matrix(quaternion: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion (x, y, z, w), normalised first."""
    x, y, z, w = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def yaw_of(quaternion) -> float:
    """Yaw (rad) of a quaternion (x, y, z, w), ZYX convention."""
    # On Python floats: the same operations as on numpy scalars, so the same bits, and a
    # fraction of the cost (it runs in the control tick).
    x, y, z, w = np.asarray(quaternion, dtype=float).tolist()
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def normalized(quaternion) -> tuple[float, float, float, float]:
    """The quaternion divided by its norm, as floats."""
    x, y, z, w = (float(c) for c in quaternion)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return x / n, y / n, z / n, w / n


def conjugate(quaternion) -> tuple[float, float, float, float]:
    """The inverse rotation of a unit quaternion."""
    x, y, z, w = quaternion
    return -x, -y, -z, w


def multiply(a, b) -> np.ndarray:
    """Hamilton product a * b of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def rotate(quaternion, vector) -> tuple[float, float, float]:
    """``vector`` rotated by the unit ``quaternion``: v + 2 u x (u x v + w v)."""
    x, y, z, w = quaternion
    vx, vy, vz = vector
    tx, ty, tz = y * vz - z * vy + w * vx, z * vx - x * vz + w * vy, x * vy - y * vx + w * vz
    return (vx + 2.0 * (y * tz - z * ty), vy + 2.0 * (z * tx - x * tz),
            vz + 2.0 * (x * ty - y * tx))
