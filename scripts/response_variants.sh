#!/usr/bin/env bash
# A setting's effect on the response to set-point changes: each robot's response run of the
# robots page with parameters overridden, on noise seeds, per set-point each whole cycle opened
# by each leg, judged as the page judges them (docs/gait.md).
#   scripts/response_variants.sh [--set NODE.KEY=VALUE ...] [--robot NAME ...] [--seed N ...]
#                                [--phase K ...] [--jobs N] [--out DIR]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_experiments.response_variants "$@"
