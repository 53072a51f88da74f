#!/usr/bin/env bash
# Push the robot.
# Usage: scripts/push.sh FX FY FZ --duration S [--torque MX MY MZ] [--delay S]
# Force in N (world axes) on the trunk at the base origin, for S seconds of sim time, starting
# at the current sim time (read from /clock). Prints what it sent.
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_ros.tools.push "$@"
