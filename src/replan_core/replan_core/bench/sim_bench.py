"""Speed of the bare PyBullet world (``SimWorld``), no ROS: simulated seconds per wall second.

The robot stands under a joint PD (cheap numpy, included), with and without the per-tick state
queries the sim node makes (base state, contact forces); best of ``repeats`` runs (the machine
may be shared). The realistic case has every realism option on: actuator lag, delay and joint
friction, compliant feet, the perturbed URDF (payload, leg masses), and per tick ``imu_truth``,
the IMU and joint sensor models (the PD then reads the sensed joints) and the state queries.
It is the physics-only factor that ``scripts/bench_speed.sh`` compares the graph with.

    python -m replan_core.bench.sim_bench [SIM_SECONDS]      (scripts/bench_sim.sh)
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from replan_core.robot_variant import perturbed_urdf
from replan_core.sensors import REALISTIC_IMU, REALISTIC_JOINTS, ImuSensor, JointSensor
from replan_core.sim_world import (
    REALISTIC_ACTUATOR,
    REALISTIC_CONTACT_DAMPING,
    REALISTIC_CONTACT_STIFFNESS,
    STANDING_POSE,
    SimWorld,
)

PD_GAINS = (300.0, 10.0)          # N m/rad, N m s/rad: holds the standing pose


def physics_rtf(urdf: str, *, terrain: str = 'flat', query: bool = True,
                realistic: bool = False, sim_seconds: float = 4.0,
                repeats: int = 3) -> tuple[float, float]:
    """(sim s per wall s, wall µs per control tick) of the best of ``repeats`` runs."""
    if realistic:
        urdf = perturbed_urdf(urdf, payload_mass=5.0, payload_offset=(0.10, 0.05, 0.05),
                              leg_mass_error=0.10, seed=0)
    kp, kd = PD_GAINS
    best, ticks = np.inf, 1
    for _ in range(repeats):
        if realistic:
            world = SimWorld(urdf, terrain=terrain, actuator=REALISTIC_ACTUATOR,
                             contact_stiffness=REALISTIC_CONTACT_STIFFNESS,
                             contact_damping=REALISTIC_CONTACT_DAMPING)
            imu = ImuSensor(REALISTIC_IMU, world.control_period, 0)
            encoders = JointSensor(REALISTIC_JOINTS, world.control_period, 0)
        else:
            world = SimWorld(urdf, terrain=terrain)
        ticks = round(sim_seconds / world.control_period)
        start = time.perf_counter()
        for _ in range(ticks):
            joints = world.joint_state()
            if realistic:
                joints = encoders.measure(joints)
                imu.measure(world.time, *world.imu_truth())
            world.step(kp * (STANDING_POSE - joints.position) - kd * joints.velocity)
            if query:
                world.base_state()
                world.contact_state()
        best = min(best, time.perf_counter() - start)
        world.close()
    return sim_seconds / best, best / ticks * 1e6


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('sim_seconds', nargs='?', type=float, default=4.0)
    args = parser.parse_args(argv)
    urdf = os.environ['REPLAN_URDF']
    cases = [(terrain, query, False) for terrain in ('flat', 'rough') for query in (False, True)]
    cases.append(('flat', True, True))
    for terrain, query, realistic in cases:
        rtf, us = physics_rtf(urdf, terrain=terrain, query=query, realistic=realistic,
                              sim_seconds=args.sim_seconds)
        label = 'all realism on' if realistic else f'state queries {"yes" if query else "no"}'
        print(f'terrain {terrain:5s}, {label:18s}: {rtf:5.1f} sim s per wall s '
              f'({us:4.0f} us per 4 ms tick)')


if __name__ == '__main__':
    main()
