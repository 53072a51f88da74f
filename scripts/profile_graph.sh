#!/usr/bin/env bash
# Where the CPU goes in the running graph: starts scripts/launch.sh (extra arguments are passed
# on, e.g. --record DIR), lets it settle, then over a window of wall time prints each node's
# share of one core (from /proc) and the control ticks per second (from /clock).
# Usage: scripts/profile_graph.sh [--window SECONDS] [LAUNCH_ARGS ...]   (scripts/launch.sh -h)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
for arg in "$@"; do
    case "$arg" in -h|--help) usage; exit 0 ;; esac
done
replan_env
claim_domain "$@"
window=10
if [ "${1:-}" = "--window" ]; then window="$2"; shift 2; fi
run_dir="$(mktemp -d)"
"$ROOT/scripts/launch.sh" --duration 600 --run-dir "$run_dir" "$@" > "$run_dir/launch.log" 2>&1 &
launch_pid=$!
trap 'kill -INT "$launch_pid" 2>/dev/null; wait "$launch_pid" 2>/dev/null || true' EXIT
# Start-up and the first steps. The launcher checks LAUNCH_ARGS itself: if it ends meanwhile
# (an unknown option: its usage, exit 2), say so now rather than after the wait.
for _ in $(seq 24); do
    if ! kill -0 "$launch_pid" 2>/dev/null; then
        status=0
        wait "$launch_pid" || status=$?
        trap - EXIT
        cat "$run_dir/launch.log" >&2
        if [ "$status" -eq 2 ]; then usage >&2; rm -rf "$run_dir"; exit 2; fi
        echo "profile_graph: launch.sh ended during start-up, exit $status (see $run_dir)" >&2
        exit 1
    fi
    sleep 0.5
done
declare -A before
pids=$(pgrep -f "lib/replan_ros/[a-z_]+_node" || true)
[ -n "$pids" ] || { echo "profile_graph: no node is running (see $run_dir)" >&2; exit 1; }
for pid in $pids; do before[$pid]=$(awk '{print $14 + $15}' "/proc/$pid/stat"); done
clock_rate=$(python -m replan_ros.tools.topic hz /clock --duration "$window" \
             | sed -n 's/^average rate: \([0-9.]*\)$/\1/p' | tail -n 1)
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
