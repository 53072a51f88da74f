#!/usr/bin/env bash
# Per-tick cost budget of the lock-step loop: runs the graph headless and prints one table
# (phase, ms per tick, share of the tick) and the real-time factor (docs/ARCHITECTURE.md,
# "Per-tick budget").
# Usage: scripts/tick_budget.sh [--profile realistic|ideal] [--record] [--duration S]
#                               [--scenario FILE] [--params FILE ...] [--out DIR] [--json]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_experiments.benchmarks.tick_table "$@"
