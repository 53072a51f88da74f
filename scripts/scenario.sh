#!/usr/bin/env bash
# Run a scenario headless.
# Usage: scripts/scenario.sh FILE.yaml [--out DIR] [--gui] [--params FILE ...] [--profile NAME]
#                            [--live [PORT]] [--robot NAME|FILE]
# Writes DIR/bag (mcap), DIR/metrics.json, DIR/*.png and the node logs in DIR/logs.
# --robot: instead of the scenario's robot: key (default hyq); docs/robot_files.md.
# --live [PORT]: watch it in Foxglove/Lichtblick at ws://localhost:PORT (default 8765).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_experiments.scenario "$@"
