# The one preamble of the scripts, sourced first: source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
# Gives ROOT (the repository), usage (the script's header comment: line 2 to the first line
# that is not a comment), help_before_setup "$@" (answers -h/--help with usage while nothing is
# set up, and starts no set-up: the tools' own --help needs the venv) and replan_env (the set-up
# if it is missing, scripts/setup.sh, then the environment, scripts/env.sh) and claim_domain
# (a script that starts a graph claims its ROS_DOMAIN_ID first: one graph per domain).
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
claim_domain() {
    # Held until this script's process (and what it execs) ends: replan_ros/launch/domain.py.
    # claim_domain "$@": a call for -h/--help starts no graph and claims nothing.
    case " $* " in *" -h "*|*" --help "*) return 0 ;; esac
    local domain="${ROS_DOMAIN_ID:-0}" lock
    [ "${REPLAN_DOMAIN_HELD:-}" = "$domain" ] && return 0     # the caller holds it
    lock="$(python -m replan_ros.launch.domain path "$domain")" || exit 2
    exec {REPLAN_DOMAIN_FD}>>"$lock"
    if ! flock -n "$REPLAN_DOMAIN_FD"; then
        printf '%s: another graph runs on ROS_DOMAIN_ID %s (its claim %s is held): two graphs on one domain mix their topics; give this one its own: ROS_DOMAIN_ID=N %s ...\n' \
            "$(basename "$0")" "$domain" "$lock" "$(basename "$0")" >&2
        exit 3
    fi
    export REPLAN_DOMAIN_HELD="$domain"
}
