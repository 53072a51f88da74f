#!/usr/bin/env bash
# Soak benchmark (issue 15): 10 min of sim time walking with changing set-points and pushes on
# the realistic profile; reports falls, memory growth after warm-up, solve and tick time trends.
# Usage: scripts/soak.sh [--duration SIM_S] [--out DIR] [--profile NAME] ...  (see --help)
# On a shared machine: flock /tmp/graph.lock scripts/soak.sh   (one graph at a time)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; }
if [ ! -f "$ROOT/install/setup.bash" ]; then
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    "$ROOT/scripts/setup.sh"
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.soak "$@"
