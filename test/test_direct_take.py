"""The lock-step fast path (replan_ros/transport/direct_take.py) over real DDS: samples of one
subscription taken outside the executor, in order, with their message info; it hands back when
nothing comes in time, when told to stop, at the end of its slice, and never re-enters."""

from __future__ import annotations

import threading
import time

from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from replan_ros.transport.direct_take import DirectTake

RELIABLE_50 = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)


def _stamped(k: int) -> JointState:
    msg = JointState()
    msg.header.stamp.sec = k
    return msg


def _setup(probe, topic: str):
    received: list[tuple[int, dict]] = []
    by_executor: list[int] = []
    subscription = probe.node.create_subscription(
        JointState, topic, lambda msg: by_executor.append(msg.header.stamp.sec), RELIABLE_50)

    def handler(msg, info) -> None:
        received.append((msg.header.stamp.sec, info))

    direct = DirectTake(probe.node, subscription, handler)
    publisher = probe.node.create_publisher(JointState, topic, RELIABLE_50)
    assert probe.spin_until(lambda: publisher.get_subscription_count() == 1, timeout=10)
    return direct, publisher, received, by_executor


def test_queued_samples_come_in_order_with_their_info(probe):
    direct, publisher, received, by_executor = _setup(probe, 'direct_take_order')
    for k in range(10):
        publisher.publish(_stamped(k))
    handled = direct.run(lambda: True, wait=0.2, slice_period=5.0)
    assert handled == 10
    assert [k for k, _ in received] == list(range(10))
    assert all(info['source_timestamp'] <= info['received_timestamp'] for _, info in received)
    assert by_executor == []                 # taken here, not by the executor
    assert direct.take(0.05) is None         # nothing left: None after the wait


def test_it_hands_back_when_a_sample_is_late_or_when_told(probe):
    direct, publisher, received, _ = _setup(probe, 'direct_take_stop')
    start = time.monotonic()
    assert direct.run(lambda: True, wait=0.1, slice_period=5.0) == 0
    assert 0.09 <= time.monotonic() - start < 2.0
    later = threading.Timer(0.05, lambda: publisher.publish(_stamped(1)))
    later.start()
    assert direct.take(5.0)[0].header.stamp.sec == 1     # woken by the sample, not the timeout
    later.join()
    for k in range(5):
        publisher.publish(_stamped(k))
    assert direct.run(lambda: len(received) < 3, wait=0.5, slice_period=5.0) == 3
    assert [k for k, _ in received] == [0, 1, 2]


def test_the_slice_bounds_the_run_and_a_nested_run_returns_at_once(probe):
    nested: list[int] = []
    subscription = probe.node.create_subscription(JointState, 'direct_take_slice',
                                                  lambda msg: None, RELIABLE_50)

    def handler(msg, info) -> None:          # a handler that tries to run the fast path again
        nested.append(direct.run(lambda: True, wait=0.1, slice_period=1.0))

    direct = DirectTake(probe.node, subscription, handler)
    publisher = probe.node.create_publisher(JointState, 'direct_take_slice', RELIABLE_50)
    assert probe.spin_until(lambda: publisher.get_subscription_count() == 1, timeout=10)
    publishing = threading.Event()

    def feed() -> None:
        k = 0
        while not publishing.is_set():
            publisher.publish(_stamped(k))
            k += 1
            time.sleep(0.002)

    feeder = threading.Thread(target=feed)
    feeder.start()
    try:
        start = time.monotonic()
        handled = direct.run(lambda: True, wait=0.5, slice_period=0.3)
        elapsed = time.monotonic() - start
    finally:
        publishing.set()
        feeder.join()
    assert handled > 10
    assert 0.3 <= elapsed < 1.0
    assert len(nested) == handled and set(nested) == {0}


def test_a_sample_of_a_watched_subscription_hands_back_to_the_executor(probe):
    plans: list[int] = []
    watched = probe.node.create_subscription(
        JointState, 'direct_take_watched', lambda msg: plans.append(msg.header.stamp.sec),
        RELIABLE_50)
    received: list[int] = []
    subscription = probe.node.create_subscription(JointState, 'direct_take_main',
                                                  lambda msg: None, RELIABLE_50)
    direct = DirectTake(probe.node, subscription,
                        lambda msg, info: received.append(msg.header.stamp.sec),
                        watched=(watched,))
    main = probe.node.create_publisher(JointState, 'direct_take_main', RELIABLE_50)
    plan = probe.node.create_publisher(JointState, 'direct_take_watched', RELIABLE_50)
    assert probe.spin_until(lambda: main.get_subscription_count() == 1
                            and plan.get_subscription_count() == 1, timeout=10)
    for k in range(3):
        main.publish(_stamped(k))
    time.sleep(0.2)                           # queued (the executor does not run here)
    assert direct.run(lambda: True, wait=0.2, slice_period=5.0) == 3
    plan.publish(_stamped(100))
    main.publish(_stamped(3))
    time.sleep(0.2)
    start = time.monotonic()
    assert direct.run(lambda: True, wait=2.0, slice_period=5.0) == 0   # the plan's turn
    assert time.monotonic() - start < 1.0
    assert received == [0, 1, 2] and plans == []
    assert probe.spin_until(lambda: plans == [100], timeout=5)        # the executor gets it
