#!/usr/bin/env bash
# The paper's experiments on the realistic robot, many runs per claim; writes docs/results.md.
# Usage: scripts/experiments.sh [--quick | --pilot] [--jobs N | --ray ADDRESS] [--only NAME ...]
#                               [--out DIR] [--fresh] [--robot NAME|FILE]
# --robot NAME|FILE: every scenario runs that robot (a top-level robot: key); the plan's sizes
#   (set-points, impulses, terrains) stay the plan file's.
# --quick: one short run of each kind (a few minutes), page in DIR/results.md (CI runs it).
# --pilot: each pre-registered claim on its pilot seeds, page in DIR/results-pilot.md, no
#   verdicts (the pilot sets n; its runs never enter a verdict: docs/usage.md).
# --ray ADDRESS: every run a task on a Ray cluster (auto, HOST:PORT, ray://HOST:10001, or local
#   for a private one); start it with `ray start --head --resources='{"graph_slot": 2}'` and
#   `ray start --address=HEAD:6379 ...` on each node (docs/cluster.md; scripts/setup.sh --with-ray).
# Runs made before with the same scenario are read from DIR (default runs/experiments).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
cd "$ROOT"
exec python -m replan_experiments.runner "$@"
