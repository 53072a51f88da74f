#!/usr/bin/env bash
# Each realism element of the realistic profile switched on alone, on one walk with a push:
# a markdown table of the measured CoP margin, velocity error, pitch and touchdown timing.
#   scripts/realism_table.sh [--scenario FILE] [--runs N] [--out DIR] [--write-doc docs/realism.md]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
case "${1:-}" in
    -h|--help) ;;
    *) [ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh" ;;
esac
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
exec python -m replan_ros.tools.realism_table "$@"
