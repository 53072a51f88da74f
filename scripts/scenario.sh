#!/usr/bin/env bash
# Run a scenario headless.
# Usage: scripts/scenario.sh FILE.yaml [--out DIR] [--gui] [--params FILE ...] [--profile NAME]
#                            [--live [PORT]]
# Writes DIR/bag (mcap), DIR/metrics.json, DIR/*.png and the node logs in DIR/logs.
# --live [PORT]: watch it in Foxglove/Lichtblick at ws://localhost:PORT (default 8765).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; }
if [ ! -f "$ROOT/install/setup.bash" ]; then
    # Help needs no set-up and must not start one (the tool's own --help needs the venv).
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    "$ROOT/scripts/setup.sh"
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.scenario "$@"
