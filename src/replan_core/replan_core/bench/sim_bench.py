"""Speed of the bare PyBullet world (``SimWorld``), no ROS: simulated seconds per wall second.

The robot stands under a joint PD (cheap numpy, included), with and without the per-tick state
queries the sim node makes (base state, contact forces); best of ``repeats`` runs (the machine
may be shared). The realistic case has every realism option on: actuator lag, delay and joint
friction, compliant feet, the perturbed URDF (payload, leg masses), and per tick ``imu_truth``,
the IMU and joint sensor models (the PD then reads the sensed joints) and the state queries.
It is the physics-only factor that ``scripts/bench_speed.sh`` compares the graph with.

    python -m replan_core.bench.sim_bench [SIM_SECONDS] [--robot NAME|FILE --root DIR]
                                                             (scripts/bench_sim.sh)

Another robot (``--robot``, a robot file): its model, names and standing pose; the PD gains,
the realistic payload and its offset scaled from HyQ's by the rules of the robot files
(``config/robots/scaling.yaml``: gains with m g l, payload with m g, offset with l).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from replan_core.bench import bench_robots
from replan_core.common.types import BASE_FRAME, FOOT_FRAMES, JOINT_NAMES
from replan_core.robot.robot_file import RobotSpec, robot_facts
from replan_core.robot.scaling import SCALES, derived_parameters
from replan_core.robot.variant import perturbed_urdf
from replan_core.sim.sensors import REALISTIC_IMU, REALISTIC_JOINTS, ImuSensor, JointSensor
from replan_core.sim.settings import (
    REALISTIC_ACTUATOR,
    REALISTIC_CONTACT_DAMPING,
    REALISTIC_CONTACT_STIFFNESS,
)
from replan_core.sim.world import STANDING_POSE, SimWorld

PD_GAINS = (300.0, 10.0)          # N m/rad, N m s/rad: holds HyQ's standing pose
PAYLOAD = (5.0, (0.10, 0.05, 0.05))   # kg, m: the realistic payload on HyQ's trunk


@dataclass(frozen=True)
class BenchRobot:
    """What the bench needs of a robot: HyQ's values, or another's scaled from them."""

    urdf: str
    joints: tuple[str, ...] = JOINT_NAMES
    feet: tuple[str, ...] = FOOT_FRAMES
    foot_offset: np.ndarray | None = None
    root_link: str = BASE_FRAME
    standing_pose: np.ndarray = field(default_factory=lambda: STANDING_POSE.copy())
    pd_gains: tuple[float, float] = PD_GAINS
    payload_mass: float = PAYLOAD[0]
    payload_offset: tuple[float, float, float] = PAYLOAD[1]


def bench_robot(spec: RobotSpec, reference: RobotSpec, rules: dict) -> BenchRobot:
    """``spec``'s robot with the reference robot's (HyQ's) PD gains and payload scaled to it:
    the payload by ``rules`` (config/robots/scaling.yaml), the bench's own PD hold like a joint
    stiffness (m g l) and damping (m g l sqrt(l / g))."""
    facts, ref = robot_facts(spec), robot_facts(reference)
    payload = derived_parameters(
        facts, ref, {'sim': {'payload_mass': PAYLOAD[0], 'payload_offset': list(PAYLOAD[1])}},
        {'rules': {scale: [k for k in keys if k in ('sim.payload_mass', 'sim.payload_offset')]
                   for scale, keys in rules.get('rules', {}).items()}}, measure=False)['sim']
    torque = SCALES['torque'](facts) / SCALES['torque'](ref)
    time_scale = SCALES['time'](facts) / SCALES['time'](ref)
    kp, kd = PD_GAINS
    return BenchRobot(str(spec.urdf), spec.joints, spec.feet, spec.foot_offset, spec.root_link,
                      np.asarray(spec.standing_pose, dtype=float),
                      (kp * torque, kd * torque * time_scale), payload['payload_mass'],
                      tuple(payload['payload_offset']))


def physics_rtf(urdf: str, *, terrain: str = 'flat', query: bool = True,
                realistic: bool = False, sim_seconds: float = 4.0,
                repeats: int = 3, robot: BenchRobot | None = None) -> tuple[float, float]:
    """(sim s per wall s, wall µs per control tick) of the best of ``repeats`` runs; ``robot``
    (None: HyQ from ``urdf``)."""
    robot = robot or BenchRobot(urdf)
    urdf = robot.urdf
    if realistic:
        urdf = perturbed_urdf(urdf, payload_mass=robot.payload_mass,
                              payload_offset=robot.payload_offset, leg_mass_error=0.10, seed=0,
                              base_link=robot.root_link)
    kp, kd = robot.pd_gains
    names = dict(joint_names=robot.joints, foot_frames=robot.feet,
                 foot_offset=robot.foot_offset, initial_joint_positions=robot.standing_pose)
    best, ticks = np.inf, 1
    for _ in range(repeats):
        if realistic:
            world = SimWorld(urdf, terrain=terrain, actuator=REALISTIC_ACTUATOR,
                             contact_stiffness=REALISTIC_CONTACT_STIFFNESS,
                             contact_damping=REALISTIC_CONTACT_DAMPING, **names)
            imu = ImuSensor(REALISTIC_IMU, world.control_period, 0)
            encoders = JointSensor(REALISTIC_JOINTS, world.control_period, 0)
        else:
            world = SimWorld(urdf, terrain=terrain, **names)
        ticks = round(sim_seconds / world.control_period)
        start = time.perf_counter()
        for _ in range(ticks):
            joints = world.joint_state()
            if realistic:
                joints = encoders.measure(joints)
                imu.measure(world.time, *world.imu_truth())
            world.step(kp * (robot.standing_pose - joints.position) - kd * joints.velocity)
            if query:
                world.base_state()
                world.contact_state()
        best = min(best, time.perf_counter() - start)
        world.close()
    return sim_seconds / best, best / ticks * 1e6


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('sim_seconds', nargs='?', type=float, default=4.0)
    parser.add_argument('--robot', default='', help='a robot file: a name of '
                        'config/robots/ (go1) or a path (default: HyQ from $REPLAN_URDF)')
    parser.add_argument('--root', default='.', help='the project (its config/ and urdf/)')
    args = parser.parse_args(argv)
    urdf = os.environ.get('REPLAN_URDF', '')
    robot = None
    if args.robot:
        root = Path(args.root)
        try:
            spec, reference, rules = bench_robots(args.robot, root)
        except ValueError as err:            # RobotFileError: one line naming file and key
            print(f'config error: {err}', file=sys.stderr)
            raise SystemExit(2) from None
        robot = bench_robot(spec, reference, rules)
        print(f'robot {spec.name}: PD {robot.pd_gains[0]:.1f} N m/rad, '
              f'{robot.pd_gains[1]:.2f} N m s/rad; realistic payload {robot.payload_mass:.2f} kg')
    cases = [(terrain, query, False) for terrain in ('flat', 'rough') for query in (False, True)]
    cases.append(('flat', True, True))
    for terrain, query, realistic in cases:
        rtf, us = physics_rtf(urdf, terrain=terrain, query=query, realistic=realistic,
                              sim_seconds=args.sim_seconds, robot=robot)
        label = 'all realism on' if realistic else f'state queries {"yes" if query else "no"}'
        print(f'terrain {terrain:5s}, {label:18s}: {rtf:5.1f} sim s per wall s '
              f'({us:4.0f} us per 4 ms tick)')


if __name__ == '__main__':
    main()
