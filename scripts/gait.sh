#!/usr/bin/env bash
# Switch the walking robot's gait: publish a gait's name on /gait_command.
# Usage: scripts/gait.sh NAME [--wait SECONDS] [--timeout SECONDS]
# NAME is a gait of config/gaits/ (crawl, walking_trot, trot). The gait node switches at the
# next step boundary and says so on /gait_in_force, which this waits for (--timeout wall s).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_ros.tools.gait_command "$@"
