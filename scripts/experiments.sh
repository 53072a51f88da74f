#!/usr/bin/env bash
# The paper's experiments on the realistic robot, many runs per claim; writes docs/results.md.
# Usage: scripts/experiments.sh [--quick] [--jobs N] [--only NAME ...] [--out DIR] [--fresh]
# --quick: one short run of each kind (a few minutes), page in DIR/results.md (CI runs it).
# Runs made before with the same scenario are read from DIR (default runs/experiments).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; }
if [ ! -f "$ROOT/install/setup.bash" ]; then
    case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    "$ROOT/scripts/setup.sh"
fi
# shellcheck disable=SC1091
source "$ROOT/scripts/env.sh"
# The QP timing runs single-threaded (see scripts/bench_mpc.sh), and so do the graphs' MPCs.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
cd "$ROOT"
exec python -m replan_ros.tools.experiments "$@"
