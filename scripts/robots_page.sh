#!/usr/bin/env bash
# The robots page: per robot its facts, derived parameters and what it does on the
# realistic profile (speed against set-point, standing drift, largest lateral push, blind step
# down, real-time factor, MPC solve time), and the same in each other gait of the plan (trot,
# walking trot), from scenario runs; writes docs/robots.md.
# Usage: scripts/robots_page.sh [--quick] [--jobs N] [--robot NAME ...] [--out DIR] [--page FILE]
# --quick: the plan's quick section (one short run of each kind), page in DIR/robots.md.
# --robot NAME: only this robot of config/robots_page.yaml (repeatable).
# Runs made before with the same scenario and code are read from DIR (default runs/robots_page).
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
cd "$ROOT"
exec python -m replan_experiments.robots_page "$@"
