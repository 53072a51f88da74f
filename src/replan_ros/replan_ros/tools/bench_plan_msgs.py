"""What one re-plan's messages cost: a 201-point ``com_plan`` and a 201-pose ``nav_msgs/Path``
built and serialized, and ``com_plan`` decoded, with rclpy's message classes and with the
hand-written CDR that the mpc and wbc nodes use (``replan_ros/cdr.py``). Prints one row per
operation (median and p90 over ``--repeats``, ms) and, with ``--json``, one JSON line.

    python -m replan_ros.tools.bench_plan_msgs [--repeats N] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_core.types import WORLD_FRAME, ComPlan
from replan_ros import cdr
from replan_ros.interfaces import com_plan_from_msg, com_plan_to_msg, path_msg, sec_to_ns

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
    """(median, p90) in ms of each operation, on one fixed-seed plan."""
    rng = np.random.default_rng(0)
    t, dt = 12.34, 0.04
    plan = ComPlan(t, dt, *(rng.normal(size=(_HORIZON + 1, 3)) for _ in range(3)))
    stamp_ns = sec_to_ns(t)
    data = cdr.encode_com_plan(plan, stamp_ns, WORLD_FRAME)
    return {
        'com_plan encode, rclpy (message + serialize)':
            _timed(lambda: serialize_message(com_plan_to_msg(plan)), repeats),
        'com_plan encode, cdr.py':
            _timed(lambda: cdr.encode_com_plan(plan, stamp_ns, WORLD_FRAME), repeats),
        'com_plan decode, rclpy (deserialize + arrays)':
            _timed(lambda: com_plan_from_msg(deserialize_message(data, MultiDOFJointTrajectory)),
                   repeats),
        'com_plan decode, cdr.py': _timed(lambda: cdr.com_plan_from_cdr(data), repeats),
        'path encode, rclpy (message + serialize)':
            _timed(lambda: serialize_message(path_msg(t, dt, plan.position)), repeats),
        'path encode, cdr.py':
            _timed(lambda: cdr.encode_path(stamp_ns, t, dt, plan.position, WORLD_FRAME),
                   repeats),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--repeats', type=int, default=200)
    parser.add_argument('--json', action='store_true', help='also print one JSON line')
    args = parser.parse_args(argv)
    results = measure(max(args.repeats, 1))
    print(f'{"operation (201 samples)":48s} {"median ms":>10s} {"p90 ms":>8s}')
    for name, (median, p90) in results.items():
        print(f'{name:48s} {median:10.3f} {p90:8.3f}')
    if args.json:
        print(json.dumps({name: {'median_ms': round(m, 4), 'p90_ms': round(p, 4)}
                          for name, (m, p) in results.items()}))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
