#!/usr/bin/env bash
# Whole-graph benchmark, headless, lock-step, 1 kHz physics, 250 Hz control. Two runs:
#  1. the four nodes alone (scripts/launch.sh --duration 20: the robot steps in place);
#  2. the forward scenario (0.15 m/s, 22 s of sim time) with the recorder on, as users run it.
# Prints one JSON line: real-time factors (sim s per wall s, from the first tick), peak memory
# of the nodes, MPC solve times, distance.   Usage: scripts/bench_graph.sh [OUT_DIR]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
out="${1:-$(mktemp -d)/bench_graph}"
mkdir -p "$out"
"$ROOT/scripts/launch.sh" --duration 20 --run-dir "$out/graph" > "$out/graph.log" 2>&1
"$ROOT/scripts/scenario.sh" "$ROOT/config/scenarios/forward.yaml" --out "$out/forward" >/dev/null
python - "$out" <<'PY'
import json, re, sys
from pathlib import Path
out = Path(sys.argv[1])
line = next(l for l in (out / 'graph.log').read_text().splitlines() if 'real-time factor' in l)
rtf, memory = re.search(r'real-time factor ([0-9.]+).*peak memory ([0-9]+) MB', line).groups()
m = json.loads((out / 'forward' / 'metrics.json').read_text())
print(json.dumps({
    'four_nodes_real_time_factor': float(rtf), 'four_nodes_peak_memory_mb': float(memory),
    'walk_with_recorder_real_time_factor': m.get('real_time_factor'),
    'walk_peak_memory_total_mb': m.get('peak_memory_total_mb'),
    'walk_peak_memory_mb': m.get('peak_memory_mb'), 'walk_fell': m.get('fell'),
    'walk_mpc_solve_ms_median': m.get('mpc_solve_ms_median'),
    'walk_mpc_solve_ms_p99': m.get('mpc_solve_ms_p99'), 'walk_distance_m': m.get('distance_m')}))
PY
