#!/usr/bin/env bash
# Whether docs/results.md and docs/robots.md come from runs of this checkout's code: one line
# per page (its runs' code fingerprint against today's; the command that makes it again).
# Exit code 0 when both are current, 1 when one is not.
#   Usage: scripts/pages_status.sh
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
cd "$ROOT"
exec python -m replan_experiments.page_status "$@"
