"""What rclpy costs the lock-step chain, measured (scripts/bench_rclpy.sh; docs/performance.md).

1. ``executor``: one node publishes to itself and spins once per message, with rclpy's default
   QoS-event handlers on its 8 publishers and subscriptions and without them
   (``qos.INTERNAL_*_EVENTS``): microseconds per message.
2. ``bystanders``: a ping-pong like the sim and the controller (3 state messages out, 1 command
   back, each in its own process) with 2 extra processes subscribed to the 3 state topics, spun
   by an executor (a Python wake-up per message) or read on demand (``on_demand.py``, never
   taken here): milliseconds per round trip. Without bystanders, also the CPU time per round
   of each side (the process's user + system time over the timed rounds): what rclpy alone
   costs the sim and the wbc node per tick, before either does any work.

Prints one JSON line.   python -m replan_experiments.benchmarks.bench_rclpy [--rounds N]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import subprocess
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Empty

from replan_ros.launch.graph import process_cpu_seconds
from replan_ros.transport import qos
from replan_ros.transport.on_demand import OnDemandSubscriptions

STATE_TOPICS = ('bench_state_0', 'bench_state_1', 'bench_state_2')
WARM_UP = 100


def _executor_cost(quiet: bool, messages: int) -> float:
    """Microseconds per publish + spin_once, 8 publishers/subscriptions in the node."""
    node = Node(f'bench_executor_{int(quiet)}')
    sub_events = {'event_callbacks': qos.INTERNAL_SUB_EVENTS} if quiet else {}
    pub_events = {'event_callbacks': qos.INTERNAL_PUB_EVENTS} if quiet else {}
    node.create_subscription(Empty, 'bench_self', lambda _msg: None, 10, **sub_events)
    publisher = node.create_publisher(Empty, 'bench_self', 10, **pub_events)
    for k in range(6):
        node.create_publisher(Empty, f'bench_other_{k}', 10, **pub_events)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    for _ in range(WARM_UP):
        publisher.publish(Empty())
        executor.spin_once(timeout_sec=1.0)
    start = time.perf_counter()
    for _ in range(messages):
        publisher.publish(Empty())
        executor.spin_once(timeout_sec=1.0)
    cost = (time.perf_counter() - start) / messages * 1e6
    executor.remove_node(node)
    node.destroy_node()
    return cost


def _state(k: int) -> JointState:
    msg = JointState()
    msg.header.stamp.sec = k
    msg.name = [f'joint_{i}' for i in range(12)]
    msg.position = [0.1] * 12
    msg.velocity = [0.2] * 12
    msg.effort = [0.3] * 12
    return msg


def _round_of(msg) -> int:
    """The round a state or command belongs to: its header.stamp.sec, read from the bytes of a
    serialized message (after the 4-byte CDR header) or from a message object."""
    if isinstance(msg, bytes):
        return struct.unpack_from('<i', msg, 4)[0]
    return msg.header.stamp.sec


def _ways(lean: bool) -> tuple[dict, dict]:
    """Publisher and subscription keywords: rclpy's defaults, or (``lean``) the nodes' way:
    serialized messages (``raw=True``, bytes published) and no QoS-event handlers."""
    if not lean:
        return {}, {}
    return ({'event_callbacks': qos.INTERNAL_PUB_EVENTS},
            {'event_callbacks': qos.INTERNAL_SUB_EVENTS, 'raw': True})


def _role_controller(lean: bool) -> None:
    """Answer each round once its 3 state messages are in (as the wbc does). ``lean``: the wbc
    node's way (``_ways``; its own CDR code is not timed here), with 3 messages out per round
    (command, odom, contacts; only the command has a reader here, where the node's odom and
    contacts have the gait's: a floor of its cost)."""
    node = Node('bench_controller')
    pub_kw, sub_kw = _ways(lean)
    topics = ('bench_command', 'bench_output_1', 'bench_output_2') if lean else ('bench_command',)
    outputs = [node.create_publisher(JointState, t, qos.COMMAND, **pub_kw) for t in topics]
    seen: dict[int, int] = {}

    def on_state(msg) -> None:
        k = _round_of(msg)
        seen[k] = seen.get(k, 0) + 1
        if seen[k] == len(STATE_TOPICS):
            del seen[k]
            reply = msg if lean else _state(k)
            for publisher in outputs:
                publisher.publish(reply)
    for topic in STATE_TOPICS:
        node.create_subscription(JointState, topic, on_state, qos.SENSOR, **sub_kw)
    rclpy.spin(node)


def _role_bystander(on_demand: bool) -> None:
    node = Node('bench_bystander')
    if on_demand:
        inputs = OnDemandSubscriptions(node)
        for topic in STATE_TOPICS:
            inputs.subscribe(JointState, topic, qos.SENSOR, lambda _msg: None)
    else:
        for topic in STATE_TOPICS:
            node.create_subscription(JointState, topic, lambda _msg: None, qos.SENSOR)
    rclpy.spin(node)


def _controller_cpu(pid: int) -> float:
    """CPU s the controller process ``pid`` has used so far; it must still run."""
    seconds = process_cpu_seconds(pid)
    if seconds is None:
        raise RuntimeError(f'bench_rclpy: the controller process {pid} is gone')
    return seconds


def _round_trip(bystanders: int, on_demand: bool, rounds: int,
                lean: bool = False) -> tuple[float, float, float]:
    """Per round (3 state messages out, the command back): wall ms, and CPU ms of this
    process (the sim's side) and of the controller process (``lean``: both the nodes' way,
    ``_ways``)."""
    role = 'bystander_on_demand' if on_demand else 'bystander_spun'
    me = [sys.executable, '-m', 'replan_experiments.benchmarks.bench_rclpy', '--role']
    children = [subprocess.Popen([*me, 'controller_lean' if lean else 'controller'])]
    children += [subprocess.Popen([*me, role]) for _ in range(bystanders)]
    node = Node('bench_simulator')
    answered: list[int] = []
    pub_kw, sub_kw = _ways(lean)
    publishers = [node.create_publisher(JointState, t, qos.SENSOR, **pub_kw)
                  for t in STATE_TOPICS]
    if lean:
        # The sim's CDR code is not timed: a template with the round's number written in.
        template = bytearray(serialize_message(_state(0)))

        def state(k: int) -> bytes:
            struct.pack_into('<i', template, 4, k)
            return bytes(template)
    else:
        state = _state
    node.create_subscription(JointState, 'bench_command',
                             lambda msg: answered.append(_round_of(msg)), qos.COMMAND, **sub_kw)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        deadline = time.monotonic() + 30.0
        while (any(p.get_subscription_count() < 1 + bystanders for p in publishers)
               or node.count_publishers('bench_command') < 1):
            if time.monotonic() > deadline:
                raise RuntimeError('bench_rclpy: the helper processes did not come up')
            executor.spin_once(timeout_sec=0.1)
        start = cpu_sim = cpu_controller = 0.0
        for k in range(WARM_UP + rounds):
            if k == WARM_UP:
                start = time.perf_counter()
                cpu_sim = time.process_time()
                cpu_controller = _controller_cpu(children[0].pid)
            for publisher in publishers:
                publisher.publish(state(k))
            while not answered or answered[-1] != k:
                executor.spin_once(timeout_sec=0.5)
                if not answered or answered[-1] != k:
                    for publisher in publishers:      # best effort: a lost one is resent
                        publisher.publish(state(k))
        wall = time.perf_counter() - start
        cpu_sim = time.process_time() - cpu_sim
        cpu_controller = _controller_cpu(children[0].pid) - cpu_controller
        return wall / rounds * 1e3, cpu_sim / rounds * 1e3, cpu_controller / rounds * 1e3
    finally:
        executor.remove_node(node)
        node.destroy_node()
        for child in children:              # SIGINT: they leave no Fast DDS segments behind
            child.send_signal(signal.SIGINT)
        for child in children:
            try:
                child.wait(timeout=10)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--rounds', type=int, default=2000)
    parser.add_argument('--role', choices=('controller', 'controller_lean', 'bystander_spun',
                                           'bystander_on_demand'), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    rclpy.init()
    try:
        if args.role in ('controller', 'controller_lean'):
            _role_controller(lean=args.role == 'controller_lean')
            return 0
        if args.role is not None:
            _role_bystander(args.role == 'bystander_on_demand')
            return 0
        result = {
            'executor_us_per_message_default_event_handlers': _executor_cost(False, args.rounds),
            'executor_us_per_message_no_event_handlers': _executor_cost(True, args.rounds),
        }
        alone = _round_trip(0, False, args.rounds)
        lean = _round_trip(0, False, args.rounds, lean=True)
        result |= {
            'round_trip_ms_no_bystander': alone[0],
            'round_trip_cpu_ms_sim_side': alone[1],
            'round_trip_cpu_ms_controller_side': alone[2],
            'lean_round_trip_ms': lean[0],
            'lean_round_trip_cpu_ms_sim_side': lean[1],
            'lean_round_trip_cpu_ms_controller_side': lean[2],
            'round_trip_ms_2_spun_bystanders': _round_trip(2, False, args.rounds)[0],
            'round_trip_ms_2_on_demand_bystanders': _round_trip(2, True, args.rounds)[0],
            'cpus': os.cpu_count(),
        }
        print(json.dumps({k: round(v, 3) if isinstance(v, float) else v
                          for k, v in result.items()}))
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 130
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
