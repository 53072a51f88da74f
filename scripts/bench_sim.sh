#!/usr/bin/env bash
# Speed of the bare PyBullet world (replan_core.sim_world.SimWorld): simulated seconds per wall
# second, stepping with zero torques, without and with the per-tick state queries the sim node
# makes. Usage: scripts/bench_sim.sh [SIM_SECONDS]   (default 5)
set -euo pipefail
# shellcheck disable=SC1091
source "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/env.sh"
python - "${1:-5}" <<'PY'
import os
import sys
import time

import numpy as np

from replan_core.sim_world import SimWorld

sim_seconds = float(sys.argv[1])
for terrain in ('flat', 'rough'):
    for query in (False, True):
        world = SimWorld(os.environ['REPLAN_URDF'], terrain=terrain)
        ticks = round(sim_seconds / world.control_period)
        zero = np.zeros(12)
        start = time.perf_counter()
        for _ in range(ticks):
            world.step(zero)
            if query:
                world.base_state()
                world.joint_state()
                world.contact_state()
        wall = time.perf_counter() - start
        world.close()
        print(f'terrain {terrain:5s} state queries {"yes" if query else "no ":3s}: '
              f'{sim_seconds / wall:6.1f} sim s per wall s '
              f'({wall / ticks * 1e6:6.0f} us per 4 ms tick, {ticks} ticks)')
PY
