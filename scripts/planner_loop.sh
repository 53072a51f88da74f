#!/usr/bin/env bash
# The planner alone in a closed loop: the gait's footholds and the LIP MPC re-planned at every
# planned touchdown, the trunk exactly on the MPC's plan (no dynamics, controller or DDS): the
# mean velocity of each crawl cycle after the last set-point change, in seconds.
# Usage: scripts/planner_loop.sh [--robot NAME|FILE] [--at T VX VY WZ ...] [--duration S]
#                                [--late S] [--set gait.KEY=VALUE ...] [--json]   (--help: all)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_experiments.planner_loop "$@"
