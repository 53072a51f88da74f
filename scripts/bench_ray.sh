#!/usr/bin/env bash
# Wall time of the quick experiments with the local runner (--jobs 2) and as Ray tasks on a
# private cluster (--ray local --jobs 2), each into a fresh folder, in one command; prints both
# and their ratio (the target: --ray local at most 10 % slower). Both run in a network
# namespace with only the loopback up, so no cluster traffic leaves the machine (needs root or
# user namespaces). Needs Ray: scripts/setup.sh --with-ray.
# Usage: scripts/bench_ray.sh [--out DIR] [--jobs N] [--domain-base ID]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_experiments.benchmarks.bench_ray "$@"
