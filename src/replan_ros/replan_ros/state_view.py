"""What a viewer needs to draw the robot, derived from the graph's own topics (no Node here).

Used by the recorder (written into every bag) and by the live view (served over WebSocket), so
both show the same: one implementation, off the 250 Hz critical path (README, "Watch the
robot").

- ``/robot_description`` (``std_msgs/String``): the model URDF, as robot_state_publisher.
- ``/tf`` (``tf2_msgs/TFMessage``): ``odom -> base_link`` from the **estimate** (``/odom``, what
  the robot knows) and every link from the measured ``/joint_states`` of the same stamp, at
  most one per ``period`` of sim time. The Python type is not in the PyPI wheels: the message
  is CDR-encoded from its ``ros2msg`` schema (``bag_io.EXTRA_DEFINITIONS``), so it exists in
  bags and over WebSocket only, never over DDS.
- ``/view/contact_forces`` (``visualization_msgs/MarkerArray``, frame ``odom``): the
  simulator's measured ground reaction forces (``/ground_truth/contacts``) as arrows, their
  centre of pressure (green inside the polygon, red outside) and the polygon of the loaded
  feet; ``/view/cop_margin`` (m, ``std_msgs/Float64``), the same margin as metrics.json's.
- ``/view/mpc_solve_time_ms`` and ``/view/zmp_margin`` (``std_msgs/Float64``) from the mpc
  node's ``/diagnostics``, one per re-plan.
- ``/view/velocity_error`` (``geometry_msgs/Vector3Stamped``): estimated body velocity minus
  the set-point in force (``/velocity_setpoint``): x, y in m/s, z the yaw rate in rad/s.
"""

from __future__ import annotations

import math
import os
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, TwistStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState as JointStateMsg
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import ColorRGBA, Float64, String
from visualization_msgs.msg import Marker, MarkerArray

from replan_core.frames import LinkFrames, base_transform
from replan_core.metrics import cop_margins
from replan_core.support import convex_hull
from replan_core.types import WORLD_FRAME
from replan_ros.bag_io import message_definition, normalize_type_name
from replan_ros.cdr import POSE, CdrWriter
from replan_ros.interfaces import contacts_from_msg, joint_state_from_msg, ns_to_stamp
from replan_ros.stamped_buffer import cdr_header_stamp_ns

DESCRIPTION_TOPIC = '/robot_description'
TF_TOPIC = '/tf'
FORCES_TOPIC = '/view/contact_forces'
COP_MARGIN_TOPIC = '/view/cop_margin'
SOLVE_TIME_TOPIC = '/view/mpc_solve_time_ms'
ZMP_MARGIN_TOPIC = '/view/zmp_margin'
VELOCITY_ERROR_TOPIC = '/view/velocity_error'
TF_TYPE = 'tf2_msgs/msg/TFMessage'
TYPES = {
    DESCRIPTION_TOPIC: 'std_msgs/msg/String',
    TF_TOPIC: TF_TYPE,
    FORCES_TOPIC: 'visualization_msgs/msg/MarkerArray',
    COP_MARGIN_TOPIC: 'std_msgs/msg/Float64',
    SOLVE_TIME_TOPIC: 'std_msgs/msg/Float64',
    ZMP_MARGIN_TOPIC: 'std_msgs/msg/Float64',
    VELOCITY_ERROR_TOPIC: 'geometry_msgs/msg/Vector3Stamped',
}
DERIVED_TOPICS = tuple(TYPES)
INPUT_TOPICS = ('/odom', '/joint_states', '/ground_truth/contacts', '/diagnostics',
                '/velocity_setpoint')
_PAIRING = 16            # recent stamps of /odom and /joint_states kept to pair them


@dataclass(frozen=True)
class Derived:
    """One derived message: topic, ``pkg/msg/Type``, CDR payload, stamp (sim ns)."""

    topic: str
    type_name: str
    data: bytes
    stamp_ns: int


def default_urdf_path() -> str:
    """``$REPLAN_URDF``, else the repository's (or the installed share's) ``urdf/hyq.urdf``."""
    env = os.environ.get('REPLAN_URDF', '')
    if env:
        return env
    here = Path(__file__).resolve()
    for candidate in (here.parents[3] / 'urdf' / 'hyq.urdf',
                      here.parents[1] / 'share' / 'replan_ros' / 'urdf' / 'hyq.urdf'):
        if candidate.is_file():
            return str(candidate)
    return str(here.parents[3] / 'urdf' / 'hyq.urdf')


def definition(type_name: str) -> str:
    """Full ``ros2msg`` schema text of a derived type (tf2_msgs included)."""
    return message_definition(normalize_type_name(type_name))


def encode_tf(stamp_ns: int, transforms) -> bytes:
    """CDR (little endian) of a ``tf2_msgs/msg/TFMessage`` whose ``TransformStamped`` all have
    ``stamp_ns``. Written by hand (``cdr.CdrWriter``): no Python class exists for the type, and
    mcap_ros2's generic encoder from the schema took 0.33 ms per message here against 0.07 ms
    (test_tf_bag.py checks the bytes against that encoder and decodes them with rosbags)."""
    w = CdrWriter()
    w.u32(len(transforms))
    for t in transforms:
        w.time(stamp_ns)
        w.string(t.parent)
        w.string(t.child)
        w.packed(POSE, 8, *t.translation, *t.rotation)
    return w.bytes()


def _color(r: float, g: float, b: float, a: float = 1.0) -> ColorRGBA:
    return ColorRGBA(r=r, g=g, b=b, a=a)


class StateView:
    """Feed it the serialized messages of ``INPUT_TOPICS``; it returns the derived ones."""

    def __init__(self, urdf_path: str | None = None, *, period: float = 0.04,
                 force_scale: float = 0.001, min_normal_force: float = 1.0) -> None:
        self.urdf_path = urdf_path or default_urdf_path()
        self.urdf = Path(self.urdf_path).read_text()
        self.frames = LinkFrames(self.urdf_path)
        self.period_ns = round(period * 1e9)
        self.force_scale = float(force_scale)
        self.min_normal_force = float(min_normal_force)
        self._joints: OrderedDict[int, bytes] = OrderedDict()
        self._odom: OrderedDict[int, bytes] = OrderedDict()
        self._last: dict[str, int] = {}
        self._setpoint = (0.0, 0.0, 0.0)

    def description(self) -> Derived:
        """``/robot_description`` (stamp 0: it holds from the start)."""
        return Derived(DESCRIPTION_TOPIC, TYPES[DESCRIPTION_TOPIC],
                       bytes(serialize_message(String(data=self.urdf))), 0)

    def feed(self, topic: str, data: bytes) -> list[Derived]:
        """The derived messages that this input completes (often none). Malformed input is
        skipped: a viewer must never stop the recorder or the live view."""
        try:
            if topic in ('/odom', '/joint_states'):
                return self._feed_state(topic, data)
            if topic == '/ground_truth/contacts':
                return self._feed_contacts(data)
            if topic == '/diagnostics':
                return self._feed_diagnostics(data)
            if topic == '/velocity_setpoint':
                msg = deserialize_message(data, TwistStamped)
                t = msg.twist
                self._setpoint = (t.linear.x, t.linear.y, t.angular.z)
        except Exception:  # rclpy raises its own RMWError on bad CDR: skip, never stop
            pass
        return []

    def _due(self, key: str, stamp: int) -> bool:
        last = self._last.get(key)
        # A stamp before the last one: a new run or a replayed bag starts again.
        if last is None or stamp < last or stamp - last >= self.period_ns - 1000:
            self._last[key] = stamp
            return True
        return False

    # ------------------------------------------------------------------ transforms

    def _feed_state(self, topic: str, data: bytes) -> list[Derived]:
        stamp = cdr_header_stamp_ns(data)
        if stamp is None:
            return []
        mine, other = ((self._odom, self._joints) if topic == '/odom'
                       else (self._joints, self._odom))
        mine[stamp] = data
        while len(mine) > _PAIRING:
            mine.popitem(last=False)
        if stamp not in other or not self._due('tf', stamp):
            return []
        odom = deserialize_message(self._odom[stamp], Odometry)
        joints = joint_state_from_msg(deserialize_message(self._joints[stamp], JointStateMsg))
        return [self.transforms(stamp, odom, joints.position), *self._velocity_error(odom)]

    def transforms(self, stamp: int, odom: Odometry, joint_positions) -> Derived:
        """``/tf`` of one state: the base from ``odom``, the links from the joint angles."""
        p, o = odom.pose.pose.position, odom.pose.pose.orientation
        items = [base_transform((p.x, p.y, p.z), (o.x, o.y, o.z, o.w),
                                odom.header.frame_id or WORLD_FRAME,
                                odom.child_frame_id or 'base_link')]
        items += self.frames.link_transforms(np.asarray(joint_positions, dtype=float))
        return Derived(TF_TOPIC, TF_TYPE, encode_tf(stamp, items), stamp)

    def _velocity_error(self, odom: Odometry) -> list[Derived]:
        twist = odom.twist.twist
        msg = Vector3Stamped()
        msg.header = odom.header
        msg.vector.x = twist.linear.x - self._setpoint[0]
        msg.vector.y = twist.linear.y - self._setpoint[1]
        msg.vector.z = twist.angular.z - self._setpoint[2]
        return [self._derived(VELOCITY_ERROR_TOPIC, msg, _ns(odom.header.stamp))]

    # ------------------------------------------------------------------ forces and CoP

    def _feed_contacts(self, data: bytes) -> list[Derived]:
        stamp = cdr_header_stamp_ns(data)
        if stamp is None or not self._due('contacts', stamp):
            return []
        contacts = contacts_from_msg(deserialize_message(data, PointCloud2))
        feet, forces = contacts.foot_position, contacts.force
        cop, margin = cop_margins(feet[None], forces[None], self.min_normal_force)
        markers = self.force_markers(stamp, feet, forces, cop[0], float(margin[0]))
        out = [self._derived(FORCES_TOPIC, markers, stamp)]
        if math.isfinite(margin[0]):
            out.append(self._derived(COP_MARGIN_TOPIC, Float64(data=float(margin[0])), stamp))
        return out

    def force_markers(self, stamp: int, feet: np.ndarray, forces: np.ndarray,
                      cop: np.ndarray, margin: float) -> MarkerArray:
        """Arrows of the loaded feet's forces, the CoP and the polygon of the loaded feet."""
        header_stamp = ns_to_stamp(stamp)

        def marker(ns: str, marker_id: int, kind: int) -> Marker:
            m = Marker()
            m.header.stamp = header_stamp
            m.header.frame_id = WORLD_FRAME
            m.ns, m.id, m.type, m.action = ns, marker_id, kind, Marker.ADD
            m.pose.orientation.w = 1.0
            return m

        clear = Marker()
        clear.action = Marker.DELETEALL      # feet that lift off lose their arrow
        out = [clear]
        loaded = forces[:, 2] > self.min_normal_force
        for leg in np.flatnonzero(loaded):
            arrow = marker('contact_force', int(leg), Marker.ARROW)
            tip = feet[leg] + self.force_scale * forces[leg]
            arrow.points = [Point(x=float(a), y=float(b), z=float(c))
                            for a, b, c in (feet[leg], tip)]
            arrow.scale.x, arrow.scale.y, arrow.scale.z = 0.015, 0.03, 0.04   # m
            arrow.color = _color(1.0, 0.55, 0.0)
            out.append(arrow)
        if np.any(loaded):
            height = float(np.mean(feet[loaded, 2]))
            hull = convex_hull(feet[loaded, :2])
            if len(hull) >= 2:
                polygon = marker('support_polygon', 0, Marker.LINE_STRIP)
                polygon.points = [Point(x=float(x), y=float(y), z=height)
                                  for x, y in [*hull, hull[0]]]
                polygon.scale.x = 0.008
                polygon.color = _color(0.2, 0.5, 1.0)
                out.append(polygon)
            if np.all(np.isfinite(cop)):
                sphere = marker('centre_of_pressure', 0, Marker.SPHERE)
                sphere.pose.position = Point(x=float(cop[0]), y=float(cop[1]), z=height)
                sphere.scale.x = sphere.scale.y = sphere.scale.z = 0.03
                sphere.color = (_color(0.1, 0.8, 0.1) if margin >= 0.0
                                else _color(0.9, 0.1, 0.1))
                out.append(sphere)
        return MarkerArray(markers=out)

    # ------------------------------------------------------------------ planner figures

    def _feed_diagnostics(self, data: bytes) -> list[Derived]:
        msg = deserialize_message(data, DiagnosticArray)
        out = []
        for status in msg.status:
            if status.name != 'mpc':
                continue
            values = {kv.key: kv.value for kv in status.values}
            if 'stamp' not in values:
                continue                      # an error status without a solve
            stamp = _ns(msg.header.stamp)     # the re-plan's sim time
            for key, topic in (('solve_time_ms', SOLVE_TIME_TOPIC),
                               ('zmp_margin_m', ZMP_MARGIN_TOPIC)):
                value = float(values.get(key, 'nan'))
                if math.isfinite(value):
                    out.append(self._derived(topic, Float64(data=value), stamp))
        return out

    @staticmethod
    def _derived(topic: str, msg, stamp: int) -> Derived:
        return Derived(topic, TYPES[topic], bytes(serialize_message(msg)), stamp)


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
