#!/usr/bin/env bash
# The whole test suite: ruff, the package unit tests (colcon test, per-package pytest
# arguments from colcon.meta) and the node-graph tests in test/ (real processes on a reserved
# ROS_DOMAIN_ID). Exit code 0 only if everything passed.
# Usage: scripts/test.sh [--slow] [-- PYTEST_ARGS]
#   ./scripts/test.sh            everything but tests marked slow
#   ./scripts/test.sh --slow     everything
#   ./scripts/test.sh -- ARGS    extra pytest arguments for test/ (e.g. -k sim)
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
cd "$ROOT"
marker=(-m "not slow")
extra=()
while [ $# -gt 0 ]; do
    case "$1" in
        -h|--help) usage; exit 0 ;;
        --slow) marker=(); shift ;;
        --) shift; extra=("$@"); break ;;
        *) echo "test.sh: unknown argument $1" >&2; usage >&2; exit 2 ;;
    esac
done
start=$(date +%s)
./scripts/setup.sh --with-ray      # Ray: test/test_ray.py runs the experiments on a cluster
echo "test: setup took $(( $(date +%s) - start )) s"
# shellcheck disable=SC1091
source scripts/env.sh

echo "test: ruff"
ruff check src test

echo "test: package unit tests (colcon test)"
rm -rf build/*/pytest.xml log/test
colcon --log-base log test --base-paths src --metas colcon.meta \
    --event-handlers console_direct+ ${marker[@]+--pytest-args "${marker[@]}"}
colcon --log-base log test-result --test-result-base build --verbose

echo "test: node-graph tests (pytest test/)"
# --durations: the slowest tests in every log, to keep the whole run under its 40 minutes.
# Two modules at a time (-n 2, a module's tests in one worker: its fixtures are shared): each
# worker reserves its own ROS_DOMAIN_ID (test/harness.py), so their graphs never meet.
# `-- -n 0` runs them one at a time.
python -m pytest test -n 2 --dist loadfile ${marker[@]+"${marker[@]}"} ${extra[@]+"${extra[@]}"} \
    -o console_output_style=classic -rfE --durations=15
