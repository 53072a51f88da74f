#!/usr/bin/env bash
# The main job: set up if needed, then run the demo scenario headless (36 s of sim time:
# a crawl forward, sideways and turning, then a trot, then stop) and print a summary with
# where the bag and plots are.
# Usage: scripts/demo.sh [OUT_DIR] [--live [PORT]] [--robot NAME|FILE]   (default runs/demo-<time>)
#   --robot: a name of config/robots/ (default hyq) or a robot file (docs/robot_files.md)
#   --live [PORT]: watch it in Foxglove/Lichtblick at ws://localhost:PORT (default 8765)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
# Options first, before any set-up: an option is never taken for the output folder.
live=()
robot=()
positional=()
while [ $# -gt 0 ]; do
    case "$1" in
        -h|--help) usage; exit 0 ;;
        --live)
            if [[ "${2:-}" =~ ^[0-9]+$ ]]; then live=(--live "$2"); shift; else live=(--live); fi ;;
        --robot) robot=(--robot "${2:-}"); shift ;;
        -*) echo "demo.sh: unknown option $1" >&2; usage >&2; exit 2 ;;
        *) positional+=("$1") ;;
    esac
    shift
done
cd "$ROOT"
./scripts/setup.sh
out="${positional[0]:-runs/demo-$(date +%Y%m%d-%H%M%S)}"
exec ./scripts/scenario.sh config/scenarios/demo.yaml --out "$out" ${live[@]+"${live[@]}"} \
    ${robot[@]+"${robot[@]}"}
