"""Push the robot: an external force on the trunk for a given duration of sim time.

    scripts/push.sh FX FY FZ --duration S [--torque MX MY MZ] [--delay S]

Forces in N, torques in N m, world (odom) axes, applied at the base origin. Reads the current
sim time from /clock (or, while the sim waits for a controller, from the republished odom
stamp), then publishes on external_wrench the wrench stamped at that time (+ --delay) and a zero
wrench stamped --duration later. The sim applies each one at the exact tick of its stamp.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import rclpy
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from rosgraph_msgs.msg import Clock

from replan_core.common.types import WORLD_FRAME
from replan_ros.messages.stamps import sec_to_ns, stamp_to_ns
from replan_ros.messages.wrench import wrench_to_msg
from replan_ros.transport import qos


class PushPublisher(Node):
    """Learns the sim time, then sends the start and end wrenches of one push."""

    def __init__(self) -> None:
        super().__init__('push')
        self.sim_ns: int | None = None
        self.pub = self.create_publisher(WrenchStamped, 'external_wrench', qos.SCHEDULE)
        self.create_subscription(Clock, '/clock', self._on_clock, qos.CLOCK)
        self.create_subscription(Odometry, 'odom', self._on_odom, qos.SENSOR)

    def _on_clock(self, msg: Clock) -> None:
        self.sim_ns = max(self.sim_ns or 0, stamp_to_ns(msg.clock))

    def _on_odom(self, msg: Odometry) -> None:
        self.sim_ns = max(self.sim_ns or 0, stamp_to_ns(msg.header.stamp))

    def wrench(self, stamp_ns: int, force, torque) -> WrenchStamped:
        return wrench_to_msg(stamp_ns, force, torque)


def _spin_until(node: Node, predicate, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not predicate():
        rclpy.spin_once(node, timeout_sec=0.05)
    return predicate()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='push.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('fx', type=float, help='N, world x')
    parser.add_argument('fy', type=float, help='N, world y')
    parser.add_argument('fz', type=float, help='N, world z')
    parser.add_argument('--duration', type=float, required=True, metavar='S',
                        help='sim seconds the force lasts')
    parser.add_argument('--torque', type=float, nargs=3, default=(0.0, 0.0, 0.0),
                        metavar=('MX', 'MY', 'MZ'), help='N m, world axes (default 0)')
    parser.add_argument('--delay', type=float, default=0.0, metavar='S',
                        help='start this many sim seconds after the current time (default 0)')
    parser.add_argument('--timeout', type=float, default=5.0, metavar='S',
                        help='wall seconds to wait for the sim (default 5)')
    argv = list(sys.argv[1:] if argv is None else argv)
    # Only what follows --ros-args is rclpy's: any other unknown option is an error.
    args = parser.parse_args(remove_ros_args(['', *argv])[1:])
    force = (args.fx, args.fy, args.fz)
    if not all(math.isfinite(v) for v in (*force, *args.torque)):
        parser.error('FX FY FZ and --torque must be finite numbers')
    if not (args.duration > 0 and math.isfinite(args.duration)) or args.delay < 0:
        parser.error('--duration must be positive and --delay not negative')

    rclpy.init(args=[sys.argv[0], *argv])
    node = None
    try:
        node = PushPublisher()
        if not _spin_until(node, lambda: node.sim_ns is not None, args.timeout):
            print(f'push: no /clock or odom within {args.timeout} s: is the sim running?',
                  file=sys.stderr)
            return 1
        if not _spin_until(node, lambda: node.pub.get_subscription_count() > 0, args.timeout):
            print('push: nobody subscribes external_wrench', file=sys.stderr)
            return 1
        start_ns = node.sim_ns + sec_to_ns(args.delay)
        end_ns = start_ns + sec_to_ns(args.duration)
        node.pub.publish(node.wrench(start_ns, force, args.torque))
        node.pub.publish(node.wrench(end_ns, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
        acked = node.pub.wait_for_all_acked(Duration(seconds=args.timeout))
        print(f'push: F = ({args.fx:g}, {args.fy:g}, {args.fz:g}) N, '
              f'M = ({args.torque[0]:g}, {args.torque[1]:g}, {args.torque[2]:g}) N m '
              f'in {WORLD_FRAME} from t = {start_ns * 1e-9:.3f} s to t = {end_ns * 1e-9:.3f} s '
              f'(sim time), then zero' + ('' if acked else ' [not acknowledged by the sim]'))
        return 0 if acked else 1
    except KeyboardInterrupt:
        return 130
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
