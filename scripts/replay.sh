#!/usr/bin/env bash
# Replay a bag with its original timing (and its /clock, for use_sim_time nodes).
# Usage: scripts/replay.sh BAG [--topics T ...] [--rate R] [--loop] [--delay S] [--no-clock]
#            [--wait-subscribers S]
#        scripts/replay.sh BAG --info
set -euo pipefail
if [ $# -lt 1 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
    sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'
    [ $# -lt 1 ] && exit 2 || exit 0
fi
# shellcheck disable=SC1091
source "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/env.sh"
exec "$REPLAN_ROOT/install/replan_ros/lib/replan_ros/replay" "$@"
