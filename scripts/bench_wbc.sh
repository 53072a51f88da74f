#!/usr/bin/env bash
# Whole-body controller benchmark: median and p99 computation time per 250 Hz control tick on
# a closed-loop PyBullet run (static crawl, haptic steps). Target: median <= 1 ms.
# --robot NAME|FILE: another robot (a robot file), controller values and crawl scaled from HyQ's.
# Usage: scripts/bench_wbc.sh [--cycles N] [--urdf PATH] [--robot NAME|FILE]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
python -m replan_core.bench.wbc_bench "$@" 2>&1 | grep -v -e "^argv" -e "build time"
