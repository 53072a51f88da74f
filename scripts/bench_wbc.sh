#!/usr/bin/env bash
# Whole-body controller benchmark: median and p99 computation time per 250 Hz control tick on
# a closed-loop PyBullet run (static crawl, haptic steps). Target: median <= 1 ms.
# Usage: scripts/bench_wbc.sh [--cycles N] [--urdf PATH]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,4p' "$0" | sed 's/^# \{0,1\}//'; }
# Help needs no set-up (the tool's own --help, with every option, needs the venv).
if [ ! -f "$ROOT/install/setup.bash" ]; then
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
python -m replan_core.bench.wbc_bench "$@" 2>&1 | grep -v -e "^argv" -e "build time"
