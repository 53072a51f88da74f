#!/usr/bin/env bash
# Re-run a recorded bag (same inputs, same configuration) and compare the base trajectory.
# Usage: scripts/rerun.sh BAG [--out DIR] [--tolerance M] [--gui]
# Prints the largest base position deviation (m) and whether every message of the run is
# bit-identical; exit 0 if the deviation is within tolerance (default 0 m: runs are bit-exact).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; }
# Help needs no set-up (the tool's own --help, with every option, needs the venv).
if [ ! -f "$ROOT/install/setup.bash" ]; then
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.rerun "$@"
