#!/usr/bin/env bash
# What rclpy costs the lock-step chain on this machine: executor cost per message with and
# without QoS-event handlers, and a sim/controller-like round trip with 0 or 2 bystander
# processes, spun or read on demand. Prints one JSON line (replan_experiments/benchmarks/bench_rclpy.py).
# Usage: scripts/bench_rclpy.sh [--rounds N]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_experiments.benchmarks.bench_rclpy "$@"
