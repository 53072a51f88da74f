#!/usr/bin/env bash
# Publish a velocity set-point on /cmd_vel.
# Usage: scripts/cmd_vel.sh VX VY WZ [--for SECONDS] [--rate HZ] [--wait SECONDS]
# VX, VY in m/s (body frame), WZ in rad/s. Without --for it publishes until Ctrl-C. The time
# counts once the gait node subscribes (waits up to --wait wall s, default 10).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; }
if [ ! -f "$ROOT/install/setup.bash" ]; then
    # Help needs no set-up and must not start one (the tool's own --help needs the venv).
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    "$ROOT/scripts/setup.sh"
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.cmd_vel "$@"
