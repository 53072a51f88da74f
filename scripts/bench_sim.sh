#!/usr/bin/env bash
# Speed of the bare PyBullet world (replan_core.sim_world.SimWorld): simulated seconds per wall
# second. The robot stands under a joint PD (cheap numpy, included), with and without the
# per-tick state queries the sim node makes; best of 3 runs (the machine is shared).
# The last row is the realistic world, every realism option on: actuator lag, delay and joint
# friction, compliant feet, the perturbed URDF (payload, leg masses), and per tick imu_truth,
# the IMU and joint sensor models (the PD then reads the sensed joints) and the state queries.
# Usage: scripts/bench_sim.sh [SIM_SECONDS]   (default 4)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
for arg in "$@"; do
    case "$arg" in
        -h|--help) usage; exit 0 ;;
        -*) echo "bench_sim.sh: unknown option $arg" >&2; usage >&2; exit 2 ;;
    esac
done
replan_env
python -m replan_core.bench.sim_bench "${1:-4}" 2>&1 | grep -v -e '^argv' -e 'build time'
