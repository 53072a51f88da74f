#!/usr/bin/env bash
# Where the CPU goes in the running graph: starts scripts/launch.sh (extra arguments are passed
# on, e.g. --record DIR), lets it settle, then over a window of wall time prints each node's
# share of one core (from /proc) and the control ticks per second (from /clock).
#   scripts/profile_graph.sh [--window SECONDS] [LAUNCH_ARGS ...]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
window=10
if [ "${1:-}" = "--window" ]; then window="$2"; shift 2; fi
run_dir="$(mktemp -d)"
"$ROOT/scripts/launch.sh" --duration 600 --run-dir "$run_dir" "$@" > "$run_dir/launch.log" 2>&1 &
launch_pid=$!
trap 'kill -INT "$launch_pid" 2>/dev/null; wait "$launch_pid" 2>/dev/null || true' EXIT
sleep 12                                     # start-up and the first steps
declare -A before
pids=$(pgrep -f "lib/replan_ros/[a-z_]+_node" || true)
[ -n "$pids" ] || { echo "profile_graph: no node is running (see $run_dir)" >&2; exit 1; }
for pid in $pids; do before[$pid]=$(awk '{print $14 + $15}' "/proc/$pid/stat"); done
clock_rate=$(python -m replan_ros.tools.topic_probe hz /clock --window "$window" \
             | sed -n 's/.*: \([0-9.]*\) Hz.*/\1/p')
for pid in $pids; do
    [ -r "/proc/$pid/stat" ] || continue
    after=$(awk '{print $14 + $15}' "/proc/$pid/stat")
    name=$(tr '\0' ' ' < "/proc/$pid/cmdline" | grep -o 'lib/replan_ros/[a-z_]*' | cut -d/ -f3)
    awk -v n="$name" -v a="$after" -v b="${before[$pid]}" -v w="$window" -v hz="$(getconf CLK_TCK)" \
        'BEGIN { printf "%-14s %5.1f %% of a core\n", n, (a - b) / hz / w * 100 }'
done
awk -v r="${clock_rate:-0}" -v clock="$(sed -n 's/ *clock_period: *//p' "$ROOT/config/sim.yaml")" \
    -v tick="$(sed -n 's/ *control_period: *//p' "$ROOT/config/sim.yaml")" \
    'BEGIN { t = r * clock / tick; printf "control ticks   %.0f per s (real-time factor %.2f)\n", t, t * tick }'
