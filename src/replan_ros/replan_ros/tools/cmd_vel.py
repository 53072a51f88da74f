"""Publish a velocity set-point on /cmd_vel, as a joystick would.

    scripts/cmd_vel.sh VX VY WZ [--for SECONDS] [--rate HZ] [--wait SECONDS]

VX, VY in m/s (body frame), WZ in rad/s. The set-point is repeated at --rate (the gait node
stops the robot when /cmd_vel falls silent for its cmd_vel_timeout). With --for it stops after
that many seconds of sim time (read from /clock; wall time if no clock is running), then sends
one zero set-point. The time counts from the moment the gait node (or, in a graph without one,
any node) subscribes: a new process is discovered by the others in 0.1-3 s, and a set-point
published before that is lost. --wait bounds that wait (wall s; then it publishes anyway).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import rclpy
from geometry_msgs.msg import Twist
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args
from rosgraph_msgs.msg import Clock

from replan_ros.messages.stamps import stamp_to_sec
from replan_ros.transport import qos


class CmdVelPublisher(Node):
    """Repeats one Twist set-point until a sim-time (or wall-time) deadline."""

    def __init__(self, twist: Twist, rate: float) -> None:
        super().__init__('cmd_vel_publisher')
        self.twist = twist
        self.sim_time: float | None = None
        self._first_reader: float | None = None    # wall s a subscriber was first seen
        self.pub = self.create_publisher(Twist, 'cmd_vel', qos.COMMAND)
        self.create_subscription(Clock, '/clock', self._on_clock,
                                 QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.create_timer(1.0 / rate, lambda: self.pub.publish(self.twist))

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = stamp_to_sec(msg.clock)

    def listener(self, settle: float = 1.0) -> str | None:
        """The node that subscribes to cmd_vel: 'gait' once it does; another subscriber once
        it has been seen for ``settle`` wall s with no gait node in the graph; else None.
        (Discovery brings an endpoint before its node's name, and nodes one by one.)"""
        readers = {info.node_name for info in self.get_subscriptions_info_by_topic(
            self.pub.topic_name)} - {'_NODE_NAME_UNKNOWN_'}
        if 'gait' in readers:
            return 'gait'
        if not readers:
            self._first_reader = None
            return None
        if self._first_reader is None:
            self._first_reader = time.monotonic()
        if time.monotonic() - self._first_reader >= settle and (
                'gait' not in self.get_node_names()):
            return sorted(readers)[0]
        return None

    def elapsed_since(self, sim_start: float | None, wall_start: float) -> float:
        if self.sim_time is not None and sim_start is not None:
            return self.sim_time - sim_start
        return time.monotonic() - wall_start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='cmd_vel.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('vx', type=float)
    parser.add_argument('vy', type=float)
    parser.add_argument('wz', type=float)
    parser.add_argument('--for', dest='duration', type=float, metavar='SECONDS')
    parser.add_argument('--rate', type=float, default=10.0)
    parser.add_argument('--wait', type=float, default=10.0, metavar='SECONDS',
                        help='wall s to wait for a subscriber before the time counts (10)')
    argv = list(sys.argv[1:] if argv is None else argv)
    # Only what follows --ros-args is rclpy's: any other unknown option is an error.
    args = parser.parse_args(remove_ros_args(['', *argv])[1:])
    if not all(math.isfinite(v) for v in (args.vx, args.vy, args.wz)):
        parser.error('VX VY WZ must be finite numbers')
    if args.rate <= 0 or (args.duration is not None and args.duration <= 0) or args.wait < 0:
        parser.error('--rate and --for must be positive, --wait not negative')
    twist = Twist()
    twist.linear.x, twist.linear.y, twist.angular.z = args.vx, args.vy, args.wz
    rclpy.init(args=[sys.argv[0], *argv])
    node = None
    try:
        node = CmdVelPublisher(twist, args.rate)
        print(f'cmd_vel: publishing vx={args.vx} m/s vy={args.vy} m/s wz={args.wz} rad/s '
              f'at {args.rate} Hz' + (f' for {args.duration} s' if args.duration else
                                      ' until Ctrl-C'))
        deadline = time.monotonic() + args.wait
        while node.listener() is None and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        listener = node.listener()
        print(f'cmd_vel: {listener} subscribes' if listener else
              f'cmd_vel: no subscriber after {args.wait} s, publishing anyway')
        wall_start = time.monotonic()
        rclpy.spin_once(node, timeout_sec=0.5)
        sim_start = node.sim_time
        while args.duration is None or node.elapsed_since(sim_start, wall_start) < args.duration:
            rclpy.spin_once(node, timeout_sec=0.1)
            if sim_start is None and node.sim_time is not None:
                sim_start = node.sim_time
        node.pub.publish(Twist())
        rclpy.spin_once(node, timeout_sec=0.2)
        print('cmd_vel: done, sent a zero set-point')
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
