#!/usr/bin/env bash
# Publish a velocity set-point on /cmd_vel: scripts/cmd_vel.sh VX VY WZ [--for SECONDS]
# VX, VY in m/s (body frame), WZ in rad/s. Without --for it publishes until Ctrl-C.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.cmd_vel "$@"
