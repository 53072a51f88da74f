#!/usr/bin/env bash
# The main job: set up if needed, then run the demo scenario headless (30 s of sim time:
# forward, sideways, turn, stop) and print a summary with where the bag and plots are.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
./scripts/setup.sh
out="${1:-runs/demo-$(date +%Y%m%d-%H%M%S)}"
exec ./scripts/scenario.sh config/scenarios/demo.yaml --out "$out"
