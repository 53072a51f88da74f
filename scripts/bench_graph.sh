#!/usr/bin/env bash
# Whole-graph benchmark, headless, lock-step, 1 kHz physics, 250 Hz control, RUNS times each
# (default 3: on a shared 2-core VM one run varies by +-0.2 in real-time factor), the two
# profiles interleaved in every round so that their ratio is measured under the same load:
#  1. the four nodes alone (scripts/launch.sh --duration 20: zero set-point, so the robot steps
#     in place for one crawl cycle and then stands: idle stance, docs/gait.md), ideal
#     and realistic profile;
#  2. the robot's forward walk with the recorder on, as users run it, ideal and realistic:
#     config/scenarios/<robot>_forward.yaml where the robot has one (its robot-appropriate
#     set-point, e.g. Go1 0.05 m/s), else forward.yaml (0.15 m/s); 22 s of sim time
#     (bench_speed.walk_scenario, which bench_speed.sh walks too).
# Prints one JSON line: real-time factors (sim s per wall s, from the first tick; median, min,
# max and every run) per profile, the realistic/ideal ratio of each round, peak memory, MPC
# solve times, distance.
#   Usage: scripts/bench_graph.sh [--runs N] [--robot NAME|FILE] [--gait NAME] [OUT_DIR]
#   --robot: the robot of every run (default hyq; config/robots/, docs/robot_files.md).
#   --gait: the gait of every run (default crawl; config/gaits/); with trot the walk is the
#     robot's config/scenarios/<robot>_trot.yaml (Froude 0.02, then a stop), where it has one.
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
runs=3
robot=hyq
gait=crawl
while [ $# -gt 0 ]; do
    case "$1" in
        -h|--help) usage; exit 0 ;;
        --runs) runs="$2"; shift 2 ;;
        --robot) robot="$2"; shift 2 ;;
        --gait) gait="$2"; shift 2 ;;
        -*) echo "bench_graph.sh: unknown option $1" >&2; usage >&2; exit 2 ;;
        *) break ;;
    esac
done
replan_env
claim_domain "$@"
out="${1:-$(mktemp -d)/bench_graph}"
mkdir -p "$out"
# The robot's walk; a robot that cannot be used stops here in one line, before any run.
walk=$(python -c 'import sys
from replan_core.robot.robot_file import RobotFileError
from replan_experiments.benchmarks.bench_speed import walk_scenario
try:
    print(walk_scenario(sys.argv[1]))
except RobotFileError as err:
    print(f"config error: {err}", file=sys.stderr)
    sys.exit(2)' "$robot") || exit 2
if [ -f "$ROOT/config/scenarios/${robot}_$gait.yaml" ]; then
    walk="$ROOT/config/scenarios/${robot}_$gait.yaml"
fi
for k in $(seq 1 "$runs"); do
    for profile in ideal realistic; do
        "$ROOT/scripts/launch.sh" --profile "$profile" --robot "$robot" --gait "$gait" --duration 20 \
            --run-dir "$out/graph_${profile}_$k" > "$out/graph_${profile}_$k.log" 2>&1
        "$ROOT/scripts/scenario.sh" "$walk" --profile "$profile" \
            --robot "$robot" --gait "$gait" --out "$out/forward_${profile}_$k" >/dev/null
    done
done
python - "$out" "$runs" "$robot" "$walk" "$gait" <<'PY'
import json, re, statistics, sys
from pathlib import Path
out, runs = Path(sys.argv[1]), int(sys.argv[2])

def summary(values):
    return {'median': round(statistics.median(values), 3), 'min': min(values),
            'max': max(values), 'runs': values}

result = {'robot': sys.argv[3], 'gait': sys.argv[5], 'walk_scenario': Path(sys.argv[4]).name}
for profile in ('ideal', 'realistic'):
    rtf, memory = [], []
    for k in range(1, runs + 1):
        line = next(l for l in (out / f'graph_{profile}_{k}.log').read_text().splitlines()
                    if 'real-time factor' in l)
        r, m = re.search(r'real-time factor ([0-9.]+).*peak memory ([0-9]+) MB', line).groups()
        rtf.append(float(r))
        memory.append(float(m))
    walks = [json.loads((out / f'forward_{profile}_{k}' / 'metrics.json').read_text())
             for k in range(1, runs + 1)]
    last = walks[-1]
    result[profile] = {
        'four_nodes_real_time_factor': summary(rtf),
        'four_nodes_peak_memory_mb': max(memory),
        'walk_with_recorder_real_time_factor': summary(
            [round(w['real_time_factor'], 3) for w in walks]),
        'walk_peak_memory_total_mb': max(w.get('peak_memory_total_mb', 0.0) for w in walks),
        'walk_peak_memory_mb': last.get('peak_memory_mb'),
        'walk_fell': any(w.get('fell') for w in walks),
        'walk_mpc_solve_ms_median': last.get('mpc_solve_ms_median'),
        'walk_mpc_solve_ms_p99': last.get('mpc_solve_ms_p99'),
        'walk_distance_m': last.get('distance_m')}
for key in ('four_nodes_real_time_factor', 'walk_with_recorder_real_time_factor'):
    ratios = [round(r / i, 3) for r, i in zip(result['realistic'][key]['runs'],
                                                result['ideal'][key]['runs'])]
    result[f'realistic_over_ideal_{key}'] = summary(ratios)
print(json.dumps(result))
PY
