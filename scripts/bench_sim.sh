#!/usr/bin/env bash
# Speed of the bare PyBullet world (replan_core.sim_world.SimWorld): simulated seconds per wall
# second. The robot stands under a joint PD (cheap numpy, included), with and without the
# per-tick state queries the sim node makes; best of 3 runs (the machine is shared).
# The last row is the realistic world, every realism option on: actuator lag, delay and joint
# friction, compliant feet, the perturbed URDF (payload, leg masses), and per tick imu_truth,
# the IMU and joint sensor models (the PD then reads the sensed joints) and the state queries.
# Usage: scripts/bench_sim.sh [SIM_SECONDS]   (default 4)
set -euo pipefail
usage() { sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; }
for arg in "$@"; do
    case "$arg" in
        -h|--help) usage; exit 0 ;;
        -*) echo "bench_sim.sh: unknown option $arg" >&2; usage >&2; exit 2 ;;
    esac
done
# shellcheck disable=SC1091
source "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/env.sh"
python - "${1:-4}" <<'PY' 2>&1 | grep -v -e '^argv' -e 'build time'
import os
import sys
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

sim_seconds = float(sys.argv[1])
urdf = os.environ['REPLAN_URDF']
variant = perturbed_urdf(urdf, payload_mass=5.0, payload_offset=(0.10, 0.05, 0.05),
                         leg_mass_error=0.10, seed=0)
cases = [(terrain, query, False) for terrain in ('flat', 'rough') for query in (False, True)]
cases.append(('flat', True, True))
for terrain, query, realistic in cases:
    best = np.inf
    for _ in range(3):
        if realistic:
            world = SimWorld(variant, terrain=terrain, actuator=REALISTIC_ACTUATOR,
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
            world.step(300.0 * (STANDING_POSE - joints.position) - 10.0 * joints.velocity)
            if query:
                world.base_state()
                world.contact_state()
        best = min(best, time.perf_counter() - start)
        world.close()
    label = 'all realism on' if realistic else f'state queries {"yes" if query else "no"}'
    print(f'terrain {terrain:5s}, {label:18s}: {sim_seconds / best:5.1f} sim s per wall s '
          f'({best / ticks * 1e6:4.0f} us per {world.control_period * 1e3:g} ms tick)')
PY
