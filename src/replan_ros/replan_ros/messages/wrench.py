"""geometry_msgs/WrenchStamped: a force and torque on the base (pushes, the sim's applied wrench).

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import WrenchStamped

from replan_core.common.types import WORLD_FRAME
from replan_ros.messages.stamps import ns_to_stamp, stamp_to_ns


def wrench_to_msg(stamp_ns: int, force, torque=(0.0, 0.0, 0.0)) -> WrenchStamped:
    """An external wrench on the base (N, N m, world axes) from ``stamp_ns`` on."""
    msg = WrenchStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = WORLD_FRAME
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = map(float, force)
    msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = map(float, torque)
    return msg


def wrench_from_msg(msg: WrenchStamped) -> tuple[int, np.ndarray, np.ndarray]:
    """(stamp ns, force (3,) N, torque (3,) N m); ValueError for another frame than the world
    (or none) or a non-finite value."""
    f, t = msg.wrench.force, msg.wrench.torque
    force, torque = np.array([f.x, f.y, f.z]), np.array([t.x, t.y, t.z])
    if msg.header.frame_id not in ('', WORLD_FRAME):
        raise ValueError(f'frame {msg.header.frame_id!r}: only {WORLD_FRAME!r} (world axes) '
                         'is supported')
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(torque))):
        raise ValueError('non-finite values')
    return stamp_to_ns(msg.header.stamp), force, torque
