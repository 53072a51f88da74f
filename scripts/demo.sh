#!/usr/bin/env bash
# The main job: set up if needed, then run the demo scenario headless (30 s of sim time:
# forward, sideways, turn, stop) and print a summary with where the bag and plots are.
# Usage: scripts/demo.sh [OUT_DIR]   (default runs/demo-<time>)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,4p' "$0" | sed 's/^# \{0,1\}//'; }
# Options first, before any set-up: an option is never taken for the output folder.
for arg in "$@"; do
    case "$arg" in
        -h|--help) usage; exit 0 ;;
        -*) echo "demo.sh: unknown option $arg" >&2; usage >&2; exit 2 ;;
    esac
done
cd "$ROOT"
./scripts/setup.sh
out="${1:-runs/demo-$(date +%Y%m%d-%H%M%S)}"
exec ./scripts/scenario.sh config/scenarios/demo.yaml --out "$out"
