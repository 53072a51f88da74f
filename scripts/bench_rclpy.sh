#!/usr/bin/env bash
# What rclpy costs the lock-step chain on this machine: executor cost per message with and
# without QoS-event handlers, and a sim/controller-like round trip with 0 or 2 bystander
# processes, spun or read on demand. Prints one JSON line (replan_ros/tools/bench_rclpy.py).
# Usage: scripts/bench_rclpy.sh [--rounds N]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; }
if [ ! -f "$ROOT/install/setup.bash" ]; then
    # Help needs no set-up and must not start one (the tool's own --help needs the venv).
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    "$ROOT/scripts/setup.sh"
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.bench_rclpy "$@"
