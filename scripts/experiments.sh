#!/usr/bin/env bash
# The paper's experiments on the realistic robot, many runs per claim; writes docs/results.md.
# Usage: scripts/experiments.sh [--quick] [--jobs N] [--only NAME ...] [--out DIR] [--fresh]
# --quick: one short run of each kind (a few minutes), page in DIR/results.md (CI runs it).
# Runs made before with the same scenario are read from DIR (default runs/experiments).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
cd "$ROOT"
exec python -m replan_ros.experiments.runner "$@"
