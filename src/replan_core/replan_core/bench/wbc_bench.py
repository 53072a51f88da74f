"""Benchmark of the whole-body controller: computation time per control tick, closed loop.

Run: ``scripts/bench_wbc.sh [--robot NAME|FILE]`` (or ``python -m replan_core.bench.wbc_bench
--help``).

The run is realistic for the controller: the PyBullet world (``sim_world.SimWorld``) in closed
loop with a static crawl (four haptic steps per cycle, CoM shifted into each support triangle
before its swing) generated here from the actual feet, so every tick has a swing leg or a
moving CoM and a 3- or 4-foot force QP. The time measured is ``WholeBodyController.compute``
(one pinocchio pass, the force QP, the torques) plus the plan sampling and the step tracker, i.e.
what the wbc node does per tick besides message conversion.

Another robot (``--robot``, a robot file): its model, names, contact sphere and standing pose;
every controller parameter of ``WbcParams`` and the sim's contact threshold that
``config/robots/scaling.yaml`` scales, scaled from the reference robot's (HyQ's) by its rules,
and the bench crawl's lengths (with l) and times (with sqrt(l / g)).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from replan_core.common.types import ComPlan, FootholdPlan, Step
from replan_core.robot.robot_file import default_urdf

CRAWL_ORDER = (0, 3, 1, 2)    # lf, rh, rf, lh: the crawl sequence
CONTACT_THRESHOLD = 30.0      # N: the sim's contact threshold for the reference robot (HyQ)


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


@dataclass
class WbcBenchRobot:
    """What the bench needs of a robot other than the default HyQ: its model and names (None:
    the world's and the model's defaults), the controller's parameters, the sim's contact
    threshold and the crawl's lengths (m), times (s) and haptic descent speed (m/s)."""

    urdf: str
    names: dict = field(default_factory=dict)        # SimWorld's robot keywords
    model_names: tuple = ()                          # RobotModel's (joints, feet)
    params: object | None = None                     # WbcParams; None: the defaults
    contact_threshold: float = CONTACT_THRESHOLD     # N, the sim's
    crawl: dict = field(default_factory=dict)        # crawl_plan's keywords


def bench_robot(spec, reference, rules: dict) -> WbcBenchRobot:
    """``spec``'s robot (a ``robot_file.RobotSpec``) with the reference robot's controller
    parameters scaled to it by ``rules`` (config/robots/scaling.yaml: each ``wbc.`` parameter
    of ``WbcParams`` and ``sim.contact_threshold`` it names; ``bench.bench_robots``) and the
    bench crawl scaled with the leg length and pendulum time."""
    from replan_core.robot.robot_file import robot_facts
    from replan_core.robot.scaling import SCALES, derived_parameters
    from replan_core.wbc.settings import WbcParams

    facts, ref = robot_facts(spec), robot_facts(reference)
    base = WbcParams()
    values = {'wbc': {f.name: np.asarray(getattr(base, f.name)).tolist()
                      for f in dataclasses.fields(base)},
              'sim': {'contact_threshold': CONTACT_THRESHOLD}}
    here = {f'{node}.{name}' for node, names in values.items() for name in names}
    derived = derived_parameters(
        facts, ref, values,
        {'rules': {scale: [k for k in keys if k in here]
                   for scale, keys in rules.get('rules', {}).items()}}, measure=False)
    wbc = derived.get('wbc', {})
    params = dataclasses.replace(base, **{
        name: np.asarray(value) if isinstance(getattr(base, name), np.ndarray) else value
        for name, value in wbc.items()})
    length = SCALES['length'](facts) / SCALES['length'](ref)
    time_scale = SCALES['time'](facts) / SCALES['time'](ref)
    crawl = {'step_length': 0.08 * length, 'step_height': 0.06 * length,
             'shift_time': 0.8 * time_scale, 'swing_time': 0.6 * time_scale}
    names = {'joint_names': spec.joints, 'foot_frames': spec.feet,
             'foot_offset': spec.foot_offset,
             'initial_joint_positions': np.asarray(spec.standing_pose, dtype=float)}
    return WbcBenchRobot(str(spec.urdf), names, (spec.joints, spec.feet), params,
                         derived.get('sim', {}).get('contact_threshold', CONTACT_THRESHOLD),
                         crawl)


def run(urdf: str, cycles: int, quiet: bool = False,
        robot: WbcBenchRobot | None = None) -> dict[str, float]:
    """Closed-loop crawl; returns timing figures (s) and tracking figures (m)."""
    from replan_core.robot.model import RobotModel
    from replan_core.sim.world import SimWorld
    from replan_core.wbc.controller import PlanFollower, WholeBodyController
    from replan_core.wbc.settings import WbcParams

    robot = robot or WbcBenchRobot(urdf)
    world = SimWorld(robot.urdf, contact_threshold=robot.contact_threshold, **robot.names)
    try:
        model = RobotModel(robot.urdf, *robot.model_names)
        wbc = WholeBodyController(model, robot.params)
        base, joints, contacts = world.base_state(), world.joint_state(), world.contact_state()
        com0 = model.com_state(base, joints)[0]
        footholds, com_plan = crawl_plan(0.5, contacts.foot_position, com0, cycles=cycles,
                                         **robot.crawl)
        haptic_velocity = (robot.params or WbcParams()).haptic_velocity
        follower = PlanFollower(footholds, com_plan, haptic_velocity=haptic_velocity)
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
        final = model.com_state(world.base_state(), world.joint_state())[0]
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
    parser.add_argument('--urdf', default=default_urdf(root))
    parser.add_argument('--cycles', type=int, default=2, help='crawl cycles (4 steps each)')
    parser.add_argument('--robot', default='', help='a robot file: a name of config/robots/ '
                        '(go1) or a path (default: HyQ from --urdf)')
    parser.add_argument('--root', default=str(root), help='the project (config/robots/)')
    args = parser.parse_args()
    robot = None
    if args.robot:
        from replan_core.bench import bench_robots
        from replan_core.robot.robot_file import RobotFileError
        try:
            spec, reference, rules = bench_robots(args.robot, Path(args.root))
        except RobotFileError as err:
            raise SystemExit(f'config error: {err}') from None
        robot = bench_robot(spec, reference, rules)
        print(f'robot {spec.name}: fz {robot.params.fz_min:.1f}-{robot.params.fz_max:.0f} N, '
              f'swing kp {robot.params.swing_kp[0]:.0f} N/m, step '
              f'{robot.crawl["step_length"]:.3f} m in {robot.crawl["swing_time"]:.2f} s')
    run(args.urdf, args.cycles, robot=robot)


def closed_loop_crawl(world, urdf: str, ticks: int, dt: float):
    """The closed-loop benches' rig on ``world`` (a ``SimWorld`` standing HyQ): the
    controller, the estimator (default settings, period ``dt`` s) and a plan follower of a
    crawl long enough for ``ticks`` control ticks."""
    from replan_core.estimation.estimator import StateEstimator
    from replan_core.estimation.settings import EstimatorParams
    from replan_core.robot.model import RobotModel
    from replan_core.wbc.controller import PlanFollower, WholeBodyController

    robot = RobotModel(urdf)
    wbc = WholeBodyController(robot)
    estimator = StateEstimator(robot, EstimatorParams(), dt)
    base, joints, contacts = world.base_state(), world.joint_state(), world.contact_state()
    com0 = robot.com_state(base, joints)[0]
    cycles = int(np.ceil(ticks * dt / 5.6)) + 1        # 5.6 s per crawl cycle
    footholds, com_plan = crawl_plan(0.5, contacts.foot_position, com0, cycles=cycles)
    return wbc, estimator, PlanFollower(footholds, com_plan)


if __name__ == '__main__':
    main()
