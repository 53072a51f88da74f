#!/usr/bin/env bash
# Reproduce the paper's comparisons (section VI) and print one table:
# forward (replan window 1, haptic on) vs replan window 2 vs haptic off, and a lateral push
# with vs without foothold correction.
# Usage: scripts/paper_results.sh [OUT_DIR]   (default runs/paper-<time>)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
# Options first, before any set-up: an option is never taken for the output folder.
for arg in "$@"; do
    case "$arg" in
        -h|--help) usage; exit 0 ;;
        -*) echo "paper_results.sh: unknown option $arg" >&2; usage >&2; exit 2 ;;
    esac
done
replan_env
claim_domain "$@"
out="${1:-$ROOT/runs/paper-$(date +%Y%m%d-%H%M%S)}"
runs=()
for name in forward paper_replan_window_2 paper_haptic_off push paper_push_no_correction; do
    "$ROOT/scripts/scenario.sh" "$ROOT/config/scenarios/$name.yaml" --out "$out/$name" \
        | grep -E '^\[scenario\] [a-z_0-9]+: ' || true
    runs+=("$out/$name")
done
python -m replan_experiments.compare_runs "${runs[@]}" | tee "$out/table.md"
