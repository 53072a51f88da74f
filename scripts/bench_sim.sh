#!/usr/bin/env bash
# Speed of the bare PyBullet world (replan_core.sim.world.SimWorld): simulated seconds per wall
# second. The robot stands under a joint PD (cheap numpy, included), with and without the
# per-tick state queries the sim node makes; best of 3 runs (the machine is shared).
# The last row is the realistic world, every realism option on: actuator lag, delay and joint
# friction, compliant feet, the perturbed URDF (payload, leg masses), and per tick imu_truth,
# the IMU and joint sensor models (the PD then reads the sensed joints) and the state queries.
# --robot NAME|FILE: another robot (a robot file), gains and payload scaled from HyQ's.
# Usage: scripts/bench_sim.sh [SIM_SECONDS] [--robot NAME|FILE]   (default 4 s, HyQ)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
seconds=4
robot=()
while [ $# -gt 0 ]; do
    case "$1" in
        -h|--help) usage; exit 0 ;;
        --robot) [ $# -ge 2 ] || { echo "bench_sim.sh: --robot needs a name" >&2; exit 2; }
                 robot=(--robot "$2"); shift ;;
        -*) echo "bench_sim.sh: unknown option $1" >&2; usage >&2; exit 2 ;;
        *) seconds="$1" ;;
    esac
    shift
done
replan_env
python -m replan_core.bench.sim_bench "$seconds" "${robot[@]}" --root "$ROOT" 2>&1 \
    | grep -v -e '^argv' -e 'build time'
exit "${PIPESTATUS[0]}"
