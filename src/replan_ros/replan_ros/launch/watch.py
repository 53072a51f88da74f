"""The launcher's own ROS node: ``ClockWatch`` follows the sim clock (and, for the progress
line, the re-plans and the distance walked); ``ScheduledInputs`` publishes a run's timed inputs
before sim time moves."""

from __future__ import annotations

import math
import time

import rclpy
from geometry_msgs.msg import TwistStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import Header

from replan_ros.transport import qos
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns


class ScheduledInputs:
    """Timed inputs sent before sim time moves: stamped set-points and gait requests for the
    gait node and external wrenches for the sim, on the transient-local schedule topics
    (qos.SCHEDULE)."""

    def __init__(self, setpoints: list[TwistStamped], wrenches: list[WrenchStamped],
                 gaits: list[Header] = ()) -> None:
        self.setpoints = list(setpoints)
        self.wrenches = list(wrenches)
        self.gaits = list(gaits)

    @property
    def count(self) -> int:
        return len(self.setpoints) + len(self.wrenches) + len(self.gaits)

    def publish(self, node: Node) -> list:
        """Publish them all from ``node``; returns the (publisher, topic, consumer node)
        deliveries for ``run_graph`` to wait on before the sim may advance."""
        deliveries = []
        for msg_type, topic, consumer, messages in (
                (TwistStamped, '/cmd_vel_stamped', 'gait', self.setpoints),
                (Header, '/gait_command_stamped', 'gait', self.gaits),
                (WrenchStamped, '/external_wrench', 'sim', self.wrenches)):
            if not messages:
                continue
            publisher = node.create_publisher(msg_type, topic, qos.SCHEDULE)
            for msg in messages:
                publisher.publish(msg)
            deliveries.append((publisher, topic, consumer))
        return deliveries


# The odometry the progress line reads: the newest sample is all it needs, and a best-effort
# reader of the sim's reliable writer never makes the writer wait (qos.SENSOR_PUB).
PROGRESS_ODOM_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                               reliability=ReliabilityPolicy.BEST_EFFORT,
                               durability=DurabilityPolicy.VOLATILE)
# The controller's commands, read for their stamps only when the run ends: reliable, so the
# one command of the stop tick is not dropped; depth 1, so the wbc's writer never waits on it.
END_COMMAND_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)


class ClockWatch:
    """Follows /clock from the launcher's own process, to stop after a sim-time duration.

    With ``follow_run`` it also counts the re-plans (distinct /footholds stamps) and follows
    the base position for the progress line: ``/ground_truth/odom`` if ``truth``, else
    ``/odom`` (the estimate). The odometry (a sample per tick) is read on demand
    (``on_demand``) once per ``spin``, so it never wakes the launcher in between."""

    def __init__(self, env: dict[str, str], *, follow_run: bool = False,
                 truth: bool = True, commands: bool = False) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=int(env.get('ROS_DOMAIN_ID', '0')))
        self.node = Node('launch_clock_watch', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim_time = 0.0
        self.clock_ns = 0
        self.command_ns = -1             # stamp of the newest controller command seen
        self._commands: OnDemandSubscriptions | None = None
        if commands:
            self._commands = OnDemandSubscriptions(self.node)
            self._commands.subscribe(JointState, '/joint_torque_cmd', END_COMMAND_QOS,
                                     self._on_command)
        # Reliable: the held tick's /clock, which ends the run, is sent once (the sim no longer
        # republishes a held tick that was answered), so it must not be lost.
        self.node.create_subscription(Clock, '/clock', self._on_clock, qos.CLOCK)
        self.plan_stamps: set[tuple[int, int]] = set()
        self.start_position: tuple[float, float] | None = None
        self.position: tuple[float, float] | None = None
        self.odom_topic = '/ground_truth/odom' if truth else '/odom'
        self._odom: OnDemandSubscriptions | None = None
        if follow_run:
            # Same profile as the writer (reliable, transient local, depth 1): a late start
            # still gets the newest plan, and a reliable KEEP_LAST reader never blocks it.
            self.node.create_subscription(PointCloud2, '/footholds', self._on_footholds,
                                          qos.LATCHED, event_callbacks=qos.INTERNAL_SUB_EVENTS)
            self._odom = OnDemandSubscriptions(self.node)
            self._odom.subscribe(Odometry, self.odom_topic, PROGRESS_ODOM_QOS, self._on_odom,
                                 raw=False)

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.sec + msg.clock.nanosec * 1e-9
        self.clock_ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec

    def _on_command(self, data: bytes) -> None:
        self.command_ns = max(self.command_ns, cdr_header_stamp_ns(data) or -1)

    def wait_for_command(self, stamp_ns: int, timeout: float) -> bool:
        """Wait up to ``timeout`` wall s for the controller's command stamped ``stamp_ns`` (or
        later); True once it was published. Without ``commands`` there is nothing to wait for."""
        if self._commands is None:
            return True
        return self._commands.drain(lambda: self.command_ns >= stamp_ns, timeout)

    def _on_footholds(self, msg: PointCloud2) -> None:
        # A respawned gait node may send a plan again: a re-plan is a new stamp.
        self.plan_stamps.add((msg.header.stamp.sec, msg.header.stamp.nanosec))

    def _on_odom(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        self.position = (p.x, p.y)
        if self.start_position is None:
            self.start_position = self.position

    @property
    def replans(self) -> int:
        return len(self.plan_stamps)

    def distance(self) -> float | None:
        """Straight-line distance (m, in the plane) of the base from its first position."""
        if self.position is None or self.start_position is None:
            return None
        return math.hypot(self.position[0] - self.start_position[0],
                          self.position[1] - self.start_position[1])

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=max(end - time.monotonic(), 0.0))
        if self._odom is not None:
            # The newest sample only (depth 1); taken at each look from the start on, so the
            # first one is the pose the robot started from.
            self._odom.drain()

    def close(self) -> None:
        if self._odom is not None:
            self._odom.destroy()
        if self._commands is not None:
            self._commands.destroy()
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
