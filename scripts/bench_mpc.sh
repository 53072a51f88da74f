#!/usr/bin/env bash
# Benchmark of the LIP-ZMP re-planner: 200 consecutive re-plans of a crawl at the paper's size
# (8 s horizon, 40 ms samples, 8 footholds). Prints progress-free; the last line is one JSON
# object (n_per_axis, n_constraints, cold_ms, median_ms, p99_ms, max_zmp_violation_m, ...).
# Extra arguments go to the benchmark, e.g. --formulation dense, --no-warm, --proxsuite-dual.
# --robot NAME|FILE: another robot's crawl (a robot file; default hyq): its standing feet, the
# timing scaled by sqrt(l / g), the set-points by sqrt(g l), its CoM height.
# Usage: scripts/bench_mpc.sh [--formulation F] [--no-warm] [--replans N] [--robot NAME] ...
#        (--help: all)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_core.bench.mpc_bench --root "$ROOT" "$@"
