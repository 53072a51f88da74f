#!/usr/bin/env bash
# Run a scenario headless: scripts/scenario.sh FILE.yaml [--out DIR] [--gui] [--params FILE ...]
# Writes DIR/bag (mcap), DIR/metrics.json, DIR/*.png and the node logs in DIR/logs.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.scenario "$@"
