"""The sim node's outputs of a tick: the sensors measured once per tick (`imu`, `joint_states`)
and the truth (`ground_truth/odom`, `ground_truth/contacts`), each serialized only when its topic
has a reader, published in the order the controller needs them, republished as they are, and
`/clock` (docs/sim.md; docs/ARCHITECTURE.md, "Time and lock-step")."""

from __future__ import annotations

import time

from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, PointCloud2

from replan_ros.messages.contacts import encode_contacts
from replan_ros.messages.imu import encode_imu
from replan_ros.messages.joint_state import encode_joint_state
from replan_ros.messages.odom import encode_odom
from replan_ros.messages.stamps import ns_to_stamp, sec_to_ns
from replan_ros.transport import qos
from replan_ros.transport.on_demand import helper_name


class TickOutputs:
    """Publishers and the messages of the current tick."""

    def __init__(self, node, world, imu_sensor, joint_sensor, imu_variances: tuple[float, float],
                 budget, clock_every: int) -> None:
        self.node = node
        self.world = world
        self.imu_sensor = imu_sensor
        self.joint_sensor = joint_sensor
        # Variances of one sample, for the Imu message's covariances.
        self._gyro_variance, self._accel_variance = imu_variances
        self.budget = budget
        self._clock_every = clock_every          # ticks between two /clock messages
        self._tick_messages: list = []      # the samples of the current tick, drawn once
        self._tick_sources: list = []
        # Whether the controller reads the truth (the ideal world): then the truth goes out
        # before imu/joint_states, so that it does not wait for it. Derived from the graph
        # when lock-step starts (controller_reads_truth), not configured.
        self.truth_first = False
        self.last_publish_wall = 0.0             # time.monotonic() of the last publish
        self.published_ns: int | None = None     # perf_counter_ns of a tick's joint_states
        events = qos.INTERNAL_PUB_EVENTS
        self.clock_pub = node.create_publisher(Clock, '/clock', qos.CLOCK_PUB,
                                               event_callbacks=events)
        self.truth_odom_pub = node.create_publisher(Odometry, 'ground_truth/odom',
                                                    qos.SENSOR_PUB, event_callbacks=events)
        self.truth_contacts_pub = node.create_publisher(
            PointCloud2, 'ground_truth/contacts', qos.CONTACTS_PUB, event_callbacks=events)
        self.imu_pub = node.create_publisher(Imu, 'imu', qos.SENSOR_PUB, event_callbacks=events)
        self.joint_pub = node.create_publisher(JointState, 'joint_states', qos.SENSOR_PUB,
                                               event_callbacks=events)
        self.cmd_topic = node.resolve_topic_name('joint_torque_cmd')

    def sense(self) -> None:
        """Measure the current tick's sensors once (drawn once, republished as they are)."""
        w = self.world
        t0 = time.perf_counter_ns()
        omega_body, specific_force = w.imu_truth()
        imu = self.imu_sensor.measure(w.time, omega_body, specific_force)
        joints = self.joint_sensor.measure(w.joint_state())
        t1 = time.perf_counter_ns()
        # Serialized when first published to a reader: a topic nobody reads (the truth without
        # the recorder, the imu in the ideal profile) costs nothing (volatile topics: a sample
        # published to no reader is lost anyway). The samples are drawn all the same. The
        # messages are CDR bytes written by hand (replan_ros.messages), which rclpy publishes as
        # they are.
        self._tick_sources = [
            None, None, (self.imu_pub, encode_imu,
                         (imu, self._gyro_variance, self._accel_variance))]
        self._tick_messages = [None, None, None, encode_joint_state(joints)]
        self._message(2)
        budget = self.budget
        budget.add('sim_sensing', t1 - t0)
        budget.add('sim_conversion', time.perf_counter_ns() - t1)

    def sense_truth(self, timed: bool = True) -> None:
        """The current tick's truth (read before the next period's lead physics steps)."""
        w = self.world
        t0 = time.perf_counter_ns()
        self._tick_sources[0] = (self.truth_odom_pub, encode_odom, (w.base_state(),))
        self._tick_sources[1] = (self.truth_contacts_pub, encode_contacts, (w.contact_state(),))
        t1 = time.perf_counter_ns()
        self._message(0)
        self._message(1)
        if timed:
            budget = self.budget
            budget.add('sim_truth_sensing', t1 - t0)
            budget.add('sim_truth_conversion', time.perf_counter_ns() - t1)

    def _message(self, k: int):
        """Message ``k`` (truth odom, truth contacts, imu) of the tick if ``k``'s topic has a
        reader now, built once; None otherwise."""
        message = self._tick_messages[k]
        if message is None:
            publisher, build, args = self._tick_sources[k]
            if publisher.get_subscription_count() > 0:
                message = self._tick_messages[k] = build(*args)
        return message

    def publish_state(self, with_clock: bool = False, timed: bool = False) -> None:
        """State of the current tick: first what the controller waits for (with
        ``truth_first`` the truth, then imu and joint_states: it wakes on them), then the
        truth otherwise and /clock (on its grid, clock_period, or when forced), which nobody
        waits for. ``timed``: a tick's first publish, whose phases go into the budget (a
        republish does not); it senses the truth after the controller's inputs are out, or
        before them with ``truth_first``."""
        clock = time.perf_counter_ns
        t0 = clock()
        if not timed:                 # a republish: a reader may have come meanwhile
            for k in range(3):
                self._message(k)
        elif self.truth_first:
            self.sense_truth(timed=False)
        if self.truth_first:
            self._publish_truth()
        t1 = clock()
        imu, joints = self._tick_messages[2:]
        if imu is not None:
            self.imu_pub.publish(imu)
        t2 = clock()
        self.joint_pub.publish(joints)
        t3 = clock()
        self.last_publish_wall = time.monotonic()
        odom_ns = contacts_ns = 0
        if not self.truth_first:
            if timed:
                self.sense_truth()
            odom_ns, contacts_ns = self._publish_truth()
        t4 = clock()
        if with_clock or self.world.tick % self._clock_every == 0:
            self.clock_pub.publish(Clock(clock=ns_to_stamp(sec_to_ns(self.world.time))))
        t5 = clock()
        if timed:
            add = self.budget.add
            add('sim_truth_first', t1 - t0)
            add('sim_publish_imu', t2 - t1)
            add('sim_publish_joint_states', t3 - t2)
            add('sim_publish_truth_odom', odom_ns)
            add('sim_publish_truth_contacts', contacts_ns)
            add('sim_publish_clock', t5 - t4)
            self.published_ns = t3

    def _publish_truth(self) -> tuple[int, int]:
        """Publish the truth messages that have a reader; wall ns of each publish."""
        clock = time.perf_counter_ns
        truth_odom, truth_contacts = self._tick_messages[:2]
        t0 = clock()
        if truth_odom is not None:
            self.truth_odom_pub.publish(truth_odom)
        t1 = clock()
        if truth_contacts is not None:
            self.truth_contacts_pub.publish(truth_contacts)
        return t1 - t0, clock() - t1

    def controller_reads_truth(self) -> bool:
        """True if a node that publishes joint_torque_cmd (or its on-demand helper) reads
        ground_truth/odom or ground_truth/contacts: the ideal world's controller."""
        controllers = {info.node_name for info in self.node.get_publishers_info_by_topic(
            self.cmd_topic)}
        controllers |= {helper_name(name) for name in controllers}
        return any(info.node_name in controllers
                   for pub in (self.truth_odom_pub, self.truth_contacts_pub)
                   for info in self.node.get_subscriptions_info_by_topic(pub.topic_name))
