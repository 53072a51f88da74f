#!/usr/bin/env bash
# Drive the robot from the keyboard (like teleop_twist_keyboard): geometry_msgs/Twist on
# cmd_vel at 10 Hz. w/s or Up/Down: vx; a/d or Left/Right: vy; q/e: yaw; +/-: increment;
# space: stop; x or Ctrl-C: send zero and quit. Limits from config/gait.yaml. Needs a terminal.
# Usage: scripts/teleop.sh [--rate HZ] [--gait NAME|FILE]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_ros.tools.teleop "$@"
