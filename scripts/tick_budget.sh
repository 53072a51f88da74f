#!/usr/bin/env bash
# Per-tick cost budget of the lock-step loop: runs the graph headless and prints one table
# (phase, ms per tick, share of the tick) and the real-time factor (docs/ARCHITECTURE.md,
# "Per-tick budget").
# Usage: scripts/tick_budget.sh [--profile realistic|ideal] [--record] [--duration S]
#                               [--scenario FILE] [--params FILE ...] [--out DIR] [--json]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; }
if [ ! -f "$ROOT/install/setup.bash" ]; then
    # Help needs no set-up and must not start one (the tool's own --help needs the venv).
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    "$ROOT/scripts/setup.sh"
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.tick_budget "$@"
