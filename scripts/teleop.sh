#!/usr/bin/env bash
# Drive the robot from the keyboard (like teleop_twist_keyboard): geometry_msgs/Twist on
# cmd_vel at 10 Hz. w/s or Up/Down: vx; a/d or Left/Right: vy; q/e: yaw; +/-: increment;
# space: stop; x or Ctrl-C: send zero and quit. Limits from config/gait.yaml. Needs a terminal.
# Usage: scripts/teleop.sh [--rate HZ] [--gait-config FILE]
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
exec python -m replan_ros.tools.teleop "$@"
