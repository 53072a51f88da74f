#!/usr/bin/env bash
# Start sim, gait, mpc, wbc (and the recorder with --record DIR), supervise, stop cleanly.
# Usage: scripts/launch.sh [--gui] [--record DIR] [--params FILE ...] [--duration SIM_SECONDS]
#                          [--no-respawn] [--run-dir DIR] [--profile NAME] [--live [PORT]]
#                          [--robot NAME|FILE]
# Ctrl-C stops every node (SIGINT, then SIGKILL after 10 s). Logs: <run folder>/logs/<node>.log
# --robot: a name of config/robots/ (default hyq; the list: ls config/robots) or a robot file
#          (docs/robot_files.md); its parameters are derived from HyQ's by the scaling rules.
# --live [PORT]: watch it in Foxglove/Lichtblick at ws://localhost:PORT (default 8765).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_ros.launch.launch_graph "$@"
