#!/usr/bin/env bash
# What a run's gait did, from its bag: each touchdown sensed against the true contact, the step
# periods, and each whole cycle's speed split into the feet's strides, the trunk's place over
# them and its place about the reference of the change (docs/gait.md).
#   scripts/gait_report.sh RUN_DIR [--after S] [--late S]
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_experiments.gait_report "$@"
