#!/usr/bin/env bash
# Speed of the lock-step graph against its targets, every figure from one run of this command:
# physics alone, the graph walking (ideal, realistic, + recorder, + live view with a viewer),
# the MPC alone and inside the graph; one table with a verdict per target (--json: one JSON
# line of everything). Rounds are interleaved so ratios are measured under one load.
# Usage: scripts/bench_speed.sh [--runs N] [--duration S] [--out DIR] [--json]
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
exec python -m replan_ros.tools.bench_speed "$@"
