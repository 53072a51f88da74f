#!/usr/bin/env bash
# Speed of the bare PyBullet world (replan_core.sim_world.SimWorld): simulated seconds per wall
# second. The robot stands under a joint PD (cheap numpy, included), with and without the
# per-tick state queries the sim node makes; best of 3 runs (the machine is shared).
# Usage: scripts/bench_sim.sh [SIM_SECONDS]   (default 4)
set -euo pipefail
# shellcheck disable=SC1091
source "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/env.sh"
python - "${1:-4}" <<'PY' 2>&1 | grep -v -e '^argv' -e 'build time'
import os
import sys
import time

import numpy as np

from replan_core.sim_world import STANDING_POSE, SimWorld

sim_seconds = float(sys.argv[1])
for terrain in ('flat', 'rough'):
    for query in (False, True):
        best = np.inf
        for _ in range(3):
            world = SimWorld(os.environ['REPLAN_URDF'], terrain=terrain)
            ticks = round(sim_seconds / world.control_period)
            start = time.perf_counter()
            for _ in range(ticks):
                joints = world.joint_state()
                world.step(300.0 * (STANDING_POSE - joints.position) - 10.0 * joints.velocity)
                if query:
                    world.base_state()
                    world.contact_state()
            best = min(best, time.perf_counter() - start)
            world.close()
        print(f'terrain {terrain:5s}, state queries {"yes" if query else "no ":3s}: '
              f'{sim_seconds / best:5.1f} sim s per wall s '
              f'({best / ticks * 1e6:4.0f} us per {world.control_period * 1e3:g} ms tick)')
PY
