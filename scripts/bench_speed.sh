#!/usr/bin/env bash
# Speed of the lock-step graph against its targets, every figure from one run of this command:
# physics alone, the graph walking (ideal, realistic, + recorder, + live view with a viewer),
# the MPC alone and inside the graph; one table with a verdict per target (--json: one JSON
# line of everything; --page FILE: the run's Markdown page, docs/speed.md). Rounds are
# interleaved so ratios are measured under one load.
# --robot NAME|FILE: the robot of every part (default hyq; config/robots/, docs/robot_files.md):
# physics alone with its gains and payload scaled from HyQ's, the graph with its derived
# parameters (the forward set-point stays 0.15 m/s), the MPC benchmark on its crawl; a wrong
# robot stops with one "config error:" line before anything runs.
# Usage: scripts/bench_speed.sh [--runs N] [--duration S] [--robot NAME|FILE] [--out DIR]
#                               [--json] [--page FILE]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_experiments.benchmarks.bench_speed "$@"
