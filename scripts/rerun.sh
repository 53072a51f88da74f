#!/usr/bin/env bash
# Re-run a recorded bag (same inputs, same configuration) and compare the base trajectory.
# Usage: scripts/rerun.sh BAG [--out DIR] [--tolerance M] [--gui]
# Prints the largest base position deviation (m) and whether every message of the run is
# bit-identical; exit 0 if the deviation is within tolerance (default 0 m: runs are bit-exact).
# BAG: an .mcap file or a bag directory (its files read as one); a killed recorder's file is
# recovered on the way (one line).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
claim_domain "$@"
exec python -m replan_ros.tools.reproduce "$@"
