"""Live view: the running graph in Foxglove (or Lichtblick) over a WebSocket, no display needed.

``scripts/launch.sh --live [PORT]`` starts it with the graph; by hand:
``python -m replan_ros.view.live_view --ros-args --params-file config/live_view.yaml``. It

- serves every topic of the graph as it is (``ros2msg`` schemas and CDR payloads, as the
  recorder writes them: ``bag_io``), under both WebSocket subprotocols viewers offer
  (``foxglove_server``);
- adds what a viewer needs to draw the robot (``state_view``, the same as in the bags):
  ``/robot_description``, ``/tf`` (estimate + measured joints), contact force markers, the
  measured CoP and its margin, solve time, ZMP margin and velocity error as plottable numbers;
- publishes ``robot_description`` (``std_msgs/String``, reliable, transient local) over DDS,
  as robot_state_publisher does (``/tf`` cannot be: ``tf2_msgs`` is not in the PyPI wheels);
- lets viewers publish ``geometry_msgs/Twist`` on ``client_topics`` (``cmd_vel``: Foxglove's
  Teleop panel), checked by the gait node like any other ``cmd_vel``;
- serves the meshes the robot's URDF names (``package://...``) to viewers that fetch them
  (the protocol's ``assets`` capability), from the model folders only
  (``replan_core.robot.assets``): example-robot-data's share tree and the project's ``urdf/``.

Off the critical path: its own process; a topic is advertised to viewers as soon as it is
discovered but read over DDS only once a viewer subscribes to it (or to a derived topic that
needs it), as foxglove_bridge does, since every reader costs the publishing node a send per
sample; the reader then stays until the live view exits. Subscriptions are read on demand
(``on_demand``) every ``take_period`` wall s, best effort for volatile topics, so the sim and
the controller never wait for it; of a high-rate topic only the newest sample of each take is
sent (20 Hz); a slow viewer loses its oldest frames, never slows the graph (docs/usage.md,
"Watch the robot").
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

from geometry_msgs.msg import Twist
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

from replan_core.robot.assets import served_model_assets
from replan_ros.messages.introspection import message_class
from replan_ros.nodes.node_main import load_node_robot, refuse_configuration, run_node
from replan_ros.params import ConfigError, declare_node_parameters
from replan_ros.params.robot import project_root
from replan_ros.recording.bag_io import has_header, message_definition, normalize_type_name
from replan_ros.transport import qos
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns
from replan_ros.view.foxglove_server import FoxgloveServer
from replan_ros.view.state_view import (
    DERIVED_TOPICS,
    DESCRIPTION_TOPIC,
    INPUT_TOPICS,
    TYPES,
    Derived,
    definition,
    robot_state_view,
)

# Topics whose every message matters to a viewer (events, logs): all are sent, not only the
# newest of a take.
EVENT_TOPICS = frozenset({'/diagnostics', '/rosout', '/contact_events', '/velocity_setpoint',
                          '/applied_wrench', '/cmd_vel', '/cmd_vel_stamped', '/external_wrench'})
EVENT_DEPTH = 50
STATE_DEPTH = 8          # /odom and /joint_states: enough of each to pair them by stamp
STREAM_DEPTH = 1         # any other volatile topic: the newest sample only
TWIST_TYPES = ('geometry_msgs/msg/Twist', 'geometry_msgs/Twist')


@dataclass
class _Forwarded:
    topic: str
    channel_id: int
    stamp_in_header: bool
    latched: bool
    msg_type: type
    profile: QoSProfile
    subscribed: bool = False


def subscription_qos(profiles, topic: str) -> QoSProfile:
    """What the live view asks of a topic's publishers: transient local only if they all are
    (latched plans and markers, newest one), else best effort (a reliable writer never waits
    for a best-effort reader), deep enough for events and for pairing state by stamp."""
    if profiles and all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles):
        return qos.LATCHED
    depth = (EVENT_DEPTH if topic in EVENT_TOPICS else
             STATE_DEPTH if topic in INPUT_TOPICS else STREAM_DEPTH)
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


def twist_from_json(payload: bytes) -> Twist:
    """A ``geometry_msgs/Twist`` from its JSON form ({"linear": {"x": ...}, "angular": ...})."""
    data = json.loads(payload)
    msg = Twist()
    if not isinstance(data, dict) or set(data) - {'linear', 'angular'}:
        raise ValueError('expected {"linear": {...}, "angular": {...}}')
    for part, values in data.items():
        if not isinstance(values, dict) or set(values) - {'x', 'y', 'z'}:
            raise ValueError(f'{part}: expected {{"x": .., "y": .., "z": ..}}')
        for axis, value in values.items():
            setattr(getattr(msg, part), axis, float(value))
    return msg


class LiveViewNode(Node):
    """Serves the graph to Foxglove viewers."""

    def __init__(self) -> None:
        super().__init__('live_view')
        p = declare_node_parameters(self, 'live_view')
        self._wanted: list[int] = []      # channel ids first subscribed (server thread appends)
        self._wanted_ids: set[int] = set()
        self._derived_wanted = False
        self._now_ns = 0                 # newest sim time seen (stamps, /clock)
        robot = load_node_robot(self, p, '')       # the robot file's model and names
        try:
            self.view = robot_state_view(robot, period=p['view_period'],
                                         force_scale=p['force_scale'])
        except ConfigError as err:      # a live view that cannot draw the robot: exit code 2
            refuse_configuration(self, f'{err}; the live view cannot draw the robot')
        self._description_pub = self.create_publisher(String, 'robot_description', qos.LATCHED)
        self._description_pub.publish(String(data=self.view.urdf))
        # Created here, not when a viewer advertises: the server thread never creates entities.
        self._client_pubs = {self.resolve_topic_name(t): self.create_publisher(Twist, t,
                                                                              qos.COMMAND)
                             for t in p['client_topics']}
        self.server = FoxgloveServer(
            p['host'], p['port'], name='replan live view', client_topics=tuple(self._client_pubs),
            on_client_message=self._on_client_message, queue_size=p['queue_size'],
            on_first_subscriber=self._wanted.append,
            fetch_asset=served_model_assets(project_root()).read,
            log=self.get_logger().info)
        self.port = self.server.start()
        self.get_logger().info(
            f'Foxglove WebSocket on ws://{p["host"]}:{self.port} (subprotocols '
            'foxglove.websocket.v1 and foxglove.sdk.v1)')
        self._derived_channels = {
            topic: self.server.add_channel(topic, normalize_type_name(type_name),
                                           definition(type_name),
                                           latched=topic == DESCRIPTION_TOPIC)
            for topic, type_name in TYPES.items()}
        self._send(self.view.description())
        self._input = OnDemandSubscriptions(self)
        self._forwarded: dict[str, _Forwarded] = {}
        self._skipped: set[str] = set(DERIVED_TOPICS)
        self._batch: list[tuple[_Forwarded, bytes]] = []
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(p['discovery_period'], self._discover, clock=steady)
        self.create_timer(p['take_period'], self._take, clock=steady)
        self._discover()

    # ------------------------------------------------------------------ graph -> viewers

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._forwarded or topic in self._skipped:
                continue
            if any(part.startswith('_') for part in topic.split('/')):
                self._skipped.add(topic)
                continue
            publishers = [i for i in self.get_publishers_info_by_topic(topic)
                          if i.node_name != self.get_name()]
            if not publishers:
                continue
            try:
                msg_type = message_class(types[0])
                schema = message_definition(types[0])
                stamped = has_header(types[0]) or topic == '/clock'
            except (ValueError, OSError, RecursionError) as err:
                self.get_logger().warning(f'not serving {topic}: {err}')
                self._skipped.add(topic)
                continue
            profile = subscription_qos([i.qos_profile for i in publishers], topic)
            latched = profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
            channel_id = self.server.add_channel(topic, normalize_type_name(types[0]), schema,
                                                 latched=latched)
            self._forwarded[topic] = _Forwarded(topic, channel_id, stamped, latched, msg_type,
                                                profile)
        self._subscribe_wanted()

    def _subscribe_wanted(self) -> None:
        """Read over DDS the topics that viewers asked for, and the inputs of the derived
        topics once one of those is asked for."""
        derived = set(self._derived_channels.values())
        while self._wanted:
            channel_id = self._wanted.pop()
            self._wanted_ids.add(channel_id)
            self._derived_wanted |= channel_id in derived
        for entry in self._forwarded.values():
            if entry.subscribed or not (entry.channel_id in self._wanted_ids or (
                    self._derived_wanted and entry.topic in INPUT_TOPICS)):
                continue
            entry.subscribed = True
            self._input.subscribe(entry.msg_type, entry.topic, entry.profile,
                                  lambda data, e=entry: self._batch.append((e, data)), raw=True)

    def _take(self) -> None:
        if self._wanted:
            self._subscribe_wanted()
        self._input.drain()
        batch, self._batch = self._batch, []
        newest: dict[str, tuple[int, bytes]] = {}
        for entry, data in batch:
            stamp = cdr_header_stamp_ns(data) if entry.stamp_in_header else None
            if stamp is not None and not entry.latched:
                self._now_ns = max(self._now_ns, stamp)
            if entry.topic in INPUT_TOPICS:
                for item in self.view.feed(entry.topic, data):
                    self._send(item)
            stamp = self._now_ns if stamp is None else stamp
            if entry.latched or entry.topic in EVENT_TOPICS:
                self.server.send(entry.channel_id, stamp, data)
            else:
                newest[entry.topic] = (stamp, data)
        for topic, (stamp, data) in newest.items():
            self.server.send(self._forwarded[topic].channel_id, stamp, data)
        if batch:
            self.server.send_time(self._now_ns)

    def _send(self, item: Derived) -> None:
        self.server.send(self._derived_channels[item.topic], item.stamp_ns or self._now_ns,
                         item.data)

    # ------------------------------------------------------------------ viewers -> graph

    def _on_client_message(self, topic: str, encoding: str, schema_name: str,
                           payload: bytes) -> str | None:
        """Publish a viewer's Twist (server thread); the reason if it is refused."""
        publisher = self._client_pubs.get(topic)
        if publisher is None:
            return 'not a topic viewers may publish on'
        if schema_name and schema_name not in TWIST_TYPES:
            return f'expected geometry_msgs/msg/Twist, got {schema_name}'
        try:
            msg = (deserialize_message(payload, Twist) if encoding == 'cdr'
                   else twist_from_json(payload))
        except Exception as err:  # malformed payload: refused, the server goes on
            return f'malformed {encoding} Twist: {err}'
        values = (msg.linear.x, msg.linear.y, msg.linear.z,
                  msg.angular.x, msg.angular.y, msg.angular.z)
        if not all(math.isfinite(v) for v in values):
            # The gait node would reject it too; a viewer learns it here.
            return 'non-finite velocity'
        publisher.publish(msg)
        return None

    def destroy_node(self) -> None:
        self.server.stop()
        self._input.destroy()
        super().destroy_node()


def main(args=None):
    # The port taken: one line, exit code 1.
    run_node(LiveViewNode, args, one_line_errors=(OSError,), label='live_view')


if __name__ == '__main__':
    main()
