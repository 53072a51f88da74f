#!/usr/bin/env bash
# Publish a velocity set-point on /cmd_vel.
# Usage: scripts/cmd_vel.sh VX VY WZ [--for SECONDS] [--rate HZ] [--wait SECONDS]
# VX, VY in m/s (body frame), WZ in rad/s. Without --for it publishes until Ctrl-C. The time
# counts once the gait node subscribes (waits up to --wait wall s, default 10).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_ros.tools.cmd_vel "$@"
