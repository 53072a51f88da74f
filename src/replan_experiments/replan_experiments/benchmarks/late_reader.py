"""How many of a plan writer's kept plans a late graph reader takes (docs/recording.md, "No
loss"): a writer that keeps ``qos.PLAN_HISTORY`` (``LATCHED_PUB``) publishes 10 plans, then a
``LATCHED`` reader (depth 1, as the graph's) and a reader that keeps all (``recorder_qos``, as
a respawned recorder) join. A reader's depth drops only the samples it has not taken yet, and
the executor takes each as it comes, so under load the depth-1 reader can take older plans
before the newest. Per trial: how many plans it took, and whether they came in order and
ended on the newest (what the controller relies on: it keeps plans by stamp).

    python -m replan_experiments.benchmarks.late_reader [--trials N] [--load N]

``--load N``: N busy processes beside it (the 2-core machine under a CI run's load). Prints
one JSON line.
"""

from __future__ import annotations

import argparse
import collections
import json
import multiprocessing
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_ros.transport.qos import LATCHED, LATCHED_PUB, recorder_qos

PLANS = 10


def _busy() -> None:
    while True:
        pass


def _trial(node, executor, k: int) -> list[int]:
    """The plan numbers (1..PLANS) the depth-1 late reader of trial ``k`` took."""
    topic = f'/late_reader_bench/plan_{k}'
    publisher = node.create_publisher(MultiDOFJointTrajectory, topic, LATCHED_PUB)
    for number in range(1, PLANS + 1):
        msg = MultiDOFJointTrajectory()
        msg.header.stamp.sec = number
        publisher.publish(msg)
    newest: list[int] = []
    every: list[int] = []
    readers = [node.create_subscription(MultiDOFJointTrajectory, topic,
                                        lambda m: newest.append(m.header.stamp.sec), LATCHED),
               node.create_subscription(MultiDOFJointTrajectory, topic,
                                        lambda m: every.append(m.header.stamp.sec),
                                        recorder_qos([LATCHED_PUB])[0])]
    end = time.monotonic() + 5.0
    while len(every) < PLANS and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
    for _ in range(5):                      # anything more that would come
        executor.spin_once(timeout_sec=0.05)
    for reader in readers:
        node.destroy_subscription(reader)
    node.destroy_publisher(publisher)
    if every != list(range(1, PLANS + 1)):
        raise RuntimeError(f'trial {k}: the reader that keeps all got {every}')
    return newest


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--trials', type=int, default=60)
    parser.add_argument('--load', type=int, default=0, help='busy processes beside it')
    args = parser.parse_args(argv)
    load = [multiprocessing.Process(target=_busy, daemon=True) for _ in range(args.load)]
    for process in load:
        process.start()
    rclpy.init()
    node = rclpy.create_node('late_reader_bench')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        taken = [_trial(node, executor, k) for k in range(args.trials)]
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        for process in load:
            process.terminate()
    counts = collections.Counter(len(plans) for plans in taken)
    print(json.dumps({
        'trials': args.trials, 'busy_processes': args.load,
        'trials_by_plans_taken': {str(n): counts[n] for n in sorted(counts)},
        'every_trial_in_order_ending_on_the_newest': all(
            plans and plans == sorted(set(plans)) and plans[-1] == PLANS for plans in taken)}))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
