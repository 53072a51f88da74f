"""nav_msgs/Path of planned points (com_path, zmp_plan), as an rclpy message and as
hand-written CDR.

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import struct

import numpy as np
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path

from replan_core.common.types import WORLD_FRAME
from replan_ros.messages.cdr import CdrWriter
from replan_ros.messages.stamps import header


def path_msg(start_time: float, dt: float, points: np.ndarray,
             frame_id: str = WORLD_FRAME) -> Path:
    """nav_msgs/Path with one pose per row of ``points`` (n, 2 or 3), stamped every ``dt``."""
    msg = Path(header=header(start_time, frame_id))
    for k, p in enumerate(points):
        pose = PoseStamped(header=header(start_time + k * dt, frame_id))
        pose.pose.position = Point(x=float(p[0]), y=float(p[1]),
                                   z=float(p[2]) if len(p) > 2 else 0.0)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg


POSE = struct.Struct('<7d')      # geometry_msgs Pose / Transform: x y z, qx qy qz qw


def encode_path(stamp_ns: int, start_time: float, dt: float, points: np.ndarray,
                frame_id: str) -> bytes:
    """``nav_msgs/Path`` stamped ``stamp_ns`` as ``path_msg`` builds it: one pose
    per row of ``points`` (n, 2 or 3; z 0 if absent), pose ``k`` stamped
    ``start_time + k * dt`` (s), identity orientation."""
    w = CdrWriter()
    w.header(stamp_ns, frame_id)
    xyz = np.zeros((len(points), 3))
    points = np.asarray(points, dtype=float)
    xyz[:, :points.shape[1]] = points[:, :3]
    w.u32(len(xyz))
    for k, (x, y, z) in enumerate(xyz.tolist()):
        w.header(round((start_time + k * dt) * 1e9), frame_id)     # as stamps.header
        w.packed(POSE, 8, x, y, z, 0.0, 0.0, 0.0, 1.0)
    return w.bytes()
