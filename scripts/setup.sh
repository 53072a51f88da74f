#!/usr/bin/env bash
# Idempotent set-up: .venv with python3.11, the pinned requirements, colcon build.
# A second run with nothing changed takes a few seconds.
# Usage: scripts/setup.sh [--deps-only] [--with-ray]
#   --deps-only   only the .venv and requirements.txt, no colcon build: it needs no more than
#                 requirements.txt and this script (docker/Dockerfile's cached wheels layer)
#   --with-ray    also requirements-ray.txt: Ray, for experiments.sh --ray (docs/cluster.md)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; }
deps_only=false
with_ray=false
while [ $# -gt 0 ]; do
    case "$1" in
        -h|--help) usage; exit 0 ;;
        --deps-only) deps_only=true; shift ;;
        --with-ray) with_ray=true; shift ;;
        *) echo "setup.sh: unknown argument $1" >&2; usage >&2; exit 2 ;;
    esac
done
cd "$ROOT"
PYTHON="${PYTHON:-python3.11}"
STAMP_DIR=.venv/.replan
say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: %s\n' "$*" >&2; exit 1; }

# Prerequisites, each reported in one line.
command -v "$PYTHON" >/dev/null 2>&1 \
    || die "missing $PYTHON (install Python 3.11, e.g. apt-get install python3.11 python3.11-venv)"
"$PYTHON" -c 'import sys; assert sys.version_info[:2] == (3, 11)' 2>/dev/null \
    || die "$PYTHON is not Python 3.11 (the ROS 2 Jazzy wheels need exactly 3.11)"
"$PYTHON" -c 'import venv, ensurepip' 2>/dev/null \
    || die "the venv module is missing (apt-get install python3.11-venv)"
free_mb=$(df -Pm . | awk 'NR==2 {print $4}')
[ "${free_mb:-0}" -ge 2048 ] || die "only ${free_mb} MB free on disk here; need 2048 MB"

hash_of() { sha256sum "$@" | sha256sum | cut -c1-16; }

if [ ! -x .venv/bin/python ]; then
    say "creating .venv with $PYTHON"
    "$PYTHON" -m venv .venv
fi
mkdir -p "$STAMP_DIR"
req_hash=$(hash_of requirements.txt)
if [ "$(cat "$STAMP_DIR/requirements" 2>/dev/null)" != "$req_hash" ]; then
    say "installing requirements.txt"
    .venv/bin/python -m pip install --quiet --disable-pip-version-check -r requirements.txt
    echo "$req_hash" > "$STAMP_DIR/requirements"
else
    say "requirements up to date"
fi
# Optional: Ray, only when asked; a later set-up without the flag leaves it installed.
if $with_ray; then
    ray_hash=$(hash_of requirements-ray.txt)
    if [ "$(cat "$STAMP_DIR/requirements-ray" 2>/dev/null)" != "$ray_hash" ]; then
        say "installing requirements-ray.txt"
        .venv/bin/python -m pip install --quiet --disable-pip-version-check -r requirements-ray.txt
        echo "$ray_hash" > "$STAMP_DIR/requirements-ray"
    else
        say "requirements-ray up to date"
    fi
fi
if $deps_only; then
    say "dependencies ready (--deps-only: no colcon build)"
    exit 0
fi

# Rebuild only when a package's manifest or setup files changed: --symlink-install links the
# package folders, so editing or adding a module needs no rebuild.
build_hash=$( (find src -name package.xml -o -name setup.py -o -name setup.cfg | sort | xargs cat;
               cat colcon.meta) | sha256sum | cut -c1-16)
if [ ! -f install/setup.bash ] || [ "$(cat "$STAMP_DIR/build" 2>/dev/null)" != "$build_hash" ]; then
    say "colcon build"
    (
        # shellcheck disable=SC1091
        source .venv/bin/activate
        colcon --log-base log build --symlink-install --base-paths src --metas colcon.meta --event-handlers console_cohesion- \
            >"$STAMP_DIR/colcon.log" 2>&1 || { cat "$STAMP_DIR/colcon.log" >&2; exit 1; }
    )
    echo "$build_hash" > "$STAMP_DIR/build"
else
    say "workspace up to date"
fi
say "ready (source scripts/env.sh to use it)"
