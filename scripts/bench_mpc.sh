#!/usr/bin/env bash
# Benchmark of the LIP-ZMP re-planner: 200 consecutive re-plans of a crawl at the paper's size
# (8 s horizon, 40 ms samples, 8 footholds). Prints progress-free; the last line is one JSON
# object (n_per_axis, n_constraints, cold_ms, median_ms, p99_ms, max_zmp_violation_m, ...).
# Extra arguments go to the benchmark, e.g. --formulation dense, --no-warm, --proxsuite-dual.
# Usage: scripts/bench_mpc.sh [--formulation F] [--no-warm] [--replans N] ...  (--help: all)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; }
# Help needs no set-up (the tool's own --help, with every option, needs the venv).
if [ ! -f "$ROOT/install/setup.bash" ]; then
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
# proxsuite's OpenMP threads spin while waiting; on 2 shared cores that costs up to 10x in
# latency for these small QPs (measured), so the benchmark runs single-threaded.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
exec python -m replan_core.bench.mpc_bench "$@"
