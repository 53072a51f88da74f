"""What a viewer needs to draw the robot, derived from the graph's own topics (no Node here).

Used by the recorder (written into every bag) and by the live view (served over WebSocket), so
both show the same: one implementation, off the 250 Hz critical path (docs/usage.md, "Watch the
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
import struct
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import String
from visualization_msgs.msg import Marker

from replan_core.common.types import WORLD_FRAME
from replan_core.evaluation.metrics import cop_margins
from replan_core.mpc.support import convex_hull
from replan_core.robot.frames import LinkFrames, base_transform
from replan_core.robot.robot_file import default_urdf
from replan_ros.messages.cdr import ENCAPSULATION, CdrWriter
from replan_ros.messages.contacts import contacts_from_cdr
from replan_ros.messages.joint_state import joint_state_from_cdr
from replan_ros.messages.odom import odom_fields_from_cdr
from replan_ros.messages.path import POSE
from replan_ros.params.spec import ConfigError
from replan_ros.recording.bag_io import message_definition, normalize_type_name
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns

if TYPE_CHECKING:
    from replan_ros.params.robot import NodeRobot

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
# Recent stamps of /odom and /joint_states kept to pair them: 1 s of 4 ms ticks. A reliable
# reader that lost a sample holds every later one of that writer until the writer sends it
# again, a heartbeat (100 ms, config/dds/fastdds.xml) later: one topic then arrives 25 ticks
# or more behind the other, and a shorter window loses those ticks' /tf.
_PAIRING = 250
_D3 = struct.Struct('<3d')
_F4 = struct.Struct('<4f')
_I3 = struct.Struct('<3i')
_FLOAT64 = struct.Struct('<4sd')


@dataclass(frozen=True)
class Derived:
    """One derived message: topic, ``pkg/msg/Type``, CDR payload, stamp (sim ns)."""

    topic: str
    type_name: str
    data: bytes
    stamp_ns: int


def default_urdf_path() -> str:
    """``$REPLAN_URDF``, else the repository's (or the installed share's) ``urdf/hyq.urdf``."""
    here = Path(__file__).resolve()
    return default_urdf(here.parents[4], here.parents[2] / 'share' / 'replan_ros')


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


@dataclass(frozen=True)
class MarkerSpec:
    """The fields of a ``visualization_msgs/Marker`` that the view sets; the others keep
    their defaults (identity orientation, no lifetime, no colours, texture, text or mesh)."""

    ns: str = ''
    marker_id: int = 0
    kind: int = Marker.ARROW
    action: int = Marker.ADD
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: tuple[float, float, float] = (0.0, 0.0, 0.0)
    color: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)     # r g b a
    points: tuple[tuple[float, float, float], ...] = ()
    stamp_ns: int = 0
    frame_id: str = ''


def encode_markers(markers: list[MarkerSpec]) -> bytes:
    """CDR (little endian) of a ``visualization_msgs/MarkerArray``: rclpy's bytes for the same
    message but for the padding, zero here (test_tf_bag.py compares them). Building the
    message from rclpy's classes and serializing it took 0.45 ms per array here, each marker
    being some 40 Python objects; the view writes one array per 0.04 s of sim time."""
    w = CdrWriter()
    w.u32(len(markers))
    for m in markers:
        w.header(m.stamp_ns, m.frame_id)
        w.string(m.ns)
        w.packed(_I3, 4, m.marker_id, m.kind, m.action)
        w.packed(POSE, 8, *m.position, 0.0, 0.0, 0.0, 1.0)
        w.packed(_D3, 8, *m.scale)
        w.packed(_F4, 4, *m.color)
        w.time(0)                            # lifetime
        w.buf.append(0)                      # frame_locked
        w.u32(len(m.points))
        for point in m.points:
            w.packed(_D3, 8, *point)
        w.u32(0)                             # colors
        w.string('')                         # texture_resource
        w.header(0, '')                      # texture: header, format, data
        w.string('')
        w.u32(0)
        w.u32(0)                             # uv_coordinates
        w.string('')                         # text
        w.string('')                         # mesh_resource
        w.string('')                         # mesh_file: filename, data
        w.u32(0)
        w.buf.append(0)                      # mesh_use_embedded_materials
    return w.bytes()


def encode_float64(value: float) -> bytes:
    """CDR of a ``std_msgs/Float64``."""
    return _FLOAT64.pack(ENCAPSULATION, value)


def encode_vector3_stamped(stamp_ns: int, frame_id: str, x: float, y: float,
                           z: float) -> bytes:
    """CDR of a ``geometry_msgs/Vector3Stamped``."""
    w = CdrWriter()
    w.header(stamp_ns, frame_id)
    w.packed(_D3, 8, x, y, z)
    return w.bytes()


def robot_state_view(robot: NodeRobot, **options) -> StateView:
    """The ``StateView`` of a node's robot (``options``: StateView's); ConfigError with one
    line when its model gives no ``/robot_description`` and ``/tf`` (a URDF that cannot be
    read, a link that cannot be placed): a viewer or a bag without them cannot show it."""
    name = robot.spec.name if robot.spec is not None else 'the robot'
    try:
        return StateView(robot.urdf or None, joint_names=robot.joints, **options)
    except (OSError, ValueError, RuntimeError) as err:
        detail = str(err).splitlines()[0] if str(err) else type(err).__name__
        urdf = robot.urdf or default_urdf_path()
        if urdf not in detail:
            detail = f'{urdf}: {detail}'
        raise ConfigError(f'cannot derive /robot_description and /tf of {name}: '
                          f'{detail}') from None


class StateView:
    """Feed it the serialized messages of ``INPUT_TOPICS``; it returns the derived ones."""

    def __init__(self, urdf_path: str | None = None, *, period: float = 0.04,
                 force_scale: float = 0.001, min_normal_force: float = 1.0,
                 joint_names: tuple[str, ...] | None = None) -> None:
        """joint_names: the model's joints in the project's order (a robot file's; None: the
        project's HyQ names)."""
        self.urdf_path = urdf_path or default_urdf_path()
        self.urdf = Path(self.urdf_path).read_text()
        self.frames = (LinkFrames(self.urdf_path) if joint_names is None
                       else LinkFrames(self.urdf_path, tuple(joint_names)))
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
        odom_stamp, frame_id, child_frame_id, pose, twist = odom_fields_from_cdr(
            self._odom[stamp])
        _, joints = joint_state_from_cdr(self._joints[stamp])
        return [self.transforms(stamp, pose, joints.position, frame_id, child_frame_id),
                Derived(VELOCITY_ERROR_TOPIC, TYPES[VELOCITY_ERROR_TOPIC],
                        encode_vector3_stamped(odom_stamp, frame_id,
                                               twist[0] - self._setpoint[0],
                                               twist[1] - self._setpoint[1],
                                               twist[5] - self._setpoint[2]), odom_stamp)]

    def transforms(self, stamp: int, pose, joint_positions, frame_id: str = '',
                   child_frame_id: str = '') -> Derived:
        """``/tf`` of one state: the base from an odometry ``pose`` (x y z qx qy qz qw) in
        ``frame_id`` (default odom), the links from the joint angles."""
        items = [base_transform(tuple(pose[:3]), tuple(pose[3:7]), frame_id or WORLD_FRAME,
                                child_frame_id or 'base_link')]
        items += self.frames.link_transforms(np.asarray(joint_positions, dtype=float))
        return Derived(TF_TOPIC, TF_TYPE, encode_tf(stamp, items), stamp)

    # ------------------------------------------------------------------ forces and CoP

    def _feed_contacts(self, data: bytes) -> list[Derived]:
        stamp = cdr_header_stamp_ns(data)
        if stamp is None or not self._due('contacts', stamp):
            return []
        _, contacts = contacts_from_cdr(data)
        feet, forces = contacts.foot_position, contacts.force
        cop, margin = cop_margins(feet[None], forces[None], self.min_normal_force)
        markers = self.force_markers(stamp, feet, forces, cop[0], float(margin[0]))
        out = [Derived(FORCES_TOPIC, TYPES[FORCES_TOPIC], encode_markers(markers), stamp)]
        if math.isfinite(margin[0]):
            out.append(Derived(COP_MARGIN_TOPIC, TYPES[COP_MARGIN_TOPIC],
                               encode_float64(float(margin[0])), stamp))
        return out

    def force_markers(self, stamp: int, feet: np.ndarray, forces: np.ndarray,
                      cop: np.ndarray, margin: float) -> list[MarkerSpec]:
        """Arrows of the loaded feet's forces, the CoP and the polygon of the loaded feet;
        the first marker deletes the previous ones (feet that lift off lose their arrow)."""
        out = [MarkerSpec(action=Marker.DELETEALL)]
        feet_xyz = feet.tolist()
        tips = (feet + self.force_scale * forces).tolist()
        loaded = (forces[:, 2] > self.min_normal_force).tolist()
        for leg in range(len(loaded)):
            if loaded[leg]:
                out.append(MarkerSpec(
                    'contact_force', leg, Marker.ARROW, scale=(0.015, 0.03, 0.04),   # m
                    color=(1.0, 0.55, 0.0, 1.0), points=(tuple(feet_xyz[leg]),
                                                         tuple(tips[leg])),
                    stamp_ns=stamp, frame_id=WORLD_FRAME))
        if any(loaded):
            mask = np.array(loaded)
            height = float(np.mean(feet[mask, 2]))
            hull = convex_hull(feet[mask, :2]).tolist()
            if len(hull) >= 2:
                out.append(MarkerSpec(
                    'support_polygon', 0, Marker.LINE_STRIP, scale=(0.008, 0.0, 0.0),
                    color=(0.2, 0.5, 1.0, 1.0),
                    points=tuple((x, y, height) for x, y in [*hull, hull[0]]),
                    stamp_ns=stamp, frame_id=WORLD_FRAME))
            if np.all(np.isfinite(cop)):
                out.append(MarkerSpec(
                    'centre_of_pressure', 0, Marker.SPHERE,
                    position=(float(cop[0]), float(cop[1]), height), scale=(0.03, 0.03, 0.03),
                    color=(0.1, 0.8, 0.1, 1.0) if margin >= 0.0 else (0.9, 0.1, 0.1, 1.0),
                    stamp_ns=stamp, frame_id=WORLD_FRAME))
        return out

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
                    out.append(Derived(topic, TYPES[topic], encode_float64(value), stamp))
        return out


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
