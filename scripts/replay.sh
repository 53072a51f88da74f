#!/usr/bin/env bash
# Replay a bag with its original timing (and its /clock, for use_sim_time nodes).
# Usage: scripts/replay.sh BAG [--topics T ...] [--rate R] [--loop] [--delay S] [--no-clock]
#            [--wait-subscribers S]
#        scripts/replay.sh BAG --info
# BAG: an .mcap file or a bag directory (its files read as one); a killed recorder's file is
# recovered on the way (one line).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
if [ $# -lt 1 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
    usage
    [ $# -lt 1 ] && exit 2 || exit 0
fi
replan_env
case " $* " in *" --info "*) ;; *) claim_domain "$@" ;; esac     # --info: no publisher
exec "$REPLAN_ROOT/install/replan_ros/lib/replan_ros/replay" "$@"
