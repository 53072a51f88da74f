#!/usr/bin/env bash
# Soak benchmark: 10 min of sim time walking with changing set-points and pushes on
# the realistic profile; reports falls, memory growth after warm-up, solve and tick time trends.
# Usage: scripts/soak.sh [--duration SIM_S] [--out DIR] [--profile NAME] ...  (see --help)
# On a shared machine: flock /tmp/graph.lock scripts/soak.sh   (one graph at a time)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_experiments.soak "$@"
