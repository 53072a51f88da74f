#!/usr/bin/env bash
# Start sim, gait, mpc, wbc (and the recorder with --record DIR), supervise, stop cleanly.
#   scripts/launch.sh [--gui] [--record DIR] [--params FILE ...] [--duration SIM_SECONDS]
#                     [--no-respawn] [--run-dir DIR]
# Ctrl-C stops every node (SIGINT, then SIGKILL after 10 s). Logs: <run folder>/logs/<node>.log
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.launch_graph "$@"
