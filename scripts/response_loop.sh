#!/usr/bin/env bash
# The robots page's response runs through the gait's and the MPC's cores alone (no simulator,
# controller or DDS), every phase of the changes, each leg's forward and sideways cycles judged
# as docs/robots.md judges them: a setting's effect on the response in seconds (docs/gait.md).
#   scripts/response_loop.sh [--set NODE.KEY=VALUE ...] [--robot NAME ...] [--phase K ...]
#                            [--late S] [--steps]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_experiments.response_loop "$@"
