"""`ros2 topic` for this install (the PyPI wheels have no ros2 CLI): list, echo, info, hz.

    scripts/topic.sh list [-t] [--include-hidden-topics] [--wait S]
    scripts/topic.sh echo TOPIC [--once] [--count N] [--field a.b] [--no-arr]
                     [--truncate-length N] [--timeout S] [--wait S]
    scripts/topic.sh info TOPIC [-v] [--wait S]
    scripts/topic.sh hz TOPIC [--window N] [--duration S] [--wait S]
    scripts/topic.sh nodes [-a] [--wait S]          (ros2 node list)
    scripts/topic.sh talk TOPIC [--rate HZ]         (publishes std_msgs/String, for graph checks)

No daemon caches the graph: list, info and nodes first listen to DDS discovery for --wait
seconds (default 4.5: a node can take one Fast DDS announcement period, 3 s, to appear, and
longer under load; while no other node has been discovered, up to 6 s more); echo and hz
wait up to --wait seconds for a publisher. They subscribe with a QoS that matches every publisher:
transient local when all publishers are (so latched plans and schedules are received), best
effort when any publisher is. Messages are printed as YAML, like ros2 topic echo. Arguments
after --ros-args go to rclpy (e.g. --ros-args -r __node:=my_name).
"""

from __future__ import annotations

import argparse
import array
import itertools
import math
import os
import statistics
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np
import rclpy
import yaml
from rclpy.duration import Duration, Infinite
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.topic_endpoint_info import TopicEndpointInfo
from rclpy.utilities import remove_ros_args
from std_msgs.msg import String

from replan_ros.messages.introspection import message_class

# Discovered endpoints carry no history depth (DDS does not announce it), so a transient-local
# subscription takes a generous queue: a late joiner then gets every sample a publisher keeps
# (the input schedules keep 100).
_LATCHED_DEPTH = 1000
_DEFAULT_DEPTH = 10


def subscription_qos(publishers: Sequence[QoSProfile]) -> QoSProfile:
    """A subscription QoS compatible with every publisher in ``publishers``.

    Reliable unless a publisher is best effort (a reliable reader does not match a best-effort
    writer); transient local only if all publishers are (else volatile, which matches any).
    """
    best_effort = any(p.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers)
    latched = bool(publishers) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=_LATCHED_DEPTH if latched else _DEFAULT_DEPTH,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def to_plain(value: object, truncate_length: int | None = 128, no_arr: bool = False,
             no_str: bool = False) -> object:
    """A message as nested dicts, lists and scalars (field order kept), ready for YAML.

    Sequences and strings longer than ``truncate_length`` are cut and end with '...', as in
    ros2 topic echo.
    """
    if hasattr(value, 'get_fields_and_field_types'):
        return {name: to_plain(getattr(value, name), truncate_length, no_arr, no_str)
                for name in value.get_fields_and_field_types()}
    if isinstance(value, (list, tuple, array.array, np.ndarray)):
        if no_arr:
            return f'<sequence, length: {len(value)}>'
        items = list(value)
        cut = truncate_length is not None and len(items) > truncate_length
        plain = [to_plain(v, truncate_length, no_arr, no_str)
                 for v in (items[:truncate_length] if cut else items)]
        return [*plain, '...'] if cut else plain
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, bytes):
        # rclpy gives `byte` fields as length-1 bytes; show the number.
        return value[0] if len(value) == 1 else list(value)
    if isinstance(value, str):
        if no_str:
            return '<string>'
        if truncate_length is not None and len(value) > truncate_length:
            return value[:truncate_length] + '...'
    return value


def to_yaml(value: object) -> str:
    """YAML text of a plain value (block style); scalars as their bare text."""
    if isinstance(value, (dict, list)):
        return yaml.safe_dump(value, default_flow_style=False, sort_keys=False,
                              allow_unicode=True, width=10**9).rstrip('\n')
    return str(value)


def field_path(msg_type: type, path: str) -> list[str]:
    """``a.b`` split and checked against the message type; ValueError names the bad part."""
    parts = path.split('.')
    value = msg_type()
    for i, part in enumerate(parts):
        fields = getattr(value, 'get_fields_and_field_types', dict)()
        if part not in fields:
            where = '.'.join(parts[:i]) or type(value).__name__
            known = ', '.join(fields) or 'none: not a message'
            raise ValueError(f'no field {part!r} in {where} (fields: {known})')
        value = getattr(value, part)
    return parts


def pick(msg: object, parts: list[str]) -> object:
    for part in parts:
        msg = getattr(msg, part)
    return msg


def period_stats(stamps: Sequence[float]) -> tuple[float, float, float, float] | None:
    """(rate Hz, min, max, std dev of the period in s) of arrival times; None below two."""
    if len(stamps) < 2:
        return None
    periods = [b - a for a, b in itertools.pairwise(stamps)]
    mean = statistics.fmean(periods)
    rate = 1.0 / mean if mean > 0 else math.inf
    return rate, min(periods), max(periods), statistics.pstdev(periods)


def format_duration(duration: Duration) -> str:
    if duration == Infinite or duration.nanoseconds <= 0:
        return 'Infinite'
    return f'{duration.nanoseconds} nanoseconds'


def format_endpoint(info: TopicEndpointInfo) -> str:
    """One endpoint as ros2 topic info -v shows it."""
    qos = info.qos_profile
    history = qos.history.name
    if qos.history == HistoryPolicy.KEEP_LAST and qos.depth:
        history += f' ({qos.depth})'
    gid = '.'.join(f'{b:02x}' for b in info.endpoint_gid)
    return '\n'.join([
        f'Node name: {info.node_name}',
        f'Node namespace: {info.node_namespace}',
        f'Topic type: {info.topic_type}',
        f'Endpoint type: {info.endpoint_type.name}',
        f'GID: {gid}',
        'QoS profile:',
        f'  Reliability: {qos.reliability.name}',
        f'  History (Depth): {history}',
        f'  Durability: {qos.durability.name}',
        f'  Lifespan: {format_duration(qos.lifespan)}',
        f'  Deadline: {format_duration(qos.deadline)}',
        f'  Liveliness: {qos.liveliness.name}',
        f'  Liveliness lease duration: {format_duration(qos.liveliness_lease_duration)}',
    ])


def _full_name(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic


def _is_hidden(name: str) -> bool:
    return any(part.startswith('_') for part in name.split('/'))


# s: Fast DDS's participant announcement period (its default, which rmw_fastrtps keeps). A
# participant that missed this tool's first announcements (or whose answer came before the tool
# listened) is heard at its next periodic one: measured beside a running sim with 5 busy
# processes, 7 of 10 fresh participants saw it at once, 3 after 2.0-2.8 s (bimodal).
_ANNOUNCEMENT_PERIOD = 3.0
# s: how late that announcement may come under load, on top of the period.
_ANNOUNCEMENT_MARGIN = 1.5
DISCOVERY_WAIT = _ANNOUNCEMENT_PERIOD + _ANNOUNCEMENT_MARGIN    # s, --wait's default
# s: listening on while nothing but this tool's own node is discovered (two periods).
_LONELY_EXTRA = 6.0


class TopicTool:
    """The commands, on one rclpy node that only discovers and subscribes."""

    def __init__(self, node: Node) -> None:
        self.node = node

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=min(0.05, max(end - time.monotonic(), 0.0)))

    def settle(self, snapshot: Callable[[], object], wait: float,
               done: Callable[[], bool] = lambda: True, quiet: float = 0.5,
               extra: float = 2.0) -> None:
        """Listen to discovery for ``wait`` s (by default one announcement period plus a
        margin: DISCOVERY_WAIT), then until ``done()`` and no change for ``quiet`` s.

        Without a daemon caching the graph, listening is the only way to learn it, and a
        participant can take up to one announcement period (3 s in Fast DDS; 2.8 s measured
        here) to be discovered, later under load: with the 3 s of ``wait`` alone, a running
        sim was missed in a suite run beside two test runs (test_topic_tool.py; the list held
        the test probe's topics only, so the tool was not alone). Gives up ``extra`` s after
        that, or, while no node but this one has been discovered, two more announcement
        periods after that: an empty answer looks like an empty graph.
        """
        start = time.monotonic()
        last, changed = snapshot(), start
        while True:
            elapsed = time.monotonic() - start
            alone = len(self.node.get_node_names_and_namespaces()) <= 1
            if elapsed >= wait + extra + (_LONELY_EXTRA if alone else 0.0):
                return
            self.spin(0.1)
            now = snapshot()
            if now != last:
                last, changed = now, time.monotonic()
            elif (time.monotonic() - start >= wait and time.monotonic() - changed >= quiet
                  and done() and not alone):
                return

    def wait_for_publishers(self, topic: str, wait: float) -> list[TopicEndpointInfo]:
        start = time.monotonic()
        warned = False
        while True:
            publishers = self.node.get_publishers_info_by_topic(topic)
            if publishers:
                # Other publishers of the same topic are usually discovered together; a short
                # listen keeps the QoS choice from resting on the first one alone.
                self.spin(0.2)
                return self.node.get_publishers_info_by_topic(topic)
            if time.monotonic() - start >= wait:
                return []
            if not warned and time.monotonic() - start > 1.0:
                print(f'waiting for a publisher of {topic} ...', file=sys.stderr)
                warned = True
            self.spin(0.1)

    def list(self, args: argparse.Namespace) -> int:
        self.settle(self.node.get_topic_names_and_types, args.wait)
        for name, types in sorted(self.node.get_topic_names_and_types()):
            if _is_hidden(name) and not args.include_hidden_topics:
                continue
            print(f'{name} [{", ".join(types)}]' if args.show_types else name)
        return 0

    def nodes(self, args: argparse.Namespace) -> int:
        self.settle(self.node.get_node_names_and_namespaces, args.wait)
        names = sorted({(ns.rstrip('/') + '/' + name) for name, ns
                        in self.node.get_node_names_and_namespaces()})
        for name in names:
            if args.all or not _is_hidden(name):
                print(name)
        return 0

    def info(self, args: argparse.Namespace) -> int:
        topic = _full_name(args.topic)

        def endpoints() -> tuple:
            return (tuple(sorted(str(e.endpoint_gid) + e.node_name
                                 for e in self.node.get_publishers_info_by_topic(topic))),
                    tuple(sorted(str(e.endpoint_gid) + e.node_name
                                 for e in self.node.get_subscriptions_info_by_topic(topic))))

        def named() -> bool:
            # Node names come with a separate discovery message and may lag the endpoints.
            everyone = (self.node.get_publishers_info_by_topic(topic)
                        + self.node.get_subscriptions_info_by_topic(topic))
            return bool(everyone) and all(
                e.node_name != '_NODE_NAME_UNKNOWN_' for e in everyone)

        self.settle(endpoints, args.wait, done=named)
        types = dict(self.node.get_topic_names_and_types()).get(topic)
        if not types:
            print(f"Unknown topic '{topic}'", file=sys.stderr)
            return 1
        publishers = self.node.get_publishers_info_by_topic(topic)
        subscriptions = self.node.get_subscriptions_info_by_topic(topic)
        print(f'Type: {", ".join(types)}')
        if args.verbose:
            print()
        print(f'Publisher count: {len(publishers)}')
        if args.verbose:
            print()
            for endpoint in publishers:
                print(format_endpoint(endpoint) + '\n')
        print(f'Subscription count: {len(subscriptions)}')
        if args.verbose:
            print()
            for endpoint in subscriptions:
                print(format_endpoint(endpoint) + '\n')
        return 0

    def _subscribe(self, topic: str, wait: float, callback: Callable[[object], None],
                   raw: bool = False) -> type | None:
        publishers = self.wait_for_publishers(topic, wait)
        if not publishers:
            print(f'no publisher of {topic} within {wait} s (is the graph running, on the '
                  f'same ROS_DOMAIN_ID {os.environ.get("ROS_DOMAIN_ID", "0")}?)',
                  file=sys.stderr)
            return None
        types = sorted({p.topic_type for p in publishers})
        if len(types) > 1:
            print(f'{topic} is published with several types {types}; using {types[0]}',
                  file=sys.stderr)
        msg_type = message_class(types[0])
        self.node.create_subscription(msg_type, topic, callback,
                                      subscription_qos([p.qos_profile for p in publishers]),
                                      raw=raw)
        return msg_type

    def echo(self, args: argparse.Namespace) -> int:
        topic = _full_name(args.topic)
        count = 1 if args.once else args.count
        received: deque = deque()
        msg_type = self._subscribe(topic, args.wait, lambda msg: received.append(msg))
        if msg_type is None:
            return 1
        try:
            parts = field_path(msg_type, args.field) if args.field else []
        except ValueError as err:
            print(f'echo: --field {args.field}: {err}', file=sys.stderr)
            return 2
        end = None if args.timeout is None else time.monotonic() + args.timeout
        shown = 0
        while count is None or shown < count:
            if end is not None and time.monotonic() >= end:
                break
            rclpy.spin_once(self.node, timeout_sec=0.1)
            while received and (count is None or shown < count):
                value = pick(received.popleft(), parts)
                plain = to_plain(value, args.truncate_length, args.no_arr, args.no_str)
                print(to_yaml(plain))
                print('---', flush=True)
                shown += 1
        return 0 if shown else 1

    def hz(self, args: argparse.Namespace) -> int:
        topic = _full_name(args.topic)
        stamps: deque[float] = deque(maxlen=args.window + 1)
        # Raw: the arrival time is all that counts, deserialising would only slow us down.
        if self._subscribe(topic, args.wait, lambda _: stamps.append(time.monotonic()),
                           raw=True) is None:
            return 1
        start = time.monotonic()
        next_report, last_seen = start + 1.0, None
        while True:
            finished = args.duration is not None and time.monotonic() - start >= args.duration
            if not finished:
                rclpy.spin_once(self.node, timeout_sec=0.05)
                if time.monotonic() < next_report:
                    continue
                next_report += 1.0
            newest = stamps[-1] if stamps else None
            stats = period_stats(stamps)
            if stats is not None and newest != last_seen:
                last_seen = newest
                rate, shortest, longest, std = stats
                print(f'average rate: {rate:.3f}\n'
                      f'\tmin: {shortest:.3f}s max: {longest:.3f}s std dev: {std:.5f}s '
                      f'window: {len(stamps)}', flush=True)
            elif not finished:
                print('no new messages', flush=True)
            if finished:
                return 0 if stats is not None else 1

    def talk(self, args: argparse.Namespace) -> int:
        pub = self.node.create_publisher(String, args.topic, 10)
        count = 0
        while rclpy.ok():
            pub.publish(String(data=f'{self.node.get_name()} {count}'))
            count += 1
            rclpy.spin_once(self.node, timeout_sec=1.0 / args.rate)
        return 0


def _positive(kind: type) -> Callable[[str], float]:
    def parse(text: str):
        value = kind(text)
        if not value > 0:
            raise argparse.ArgumentTypeError(f'must be positive: {text}')
        return value
    return parse


def build_parser(prog: str = 'topic.sh') -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')
    wait_help = (f'wall s of listening to discovery first (default {DISCOVERY_WAIT:g}: one '
                 'DDS announcement period and a margin)')

    p = sub.add_parser('list', help='topics (ros2 topic list)')
    p.add_argument('-t', '--show-types', action='store_true', help='also the types')
    p.add_argument('--include-hidden-topics', action='store_true')
    p.add_argument('--wait', type=_positive(float), default=DISCOVERY_WAIT, help=wait_help)

    p = sub.add_parser('echo', help='print messages as YAML (ros2 topic echo)')
    p.add_argument('topic')
    p.add_argument('--once', action='store_true', help='one message, then exit')
    p.add_argument('--count', type=_positive(int), help='this many messages, then exit')
    p.add_argument('--field', metavar='a.b', help='only this field of each message')
    p.add_argument('--no-arr', action='store_true', help='show sequences as their length')
    p.add_argument('--no-str', action='store_true', help='hide strings')
    p.add_argument('--truncate-length', type=_positive(int), default=128, metavar='N',
                   help='cut sequences and strings longer than N (default 128)')
    p.add_argument('--timeout', type=_positive(float), metavar='S',
                   help='give up after S wall s (exit 1 if nothing came)')
    p.add_argument('--wait', type=_positive(float), default=10.0,
                   help='wall s to wait for a publisher (default 10)')

    p = sub.add_parser('info', help='type, endpoints and their QoS (ros2 topic info)')
    p.add_argument('topic')
    p.add_argument('-v', '--verbose', action='store_true', help='each endpoint with its QoS')
    p.add_argument('--wait', type=_positive(float), default=DISCOVERY_WAIT, help=wait_help)

    p = sub.add_parser('hz', help='publishing rate (ros2 topic hz)')
    p.add_argument('topic')
    p.add_argument('--window', '-w', type=_positive(int), default=10000, metavar='N',
                   help='messages in the rolling window (default 10000)')
    p.add_argument('--duration', type=_positive(float), metavar='S',
                   help='stop after S wall s (default: until Ctrl-C)')
    p.add_argument('--wait', type=_positive(float), default=10.0,
                   help='wall s to wait for a publisher (default 10)')

    p = sub.add_parser('nodes', help='node names (ros2 node list)')
    p.add_argument('-a', '--all', action='store_true', help='also hidden nodes')
    p.add_argument('--wait', type=_positive(float), default=DISCOVERY_WAIT, help=wait_help)

    p = sub.add_parser('talk', help='publish std_msgs/String (graph checks)')
    p.add_argument('topic')
    p.add_argument('--rate', type=_positive(float), default=10.0)
    return parser


def main(argv: Sequence[str] | None = None, prog: str = 'topic.sh') -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # Options after --ros-args belong to rclpy; anything else unknown is an error.
    args = build_parser(prog).parse_args(remove_ros_args([prog, *argv])[1:])
    rclpy.init(args=[prog, *argv])
    node = None
    try:
        # A hidden name (leading underscore), unique per process, as the ros2 CLI's own node.
        node = Node(f'_topic_tool_{os.getpid()}', enable_rosout=False,
                    start_parameter_services=False)
        return getattr(TopicTool(node), args.command)(args)
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
