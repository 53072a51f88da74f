#!/usr/bin/env bash
# Whole-graph benchmark: the forward scenario (0.15 m/s, 22 s of sim time) headless, lock-step,
# 1 kHz physics, 250 Hz control, recorder on; prints one JSON line: real-time factor (sim s per
# wall s, from the first tick), peak memory of all nodes, MPC solve times, distance.
#   scripts/bench_graph.sh [OUT_DIR]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
out="${1:-$(mktemp -d)/bench_graph}"
"$ROOT/scripts/scenario.sh" "$ROOT/config/scenarios/forward.yaml" --out "$out" >/dev/null
python - "$out/metrics.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
keys = ['completed', 'fell', 'sim_time_s', 'wall_time_s', 'real_time_factor',
        'launcher_real_time_factor', 'peak_memory_total_mb', 'peak_memory_mb',
        'mpc_solve_ms_median', 'mpc_solve_ms_p99', 'replans', 'distance_m']
print(json.dumps({k: m.get(k) for k in keys}))
PY
