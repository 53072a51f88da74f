"""Benchmark of the whole-body controller: computation time per control tick, closed loop.

Run: ``scripts/bench_wbc.sh`` (or ``python -m replan_core.bench.wbc_bench --help``).

The run is realistic for the controller: the PyBullet world (``sim_world.SimWorld``) in closed
loop with a static crawl (four haptic steps per cycle, CoM shifted into each support triangle
before its swing) generated here from the actual feet, so every tick has a swing leg or a
moving CoM and a 3- or 4-foot force QP. The time measured is ``WholeBodyController.compute``
(one pinocchio pass, the force QP, the torques) plus the plan sampling and the step tracker, i.e.
what the wbc node does per tick besides message conversion.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from replan_core.types import ComPlan, FootholdPlan, Step

CRAWL_ORDER = (0, 3, 1, 2)    # lf, rh, rf, lh: the crawl sequence


def _quintic(s: float) -> tuple[float, float, float]:
    s = min(max(s, 0.0), 1.0)
    return (s**3 * (10 - 15 * s + 6 * s * s), 30 * s * s * (1 - s) ** 2,
            60 * s * (1 - s) * (1 - 2 * s))


def crawl_plan(start_time: float, feet: np.ndarray, com: np.ndarray, cycles: int = 1,
               step_length: float = 0.08, shift_time: float = 0.8, swing_time: float = 0.6,
               step_height: float = 0.06, shift_fraction: float = 0.6, dt: float = 0.04,
               haptic: bool = True) -> tuple[FootholdPlan, ComPlan]:
    """A static crawl from the actual ``feet`` (4, 3) and ``com`` (3,): before each swing the
    CoM moves (quintic, ``shift_time`` s) ``shift_fraction`` of the way to the centroid of the
    three stance feet; then the leg swings ``step_length`` forward (``swing_time`` s).
    Returns the footholds and the CoM plan sampled every ``dt`` (s)."""
    feet = np.array(feet, dtype=float)
    initial_feet = feet.copy()
    waypoints = [(start_time, np.array(com[:2], dtype=float))]
    steps = []
    t = start_time
    for _ in range(cycles):
        for leg in CRAWL_ORDER:
            stance = [i for i in range(4) if i != leg]
            current = waypoints[-1][1]
            goal = current + shift_fraction * (feet[stance, :2].mean(axis=0) - current)
            t += shift_time
            waypoints.append((t, goal))
            target = feet[leg] + np.array([step_length, 0.0, 0.0])
            steps.append(Step(leg=leg, liftoff_time=t, touchdown_time=t + swing_time,
                              target=target, step_height=step_height, haptic=haptic,
                              replan=False, yaw=0.0))
            feet[leg] = target
            t += swing_time
            waypoints.append((t, goal))
    end = t + 1.0
    waypoints.append((end, waypoints[-1][1]))
    times = start_time + dt * np.arange(int(np.ceil((end - start_time) / dt)) + 1)
    position = np.zeros((len(times), 3))
    velocity = np.zeros((len(times), 3))
    acceleration = np.zeros((len(times), 3))
    position[:, 2] = com[2]
    ends = np.array([w[0] for w in waypoints])
    for k, tk in enumerate(times):
        i = int(np.clip(np.searchsorted(ends, tk) - 1, 0, len(waypoints) - 2))
        (ta, pa), (tb, pb) = waypoints[i], waypoints[i + 1]
        duration = tb - ta
        b, db, ddb = _quintic((tk - ta) / duration)      # clamped past the last waypoint
        position[k, :2] = pa + (pb - pa) * b
        velocity[k, :2] = (pb - pa) * db / duration
        acceleration[k, :2] = (pb - pa) * ddb / duration**2
    footholds = FootholdPlan(start_time=start_time, initial_feet=initial_feet, initial_yaw=0.0,
                             steps=steps)
    return footholds, ComPlan(start_time, dt, position, velocity, acceleration)


def run(urdf: str, cycles: int, quiet: bool = False) -> dict[str, float]:
    """Closed-loop crawl; returns timing figures (s) and tracking figures (m)."""
    from replan_core.robot_model import RobotModel
    from replan_core.sim_world import SimWorld
    from replan_core.wbc import PlanFollower, WholeBodyController

    world = SimWorld(urdf)
    try:
        robot = RobotModel(urdf)
        wbc = WholeBodyController(robot)
        base, joints, contacts = world.base_state(), world.joint_state(), world.contact_state()
        com0 = robot.com_state(base, joints)[0]
        footholds, com_plan = crawl_plan(0.5, contacts.foot_position, com0, cycles=cycles)
        follower = PlanFollower(footholds, com_plan)
        tick_times, cpu_times, compute_times, com_errors = [], [], [], []
        fallbacks = 0
        while world.time < com_plan.end_time:
            base, joints, contacts = world.base_state(), world.joint_state(), world.contact_state()
            start, cpu_start = time.perf_counter(), time.thread_time()
            t = world.time
            follower.update(t, contacts)
            com_ref, yaw, stance, swing = follower.references(t)
            result = wbc.compute(base, joints, contacts.contact, com_ref, yaw, stance, swing)
            tick_times.append(time.perf_counter() - start)
            cpu_times.append(time.thread_time() - cpu_start)
            compute_times.append(result.compute_time)
            com_errors.append(float(np.linalg.norm(result.com_error)))
            fallbacks += int(result.fallback)
            world.step(result.torque)
        final = robot.com_state(world.base_state(), world.joint_state())[0]
    finally:
        world.close()
    ticks = np.array(tick_times)
    cpu = np.array(cpu_times)
    figures = {
        'ticks': len(ticks),
        'tick_median_ms': 1e3 * float(np.median(ticks)),
        'tick_p99_ms': 1e3 * float(np.percentile(ticks, 99)),
        'tick_max_ms': 1e3 * float(ticks.max()),
        'cpu_median_ms': 1e3 * float(np.median(cpu)),
        'cpu_p99_ms': 1e3 * float(np.percentile(cpu, 99)),
        'compute_median_ms': 1e3 * float(np.median(compute_times)),
        'compute_p99_ms': 1e3 * float(np.percentile(compute_times, 99)),
        'com_error_max_m': max(com_errors),
        'com_error_median_m': float(np.median(com_errors)),
        'advance_m': float(final[0] - com0[0]),
        'steps_done': sum(x is not None for x in follower.tracker.touchdown_tick),
        'steps': len(footholds.steps),
        'fallbacks': fallbacks,
    }
    if not quiet:
        print(f'wbc bench: {figures["ticks"]} control ticks (250 Hz) of a closed-loop static '
              f'crawl, {figures["steps_done"]}/{figures["steps"]} haptic steps')
        print(f'  per tick (tracker + plan sampling + WholeBodyController.compute): '
              f'median {figures["tick_median_ms"]:.3f} ms, p99 {figures["tick_p99_ms"]:.3f} ms, '
              f'max {figures["tick_max_ms"]:.3f} ms')
        print(f'  same, thread CPU time (without preemption by other processes): median '
              f'{figures["cpu_median_ms"]:.3f} ms, p99 {figures["cpu_p99_ms"]:.3f} ms')
        print(f'  WholeBodyController.compute alone: median {figures["compute_median_ms"]:.3f} ms,'
              f' p99 {figures["compute_p99_ms"]:.3f} ms')
        print(f'  CoM error: median {1e3 * figures["com_error_median_m"]:.1f} mm, '
              f'max {1e3 * figures["com_error_max_m"]:.1f} mm; advance '
              f'{figures["advance_m"]:.3f} m; fallbacks {figures["fallbacks"]}')
        print('  target: median <= 1 ms per tick')
    return figures


def main() -> None:
    root = Path(__file__).resolve().parents[4]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--urdf', default=os.environ.get('REPLAN_URDF',
                                                         str(root / 'urdf' / 'hyq.urdf')))
    parser.add_argument('--cycles', type=int, default=2, help='crawl cycles (4 steps each)')
    args = parser.parse_args()
    run(args.urdf, args.cycles)


if __name__ == '__main__':
    main()
