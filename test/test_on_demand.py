"""On-demand subscriptions (replan_ros/transport/on_demand.py) over real DDS: samples wait in
the reader queue, the owner's executor never takes them, ``drain`` hands them over oldest first."""

from __future__ import annotations

import threading

from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from replan_ros.transport.on_demand import OnDemandSubscriptions, helper_name
from replan_ros.transport.qos import SENSOR

RELIABLE_20 = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE)


def _stamped(k: int) -> JointState:
    msg = JointState()
    msg.header.stamp.sec = k
    return msg


def _setup(probe, topic: str, qos: QoSProfile):
    received: list[int] = []
    inputs = OnDemandSubscriptions(probe.node)
    inputs.subscribe(JointState, topic, qos, lambda msg: received.append(msg.header.stamp.sec),
                     raw=False)
    publisher = probe.node.create_publisher(JointState, topic, qos)
    assert probe.spin_until(lambda: publisher.get_subscription_count() == 1, timeout=10)
    return inputs, publisher, received


def test_samples_wait_until_drained_then_come_oldest_first(probe):
    inputs, publisher, received = _setup(probe, 'on_demand_order', RELIABLE_20)
    for k in range(15):
        publisher.publish(_stamped(k))
    probe.spin_for(0.3)                          # the owner's executor runs: takes nothing
    assert received == []
    assert inputs.drain(lambda: len(received) == 15, timeout=5.0)
    assert received == list(range(15))
    inputs.drain()                               # nothing new: nothing more
    assert received == list(range(15))
    inputs.destroy()


def test_queue_keeps_the_newest_depth_samples(probe):
    inputs, publisher, received = _setup(probe, 'on_demand_depth', RELIABLE_20)
    for k in range(50):
        publisher.publish(_stamped(k))
    probe.spin_for(0.3)
    inputs.drain()
    assert received == list(range(30, 50))
    inputs.destroy()


def test_drain_waits_for_a_late_sample_up_to_its_timeout(probe):
    inputs, publisher, received = _setup(probe, 'on_demand_wait', SENSOR)
    assert not inputs.drain(lambda: 7 in received, timeout=0.2)
    late = threading.Timer(0.1, lambda: publisher.publish(_stamped(7)))
    late.start()
    assert inputs.drain(lambda: 7 in received, timeout=5.0)
    late.join()
    inputs.destroy()


def test_helper_node_is_named_after_its_owner(probe):
    inputs = OnDemandSubscriptions(probe.node)
    def names():
        return [name for name, _ in probe.node.get_node_names_and_namespaces()]
    assert probe.spin_until(lambda: helper_name(probe.node.get_name()) in names(), timeout=10), \
        names()
    inputs.destroy()
