"""What the messages of a re-plan and of a lock-step tick cost, with rclpy's message classes
and with the hand-written CDR the nodes use.

- A re-plan (``replan_ros/messages/com_plan.py``, ``path.py``): a 201-point ``com_plan`` and a
  201-pose ``nav_msgs/Path`` built and serialized, and ``com_plan`` decoded.
- A tick (the codecs of ``replan_ros/messages/``): ``joint_states``, ``imu``, ``joint_torque_cmd``,
  ``odom`` and ``contacts`` built and serialized, and decoded.
- What the recorder and the live view derive per 0.04 s of sim time (``state_view.py``):
  the contact force markers and CoP margin from ``ground_truth/contacts``, and ``/tf`` with the
  velocity error from a pair of ``odom`` and ``joint_states``.

Prints one row per operation (median and p90 over ``--repeats``, ms) and, with ``--json``, one
JSON line. rclpy's ``publish`` of a message object converts it as ``serialize_message`` does,
then serializes it; it publishes ``bytes`` as they are.

    python -m replan_experiments.benchmarks.bench_msgs [--repeats N] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, PointCloud2
from sensor_msgs.msg import JointState as JointStateMsg
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_core.common import rotations
from replan_core.common.types import (
    WORLD_FRAME,
    BaseState,
    ComPlan,
    ContactState,
    ImuReading,
    JointState,
)
from replan_ros.messages.com_plan import (
    com_plan_from_cdr,
    com_plan_from_msg,
    com_plan_to_msg,
    encode_com_plan,
)
from replan_ros.messages.contacts import (
    contacts_from_cdr,
    contacts_from_msg,
    contacts_to_msg,
    encode_contacts,
)
from replan_ros.messages.imu import encode_imu, imu_from_cdr, imu_from_msg, imu_to_msg
from replan_ros.messages.joint_state import (
    encode_joint_state,
    encode_torque_command,
    joint_state_from_cdr,
    joint_state_from_msg,
    joint_state_to_msg,
    torque_cmd_from_msg,
    torque_cmd_to_msg,
    torque_command_from_cdr,
)
from replan_ros.messages.odom import (
    base_state_from_cdr,
    base_state_from_odom,
    encode_odom,
    odom_from_base_state,
)
from replan_ros.messages.path import encode_path, path_msg
from replan_ros.messages.stamps import sec_to_ns
from replan_ros.view.state_view import StateView

_HORIZON = 200            # samples: 8 s at 0.04 s, the paper's horizon (config/mpc.yaml)


def _timed(fn, repeats: int) -> tuple[float, float]:
    fn()                                                      # warm-up
    times = []
    for _ in range(repeats):
        start = time.perf_counter_ns()
        fn()
        times.append((time.perf_counter_ns() - start) * 1e-6)
    return float(np.median(times)), float(np.percentile(times, 90))


def measure(repeats: int) -> dict[str, tuple[float, float]]:
    """(median, p90) in ms of each operation, on one fixed-seed plan and tick."""
    return {**_plan_messages(repeats), **_tick_messages(repeats), **_view(repeats)}


def _plan_messages(repeats: int) -> dict[str, tuple[float, float]]:
    rng = np.random.default_rng(0)
    t, dt = 12.34, 0.04
    plan = ComPlan(t, dt, *(rng.normal(size=(_HORIZON + 1, 3)) for _ in range(3)))
    stamp_ns = sec_to_ns(t)
    data = encode_com_plan(plan, stamp_ns, WORLD_FRAME)
    return {
        'com_plan encode, rclpy (message + serialize)':
            _timed(lambda: serialize_message(com_plan_to_msg(plan)), repeats),
        'com_plan encode, by hand':
            _timed(lambda: encode_com_plan(plan, stamp_ns, WORLD_FRAME), repeats),
        'com_plan decode, rclpy (deserialize + arrays)':
            _timed(lambda: com_plan_from_msg(deserialize_message(data, MultiDOFJointTrajectory)),
                   repeats),
        'com_plan decode, by hand': _timed(lambda: com_plan_from_cdr(data), repeats),
        'path encode, rclpy (message + serialize)':
            _timed(lambda: serialize_message(path_msg(t, dt, plan.position)), repeats),
        'path encode, by hand':
            _timed(lambda: encode_path(stamp_ns, t, dt, plan.position, WORLD_FRAME),
                   repeats),
    }


def _tick_messages(repeats: int) -> dict[str, tuple[float, float]]:
    rng = np.random.default_rng(1)
    t = 12.344
    stamp_ns = sec_to_ns(t)
    joints = JointState(t, *(rng.normal(size=12) for _ in range(3)))
    torques = rng.normal(scale=20.0, size=12)
    imu = ImuReading(t, rng.normal(size=3), rng.normal(size=3))
    base = BaseState(t, rng.normal(size=3), np.asarray(rotations.normalized(rng.normal(size=4))),
                     rng.normal(size=3), rng.normal(size=3))
    contacts = ContactState(t, rng.normal(size=(4, 3)), rng.normal(size=(4, 3)),
                            np.ones(4, bool), np.zeros(4, bool), np.zeros(4, bool))
    joints_cdr = encode_joint_state(joints)
    command_cdr = encode_torque_command(stamp_ns, torques)
    imu_cdr = encode_imu(imu, 1e-4, 1e-3)
    odom_cdr = encode_odom(base)
    contacts_cdr = encode_contacts(contacts)
    rows = {
        'joint_states encode': (lambda: serialize_message(joint_state_to_msg(joints)),
                                lambda: encode_joint_state(joints)),
        'joint_states decode': (
            lambda: joint_state_from_msg(deserialize_message(joints_cdr, JointStateMsg)),
            lambda: joint_state_from_cdr(joints_cdr)),
        'imu encode': (lambda: serialize_message(imu_to_msg(imu, 1e-4, 1e-3)),
                       lambda: encode_imu(imu, 1e-4, 1e-3)),
        'imu decode': (lambda: imu_from_msg(deserialize_message(imu_cdr, Imu)),
                       lambda: imu_from_cdr(imu_cdr)),
        'joint_torque_cmd encode': (lambda: serialize_message(torque_cmd_to_msg(t, torques)),
                                    lambda: encode_torque_command(stamp_ns, torques)),
        'joint_torque_cmd decode': (
            lambda: torque_cmd_from_msg(deserialize_message(command_cdr, JointStateMsg)),
            lambda: torque_command_from_cdr(command_cdr)),
        'odom encode': (lambda: serialize_message(odom_from_base_state(base)),
                        lambda: encode_odom(base)),
        'odom decode': (lambda: base_state_from_odom(deserialize_message(odom_cdr, Odometry)),
                        lambda: base_state_from_cdr(odom_cdr)),
        'contacts encode': (lambda: serialize_message(contacts_to_msg(contacts)),
                            lambda: encode_contacts(contacts)),
        'contacts decode': (
            lambda: contacts_from_msg(deserialize_message(contacts_cdr, PointCloud2)),
            lambda: contacts_from_cdr(contacts_cdr)),
    }
    results = {}
    for name, (generic, ours) in rows.items():
        results[f'{name}, rclpy'] = _timed(generic, repeats)
        results[f'{name}, by hand'] = _timed(ours, repeats)
    return results


def _view(repeats: int) -> dict[str, tuple[float, float]]:
    rng = np.random.default_rng(2)
    t = 12.344
    feet = rng.uniform(-0.4, 0.4, (4, 3))
    forces = np.column_stack([rng.normal(size=(4, 2)), [300.0, 250.0, 280.0, 0.0]])
    contacts_cdr = encode_contacts(ContactState(
        t, feet, forces, np.array([1, 1, 1, 0], bool), np.zeros(4, bool), np.zeros(4, bool)))
    joints_cdr = encode_joint_state(JointState(t, *(rng.normal(size=12)
                                                             for _ in range(3))))
    odom_cdr = encode_odom(BaseState(t, rng.normal(size=3), np.array([0, 0, 0, 1.0]),
                                              rng.normal(size=3), rng.normal(size=3)))
    view = StateView(period=0.0)          # every input is due

    def state_pair():
        view.feed('/joint_states', joints_cdr)
        return view.feed('/odom', odom_cdr)

    return {'view: contacts -> markers + CoP margin':
            _timed(lambda: view.feed('/ground_truth/contacts', contacts_cdr), repeats),
            'view: odom + joint_states -> /tf + velocity error': _timed(state_pair, repeats)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--repeats', type=int, default=300)
    parser.add_argument('--json', action='store_true', help='also print one JSON line')
    args = parser.parse_args(argv)
    results = measure(max(args.repeats, 1))
    print(f'{"operation (plans: 201 samples)":48s} {"median ms":>10s} {"p90 ms":>8s}')
    for name, (median, p90) in results.items():
        print(f'{name:48s} {median:10.3f} {p90:8.3f}')
    if args.json:
        print(json.dumps({name: {'median_ms': round(m, 4), 'p90_ms': round(p, 4)}
                          for name, (m, p) in results.items()}))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
