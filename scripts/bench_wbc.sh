#!/usr/bin/env bash
# Whole-body controller benchmark: median and p99 computation time per 250 Hz control tick on
# a closed-loop PyBullet run (static crawl, haptic steps). Target: median <= 1 ms.
# Usage: scripts/bench_wbc.sh [--cycles N] [--urdf PATH]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
python -m replan_core.bench.wbc_bench "$@" 2>&1 | grep -v -e "^argv" -e "build time"
