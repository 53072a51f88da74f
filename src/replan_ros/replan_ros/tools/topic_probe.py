"""A small stand-in for `ros2 topic` (not in the PyPI wheels): list, echo, hz, talk.

    topic_probe list [--wait S]
    topic_probe echo TOPIC [--count N] [--timeout S]
    topic_probe hz TOPIC [--window S]
    topic_probe talk TOPIC [--rate HZ]          (std_msgs/String, for graph checks)
"""

import argparse
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from replan_ros.introspection import message_class


def _wait_for_type(node: Node, topic: str, timeout: float) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for name, types in node.get_topic_names_and_types():
            if name == topic and types:
                return types[0]
        rclpy.spin_once(node, timeout_sec=0.1)
    raise SystemExit(f'topic_probe: no publisher of {topic} within {timeout} s')


def _best_effort() -> QoSProfile:
    # Best effort receives from reliable and best-effort publishers alike.
    return QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)


def run(node: Node, args: argparse.Namespace) -> int:
    if args.command == 'list':
        end = time.monotonic() + args.wait
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
        for name, types in sorted(node.get_topic_names_and_types()):
            print(f'{name} [{", ".join(types)}]')
        return 0
    if args.command == 'talk':
        pub = node.create_publisher(String, args.topic, 10)
        count = 0
        while rclpy.ok():
            pub.publish(String(data=f'{node.get_name()} {count}'))
            count += 1
            rclpy.spin_once(node, timeout_sec=1.0 / args.rate)
        return 0
    topic = args.topic if args.topic.startswith('/') else '/' + args.topic
    msg_type = message_class(_wait_for_type(node, topic, args.timeout))
    received = []
    node.create_subscription(msg_type, topic, lambda m: received.append((time.monotonic(), m)),
                             _best_effort())
    if args.command == 'echo':
        end = time.monotonic() + args.timeout
        shown = 0
        while shown < args.count and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
            while received and shown < args.count:
                print(received.pop(0)[1])
                print('---')
                shown += 1
        return 0 if shown else 1
    # hz
    end = time.monotonic() + args.window
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    if len(received) < 2:
        print(f'{topic}: {len(received)} messages in {args.window} s')
        return 1
    span = received[-1][0] - received[0][0]
    print(f'{topic}: {(len(received) - 1) / span:.1f} Hz over {len(received)} messages')
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='topic_probe', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)
    p_list = sub.add_parser('list')
    p_list.add_argument('--wait', type=float, default=1.0)
    p_echo = sub.add_parser('echo')
    p_echo.add_argument('topic')
    p_echo.add_argument('--count', type=int, default=1)
    p_echo.add_argument('--timeout', type=float, default=10.0)
    p_hz = sub.add_parser('hz')
    p_hz.add_argument('topic')
    p_hz.add_argument('--window', type=float, default=3.0)
    p_hz.add_argument('--timeout', type=float, default=10.0)
    p_talk = sub.add_parser('talk')
    p_talk.add_argument('topic')
    p_talk.add_argument('--rate', type=float, default=10.0)
    args, ros_args = parser.parse_known_args(argv if argv is not None else sys.argv[1:])
    rclpy.init(args=[sys.argv[0], *ros_args])
    node = None
    try:
        node = Node('topic_probe')
        return run(node, args)
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
