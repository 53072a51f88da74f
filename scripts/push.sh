#!/usr/bin/env bash
# Push the robot: scripts/push.sh FX FY FZ --duration S [--torque MX MY MZ] [--delay S]
# Force in N (world axes) on the trunk at the base origin, for S seconds of sim time, starting
# at the current sim time (read from /clock). Prints what it sent.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.push "$@"
