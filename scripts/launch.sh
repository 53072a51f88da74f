#!/usr/bin/env bash
# Start sim, gait, mpc, wbc (and the recorder with --record DIR), supervise, stop cleanly.
# Usage: scripts/launch.sh [--gui] [--record DIR] [--params FILE ...] [--duration SIM_SECONDS]
#                          [--no-respawn] [--run-dir DIR] [--profile NAME] [--live [PORT]]
# Ctrl-C stops every node (SIGINT, then SIGKILL after 10 s). Logs: <run folder>/logs/<node>.log
# --live [PORT]: watch it in Foxglove/Lichtblick at ws://localhost:PORT (default 8765).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_ros.launch.launch_graph "$@"
