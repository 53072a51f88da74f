"""Switch the gait of a running graph: publish a gait's name on /gait_command.

    scripts/gait.sh NAME [--wait SECONDS] [--timeout SECONDS]

NAME is a gait of config/gaits/. The request goes out once the gait node subscribes (up to
--wait wall s); the gait node takes it from the sim time it arrives at and switches at its next
re-plan, a step boundary (docs/gait.md, "Gait files"). This waits (up to --timeout wall s) until
/gait_in_force names the gait and says when it switched. Exit code 0 once switched, 1 if the gait
node did not subscribe or the switch was not seen, 2 for an unknown gait.
"""

from __future__ import annotations

import argparse
import sys
import time

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from std_msgs.msg import Header, String

from replan_core.gait.gait_file import gait_names
from replan_ros.messages.stamps import stamp_to_sec
from replan_ros.params.robot import config_dir
from replan_ros.transport import qos


class GaitCommand(Node):
    """Publishes one gait request and follows /gait_in_force."""

    def __init__(self) -> None:
        super().__init__('gait_command')
        self.pub = self.create_publisher(String, 'gait_command', qos.COMMAND)
        self.in_force: tuple[str, float] | None = None       # (name, sim s) of the last re-plan
        self.create_subscription(Header, 'gait_in_force', self._on_gait, qos.SCHEDULE)

    def _on_gait(self, msg: Header) -> None:
        self.in_force = (msg.frame_id, stamp_to_sec(msg.stamp))

    def gait_node_listens(self) -> bool:
        return any(info.node_name == 'gait' for info in
                   self.get_subscriptions_info_by_topic(self.pub.topic_name))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='gait.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('name', metavar='NAME', help='a gait of config/gaits/')
    parser.add_argument('--wait', type=float, default=10.0,
                        help='wall s to wait for the gait node to subscribe (default 10)')
    parser.add_argument('--timeout', type=float, default=30.0,
                        help='wall s to wait for the switch on /gait_in_force (default 30)')
    args = parser.parse_args(remove_ros_args(sys.argv if argv is None else argv)[1:])
    known = gait_names(config_dir())
    if args.name not in known:
        print(f'gait.sh: unknown gait {args.name!r}; gaits: {", ".join(known)}', file=sys.stderr)
        return 2
    rclpy.init()
    node = GaitCommand()
    try:
        deadline = time.monotonic() + args.wait
        while not node.gait_node_listens():
            if time.monotonic() > deadline:
                print(f'gait.sh: no gait node subscribed to /gait_command in {args.wait} s',
                      file=sys.stderr)
                return 1
            rclpy.spin_once(node, timeout_sec=0.1)
        node.pub.publish(String(data=args.name))
        node.pub.wait_for_all_acked(Duration(seconds=2.0))
        print(f'gait.sh: requested {args.name}; it takes effect at the next step boundary')
        deadline = time.monotonic() + args.timeout
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
            if node.in_force is not None and node.in_force[0] == args.name:
                print(f'gait.sh: walking {args.name} since the re-plan at '
                      f't={node.in_force[1]:.3f} s (sim)')
                return 0
        print(f'gait.sh: {args.name} not in force after {args.timeout} s '
              f'(last re-plan: {node.in_force})', file=sys.stderr)
        return 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
