#!/usr/bin/env bash
# Start sim, gait, mpc, wbc (and the recorder with --record DIR), supervise, stop cleanly.
# Usage: scripts/launch.sh [--gui] [--record DIR] [--params FILE ...] [--duration SIM_SECONDS]
#                          [--no-respawn] [--run-dir DIR] [--profile NAME] [--live [PORT]]
# Ctrl-C stops every node (SIGINT, then SIGKILL after 10 s). Logs: <run folder>/logs/<node>.log
# --live [PORT]: watch it in Foxglove/Lichtblick at ws://localhost:PORT (default 8765).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; }
if [ ! -f "$ROOT/install/setup.bash" ]; then
    # Help needs no set-up and must not start one (the tool's own --help needs the venv).
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    "$ROOT/scripts/setup.sh"
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.launch_graph "$@"
