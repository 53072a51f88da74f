#!/usr/bin/env bash
# Speed of the lock-step graph against its targets, every figure from one run of this command:
# physics alone, the graph walking (ideal, realistic, + recorder, + live view with a viewer),
# the MPC alone and inside the graph; one table with a verdict per target (--json: one JSON
# line of everything). Rounds are interleaved so ratios are measured under one load.
# Usage: scripts/bench_speed.sh [--runs N] [--duration S] [--out DIR] [--json]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_ros.benchmarks.bench_speed "$@"
