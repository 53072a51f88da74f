#!/usr/bin/env bash
# Each realism element of the realistic profile switched on alone, on one walk with a push:
# a markdown table of the measured CoP margin, velocity error, pitch and touchdown timing.
#   scripts/realism_table.sh [--scenario FILE] [--runs N] [--out DIR] [--write-doc docs/realism.md]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_experiments.realism_table "$@"
