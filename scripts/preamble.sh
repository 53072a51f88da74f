# The one preamble of the scripts, sourced first: source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
# Gives ROOT (the repository), usage (the script's header comment: line 2 to the first line
# that is not a comment), help_before_setup "$@" (answers -h/--help with usage while nothing is
# set up, and starts no set-up: the tools' own --help needs the venv) and replan_env (the set-up
# if it is missing, scripts/setup.sh, then the environment, scripts/env.sh).
# scripts/setup.sh stands alone: the Docker image runs it before anything else is copied.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
usage() { awk 'NR == 1 { next } /^#/ { sub(/^# ?/, ""); print; next } { exit }' "$0"; }
help_before_setup() {
    if [ ! -f "$ROOT/install/setup.bash" ]; then
        case " $* " in *" -h "*|*" --help "*) usage; exit 0 ;; esac
    fi
}
replan_env() {
    [ -f "$ROOT/install/setup.bash" ] || "$ROOT/scripts/setup.sh"
    # shellcheck disable=SC1091
    source "$ROOT/scripts/env.sh"
}
