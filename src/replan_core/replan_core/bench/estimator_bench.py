"""Benchmark of the state estimator: time of one ``StateEstimator.update``, closed loop.

Run: ``python -m replan_core.bench.estimator_bench [--ticks N]`` (after ``source scripts/env.sh``).

HyQ crawls in the PyBullet world (``wbc_bench.crawl_plan`` through ``PlanFollower``, the
controller fed the ground truth), so the estimator sees swing legs, touchdowns and a moving CoM.
Its IMU is synthesised from the simulator's truth (gyro and accelerometer with white noise and a
constant bias, fixed seed), the joints get encoder and torque noise. ``update`` is timed (wall
and thread CPU time) and, apart, ``prepare_next`` after it (as the controller calls it, after
its command: off the tick's critical path); ``--no-prepare`` times ``update`` alone, doing all
of its covariance work itself. The accuracy figures are printed as a sanity check.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from replan_core.common.types import GRAVITY, ImuReading, JointState
from replan_core.robot.robot_file import default_urdf

DT = 0.004                                   # s, control period
_G_WORLD = np.array([0.0, 0.0, -GRAVITY])    # m/s^2


def run(urdf: str, ticks: int = 2000, seed: int = 0, quiet: bool = False,
        prepare: bool = True) -> dict[str, float]:
    """Closed-loop crawl for ``ticks`` control ticks; returns timing (s) and accuracy figures.
    ``prepare``: call ``prepare_next`` after each update (timed apart)."""
    from replan_core.bench.wbc_bench import closed_loop_crawl
    from replan_core.common.rotations import quaternion_to_matrix
    from replan_core.sim.world import SimWorld

    rng = np.random.default_rng(seed)
    gyro_bias = np.array([0.002, -0.002, 0.002])       # rad/s
    accel_bias = np.array([0.03, -0.03, 0.03])         # m/s^2
    world = SimWorld(urdf, control_period=DT)
    try:
        wbc, estimator, follower = closed_loop_crawl(world, urdf, ticks, DT)
        wall, cpu, prepare_wall, velocity_errors, edge_offsets = [], [], [], [], []
        previous_velocity = None
        true_edges: list[tuple[int, int]] = []
        estimated_edges: list[tuple[int, int]] = []
        for tick in range(ticks):
            base, joints, contacts = world.base_state(), world.joint_state(), world.contact_state()
            rotation = quaternion_to_matrix(base.quaternion)
            accel_world = (np.zeros(3) if previous_velocity is None
                           else (base.linear_velocity - previous_velocity) / DT)
            previous_velocity = base.linear_velocity.copy()
            imu = ImuReading(
                base.stamp,
                rotation.T @ base.angular_velocity + gyro_bias + 0.005 * rng.normal(size=3),
                rotation.T @ (accel_world - _G_WORLD) + accel_bias + 0.05 * rng.normal(size=3))
            measured = JointState(joints.stamp, joints.position + 2e-4 * rng.normal(size=12),
                                  joints.velocity + 0.02 * rng.normal(size=12),
                                  joints.effort + 0.5 * rng.normal(size=12))
            start, cpu_start = time.perf_counter(), time.thread_time()
            est_base, est_contacts = estimator.update(imu, measured)
            wall.append(time.perf_counter() - start)
            cpu.append(time.thread_time() - cpu_start)
            velocity_errors.append(est_base.linear_velocity - base.linear_velocity)
            true_edges += [(tick, leg) for leg in np.flatnonzero(contacts.touchdown)]
            estimated_edges += [(tick, leg) for leg in np.flatnonzero(est_contacts.touchdown)]
            t = world.time
            follower.update(t, contacts)
            com_ref, yaw, stance, swing = follower.references(t)
            result = wbc.compute(base, joints, contacts.contact, com_ref, yaw, stance, swing)
            world.step(result.torque)
            if prepare:
                start = time.perf_counter()
                estimator.prepare_next(world.time)        # the next update's stamp
                prepare_wall.append(time.perf_counter() - start)
        final_error = est_base.position - base.position
    finally:
        world.close()
    for tick, leg in true_edges:
        matches = [abs(tick - k) for k, other in estimated_edges if other == leg]
        edge_offsets.append(min(matches) if matches else np.inf)
    wall_us, cpu_us = 1e6 * np.array(wall[1:]), 1e6 * np.array(cpu[1:])
    figures = {
        'ticks': len(wall),
        'wall_median_us': float(np.median(wall_us)),
        'wall_p99_us': float(np.percentile(wall_us, 99)),
        'cpu_median_us': float(np.median(cpu_us)),
        'cpu_p99_us': float(np.percentile(cpu_us, 99)),
        'velocity_rmse': float(np.sqrt(np.mean(np.sum(np.square(velocity_errors), axis=1)))),
        'final_position_error': float(np.linalg.norm(final_error)),
        'touchdowns': len(true_edges),
        'touchdown_offset_max_ticks': float(max(edge_offsets, default=0.0)),
        'prepare_median_us': (float(np.median(1e6 * np.array(prepare_wall[1:])))
                              if prepare else 0.0),
        'prepared_share': estimator.prepared_used / len(wall),
    }
    if not quiet:
        print(f'estimator bench: {figures["ticks"]} updates (250 Hz) of a closed-loop crawl')
        print(f'  StateEstimator.update wall time: median {figures["wall_median_us"]:.0f} us, '
              f'p99 {figures["wall_p99_us"]:.0f} us')
        print(f'  same, thread CPU time: median {figures["cpu_median_us"]:.0f} us, '
              f'p99 {figures["cpu_p99_us"]:.0f} us')
        if prepare:
            print(f'  prepare_next after it (not in the figures above): median '
                  f'{figures["prepare_median_us"]:.0f} us; the step prepared was used in '
                  f'{100 * figures["prepared_share"]:.1f} % of the updates')
        else:
            print('  --no-prepare: every update did its own covariance work')
        print(f'  velocity RMSE {figures["velocity_rmse"]:.4f} m/s, final position error '
              f'{1e3 * figures["final_position_error"]:.1f} mm, {figures["touchdowns"]} '
              f'touchdowns, estimated within {figures["touchdown_offset_max_ticks"]:.0f} ticks')
        print('  target: well under 500 us per update')
    return figures


def main() -> None:
    root = Path(__file__).resolve().parents[4]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--urdf', default=default_urdf(root))
    parser.add_argument('--ticks', type=int, default=2000, help='control ticks (updates)')
    parser.add_argument('--no-prepare', action='store_true',
                        help='no prepare_next between updates (the estimator before it)')
    args = parser.parse_args()
    run(args.urdf, args.ticks, prepare=not args.no_prepare)


if __name__ == '__main__':
    main()
