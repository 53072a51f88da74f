#!/usr/bin/env bash
# What rclpy costs the lock-step chain on this machine: executor cost per message with and
# without QoS-event handlers, and a sim/controller-like round trip with 0 or 2 bystander
# processes, spun or read on demand. Prints one JSON line (replan_ros/tools/bench_rclpy.py).
#   scripts/bench_rclpy.sh [--rounds N]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.bench_rclpy "$@"
