"""Replay an mcap bag: publish its messages, still serialized, with their original timing.

    replay BAG [--topics T ...] [--rate R] [--loop] [--delay S] [--wait-subscribers S]
               [--no-clock]
    replay BAG --info          # print topics, types, counts, QoS and metadata, then exit

Messages go out in log-time order; message k is published at wall time
``start + (log_time_k - log_time_0) / rate``. When the bag holds ``/clock`` it is replayed too
(even if ``--topics`` does not name it, unless ``--no-clock``), so ``use_sim_time`` nodes follow
the recorded sim time. Each topic is published with the type of its schema and the first QoS
profile recorded in ``offered_qos_profiles`` (as ``ros2 bag play`` does).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import rclpy
from mcap.exceptions import McapError
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args

from replan_ros.messages.introspection import message_class
from replan_ros.recording.bag_io import check_bag, qos_from_yaml
from replan_ros.recording.bag_open import iter_raw_files, readable_files, summarize_files
from replan_ros.recording.completeness import files_completeness

CLOCK_TOPIC = '/clock'


@dataclass
class ReplayStats:
    published: dict[str, int]
    loops: int
    wall_duration: float


def replay_qos(offered: str) -> QoSProfile:
    """QoS for re-publishing a topic: the recorded offer; keep-last history (the recorded
    history is usually 'unknown': DDS does not announce it)."""
    qos = qos_from_yaml(offered)
    if qos is None:
        return QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    latched = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    qos.history = HistoryPolicy.KEEP_LAST
    qos.depth = 1 if latched else max(qos.depth, 100)
    if qos.reliability not in (ReliabilityPolicy.RELIABLE, ReliabilityPolicy.BEST_EFFORT):
        qos.reliability = ReliabilityPolicy.RELIABLE
    if qos.durability not in (DurabilityPolicy.VOLATILE, DurabilityPolicy.TRANSIENT_LOCAL):
        qos.durability = DurabilityPolicy.VOLATILE
    return qos


class ReplayNode(Node):
    """Publishers for the replayed topics of one bag."""

    def __init__(self, files: list[Path], topics: list[str] | None, with_clock: bool) -> None:
        super().__init__('replay')
        bag = ', '.join(str(f) for f in files)
        summary = summarize_files(files)
        wanted = set(topics) if topics else set(summary.topics)
        if with_clock and CLOCK_TOPIC in summary.topics:
            wanted.add(CLOCK_TOPIC)
        missing = wanted - set(summary.topics)
        for topic in sorted(missing):
            self.get_logger().warning(f'{topic} is not in {bag}')
        self.topics = sorted(wanted & set(summary.topics))
        self.publishers_by_topic = {}
        for topic in self.topics:
            info = summary.topics[topic]
            try:
                msg_type = message_class(info.type_name)
            except ValueError as err:
                # tf2_msgs is not in the installed wheels: /tf lives in bags and in the live
                # view only (docs/usage.md, "Watch the robot"); a viewer reads it from the bag.
                log = (self.get_logger().info if info.type_name.startswith('tf2_msgs/')
                       else self.get_logger().error)
                log(f'not replaying {topic}: {err}')
                continue
            self.publishers_by_topic[topic] = self.create_publisher(
                msg_type, topic, replay_qos(info.offered_qos_profiles))
        self.summary = summary


def wait_for_subscribers(node: ReplayNode, timeout: float) -> bool:
    """Wait until every publisher is matched with a subscription (at most ``timeout`` s)."""
    deadline = time.monotonic() + timeout
    while True:
        waiting = [t for t, p in node.publishers_by_topic.items()
                   if p.get_subscription_count() == 0]
        if not waiting:
            return True
        if time.monotonic() >= deadline:
            if timeout > 0:
                node.get_logger().warning(f'no subscriber yet on {waiting}: replaying anyway')
            return False
        time.sleep(0.05)


def _sleep_until(deadline: float) -> None:
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return
        time.sleep(min(remaining, 0.05))


def run_replay(node: ReplayNode, files: list[Path], rate: float, loop: bool,
               log_every: float = 5.0) -> ReplayStats:
    """Publish the bag's messages with their timing; returns how many went out per topic."""
    published = dict.fromkeys(node.publishers_by_topic, 0)
    topics = list(node.publishers_by_topic)
    loops = 0
    wall_start = time.monotonic()
    while rclpy.ok(context=node.context):
        loops += 1
        first_log: int | None = None
        start = time.monotonic()
        next_log = start + log_every
        for _schema, channel, message in iter_raw_files(files, topics):
            if not rclpy.ok(context=node.context):
                break
            if first_log is None:
                first_log = message.log_time
            _sleep_until(start + (message.log_time - first_log) * 1e-9 / rate)
            node.publishers_by_topic[channel.topic].publish(message.data)
            published[channel.topic] += 1
            if time.monotonic() >= next_log:
                next_log += log_every
                node.get_logger().info(
                    f'replayed {(message.log_time - first_log) * 1e-9:.1f} s of the bag')
        if not loop:
            break
    return ReplayStats(published, loops, time.monotonic() - wall_start)


def format_info(files: list[Path]) -> str:
    """A ``ros2 bag info``-like text of a bag's files (summary and metadata records)."""
    summary = summarize_files(files)
    duration = (summary.end_ns - summary.start_ns) * 1e-9
    lines = [f'file:       {", ".join(str(f) for f in files)}',
             f'profile:    {summary.profile}   library: {summary.library}',
             f'duration:   {duration:.3f} s   log time {summary.start_ns * 1e-9:.3f} .. '
             f'{summary.end_ns * 1e-9:.3f} s',
             f'messages:   {summary.message_count}',
             f'counted:    {files_completeness(files).gaps_text()}',
             'topics:']
    width = max((len(t) for t in summary.topics), default=0)
    for topic, info in sorted(summary.topics.items()):
        qos = qos_from_yaml(info.offered_qos_profiles)
        qos_text = (f'{qos.reliability.name.lower()}, {qos.durability.name.lower()}'
                    if qos is not None else 'no QoS recorded')
        lines.append(f'  {topic:<{width}}  {info.message_count:>8}  {info.type_name}  '
                     f'({qos_text})')
    lines.append('metadata:')
    for name, values in summary.metadata.items():
        if name == 'rosbag2':
            continue
        lines.append(f'  [{name}]')
        for key, value in values.items():
            first = value.splitlines()[0] if value else ''
            more = f' ... ({len(value.splitlines())} lines)' if '\n' in value else ''
            lines.append(f'    {key}: {first[:100]}{more}')
    return '\n'.join(lines)


def main(args=None):
    argv = remove_ros_args(args if args is not None else sys.argv)[1:]
    parser = argparse.ArgumentParser(prog='replay', description=__doc__.split('\n')[0])
    parser.add_argument('bag', help='mcap file or bag directory (its files, splits, as one)')
    parser.add_argument('--topics', nargs='+', default=None, help='only these topics')
    parser.add_argument('--rate', type=float, default=1.0, help='playback speed factor')
    parser.add_argument('--loop', action='store_true', help='start over at the end')
    parser.add_argument('--delay', type=float, default=1.0,
                        help='wall s to wait after creating the publishers (discovery)')
    parser.add_argument('--wait-subscribers', type=float, default=0.0, metavar='S',
                        help='first wait up to S wall s until every replayed topic has a '
                             'subscriber (then --delay more)')
    parser.add_argument('--no-clock', action='store_true',
                        help='do not replay /clock even if the bag has it')
    parser.add_argument('--info', action='store_true', help='print the bag summary and exit')
    opts = parser.parse_args(argv)
    try:
        # A killed recorder's file is recovered on the way, with one line saying so.
        files = readable_files(opts.bag, lambda line: print(f'[replay] {line}',
                                                            file=sys.stderr, flush=True))
        if not files:
            raise McapError('no .mcap file')
        info = format_info(files)      # also checks that the bag is readable before init
        for path in files:
            check_bag(path)            # every chunk: a corrupt one must not end in a traceback
    except (McapError, OSError) as err:
        print(f'replay: cannot read {opts.bag}: {err}', file=sys.stderr)
        return 2
    if opts.info:
        print(info)
        return 0
    if opts.rate <= 0.0:
        parser.error('--rate must be > 0')

    rclpy.init(args=args)
    node = None
    try:
        node = ReplayNode(files, opts.topics, not opts.no_clock)
        node.get_logger().info(
            f'replaying {len(node.publishers_by_topic)} topics of {opts.bag} '
            f'({(node.summary.end_ns - node.summary.start_ns) * 1e-9:.2f} s) at x{opts.rate}')
        wait_for_subscribers(node, opts.wait_subscribers)
        time.sleep(max(opts.delay, 0.0))
        stats = run_replay(node, files, opts.rate, opts.loop)
        counts = ', '.join(f'{t}: {n}' for t, n in stats.published.items())
        node.get_logger().info(
            f'done: {sum(stats.published.values())} messages in {stats.wall_duration:.2f} s '
            f'({counts})')
        # Let reliable messages still in flight reach their readers before we go.
        time.sleep(0.5)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
