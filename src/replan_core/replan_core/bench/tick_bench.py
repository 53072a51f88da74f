"""Benchmark of the controller's whole tick in the core, and a bit-exactness check of it.

Run: ``python -m replan_core.bench.tick_bench [--ticks N] [--record FILE] [--against FILE]``
(after ``source scripts/env.sh``).

What the wbc node computes per tick, without ROS: ``StateEstimator.update`` on a synthesised
IMU and noisy joints, the plan following (``PlanFollower``), ``WholeBodyController.compute`` on
the estimate (as in the realistic profile), and after the command ``prepare_next``. HyQ crawls
in the PyBullet world (``wbc_bench.crawl_plan``), so there are swing legs, touchdowns and a
moving CoM. The thread CPU time of each stage is printed (medians over the ticks).

``--record FILE`` saves every float and flag the estimator and the controller gave (``.npy``);
``--against FILE`` compares a run with such a recording byte for byte and exits with 1 at the
first tick that differs: a change meant to be bit-exact is checked with the recording made
before it.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from replan_core.common.types import GRAVITY, ImuReading, JointState
from replan_core.robot.robot_file import default_urdf

DT = 0.004                                   # s, control period
_G_WORLD = np.array([0.0, 0.0, -GRAVITY])    # m/s^2
STAGES = ('estimator', 'plan following', 'controller', 'prepare_next')


def _outputs(base, contacts, result, covariance: np.ndarray) -> np.ndarray:
    """Every float and flag of one tick's estimate and command, as one float64 row."""
    return np.concatenate([
        base.position, base.quaternion, base.linear_velocity, base.angular_velocity,
        contacts.foot_position.ravel(), contacts.force.ravel(), contacts.contact,
        contacts.touchdown, contacts.liftoff, result.torque, result.forces.ravel(),
        result.com_error, result.com_velocity_error, result.orientation_error,
        result.swing_error, result.stance, result.active_contacts,
        (result.qp_iterations, result.fallback, result.saturated), covariance.ravel()])


def run(urdf: str, ticks: int = 3000, seed: int = 0) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Closed-loop crawl of ``ticks`` control ticks; returns the thread CPU times (s) of each
    stage per tick and the outputs (one row per tick, ``_outputs``)."""
    from replan_core.bench.wbc_bench import closed_loop_crawl
    from replan_core.common.rotations import quaternion_to_matrix
    from replan_core.sim.world import SimWorld

    rng = np.random.default_rng(seed)
    world = SimWorld(urdf, control_period=DT)
    times = {stage: np.zeros(ticks) for stage in STAGES}
    rows = []
    try:
        wbc, estimator, follower = closed_loop_crawl(world, urdf, ticks, DT)
        previous_velocity = None
        for tick in range(ticks):
            base, joints, _ = world.base_state(), world.joint_state(), world.contact_state()
            rotation = quaternion_to_matrix(base.quaternion)
            accel_world = (np.zeros(3) if previous_velocity is None
                           else (base.linear_velocity - previous_velocity) / DT)
            previous_velocity = base.linear_velocity.copy()
            imu = ImuReading(base.stamp,
                             rotation.T @ base.angular_velocity + 0.005 * rng.normal(size=3),
                             rotation.T @ (accel_world - _G_WORLD) + 0.05 * rng.normal(size=3))
            measured = JointState(joints.stamp, joints.position + 2e-4 * rng.normal(size=12),
                                  joints.velocity + 0.02 * rng.normal(size=12),
                                  joints.effort + 0.5 * rng.normal(size=12))
            t0 = time.thread_time()
            # As the node: the follower's swing legs.
            estimate, estimated_contacts = estimator.update(imu, measured,
                                                            follower.tracker.in_swing)
            t1 = time.thread_time()
            t = world.time
            # The plans follow the sensed flags, as in the node: the estimator's.
            follower.update(t, estimated_contacts)
            com_ref, yaw, stance, swing = follower.references(t)
            t2 = time.thread_time()
            result = wbc.compute(estimate, measured, estimated_contacts.contact, com_ref, yaw,
                                 stance, swing, yaw_rate_reference=follower.yaw_rate(t))
            t3 = time.thread_time()
            world.step(result.torque)
            t4 = time.thread_time()
            estimator.prepare_next(world.time)        # the next update's stamp
            t5 = time.thread_time()
            for stage, seconds in zip(STAGES, (t1 - t0, t2 - t1, t3 - t2, t5 - t4), strict=True):
                times[stage][tick] = seconds
            rows.append(_outputs(estimate, estimated_contacts, result, estimator.covariance))
    finally:
        world.close()
    return times, np.array(rows)


def first_difference(outputs: np.ndarray, recorded: np.ndarray) -> int | None:
    """The first tick whose outputs differ in any bit (a shorter run differs at its end),
    None if they are the same bytes."""
    ticks = min(len(outputs), len(recorded))
    if outputs.shape[1:] != recorded.shape[1:]:
        return 0
    same = (outputs[:ticks].view(np.int64) == recorded[:ticks].view(np.int64)).all(axis=1)
    if not same.all():
        return int(np.argmin(same))
    return None if len(outputs) == len(recorded) else ticks


def main() -> None:
    root = Path(__file__).resolve().parents[4]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--urdf', default=default_urdf(root))
    parser.add_argument('--ticks', type=int, default=3000, help='control ticks')
    parser.add_argument('--record', help='save the outputs to this .npy file')
    parser.add_argument('--against', help='compare the outputs with this recording')
    args = parser.parse_args()
    times, outputs = run(args.urdf, args.ticks)
    print(f'tick bench: {args.ticks} control ticks (250 Hz) of a closed-loop crawl, the '
          'controller on the estimate; thread CPU time per tick, median (ms):')
    total = sum(times.values())
    for stage, seconds in (*times.items(), ('all', total)):
        print(f'  {stage:15s} {1e3 * float(np.median(seconds[1:])):.4f}')
    if args.record:
        np.save(args.record, outputs)
        print(f'  outputs recorded: {args.record}')
    if args.against:
        tick = first_difference(outputs, np.load(args.against))
        if tick is not None:
            print(f'  outputs differ from {args.against} from tick {tick} on')
            sys.exit(1)
        print(f'  outputs bit-identical to {args.against}')


if __name__ == '__main__':
    main()
