#!/usr/bin/env bash
# Push the robot.
# Usage: scripts/push.sh FX FY FZ --duration S [--torque MX MY MZ] [--delay S]
# Force in N (world axes) on the trunk at the base origin, for S seconds of sim time, starting
# at the current sim time (read from /clock). Prints what it sent.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; }
# Help needs no set-up (the tool's own --help, with every option, needs the venv).
if [ ! -f "$ROOT/install/setup.bash" ]; then
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.push "$@"
