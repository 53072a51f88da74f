# Sourced by every script: the venv, the colcon overlay and safe DDS defaults.
# Usage: source scripts/env.sh   (from any directory)
REPLAN_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export REPLAN_ROOT
if [ ! -f "$REPLAN_ROOT/.venv/bin/activate" ] || [ ! -f "$REPLAN_ROOT/install/setup.bash" ]; then
    echo "replan: not set up yet; run $REPLAN_ROOT/scripts/setup.sh" >&2
    return 1 2>/dev/null || exit 1
fi
# shellcheck disable=SC1091
source "$REPLAN_ROOT/.venv/bin/activate"
# colcon's setup scripts read unset variables; relax nounset while sourcing them.
_replan_nounset=$(set -o | awk '$1=="nounset"{print $2}')
set +u
# shellcheck disable=SC1091
source "$REPLAN_ROOT/install/setup.bash"
[ "$_replan_nounset" = "on" ] && set -u
unset _replan_nounset
# Never talk to other machines unless the user asks for it: Fast DDS over UDP on the loopback,
# no shared memory (config/dds/fastdds.xml says why). SYSTEM_DEFAULT leaves the transports to
# that profile; LOCALHOST would add shared memory (docs/usage.md, "DDS").
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-SYSTEM_DEFAULT}"
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
# The loopback transport above, and reliable writers that announce what they sent every 100 ms
# (Fast DDS: every 3 s), so a sample lost in transport is sent again before a run's end stops
# its writer (docs/recording.md, "The end of a run").
export FASTRTPS_DEFAULT_PROFILES_FILE="${FASTRTPS_DEFAULT_PROFILES_FILE:-$REPLAN_ROOT/config/dds/fastdds.xml}"
export PYTHONUNBUFFERED=1
# proxsuite's OpenMP threads spin on a 2-core machine shared with the simulator; one thread
# halves the MPC's p99 and makes cold solves 10x faster here (docs/mpc.md).
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
# One thread for every numeric library the nodes load (numpy's and scipy's OpenBLAS, any MKL):
# a fixed thread count is one condition of bit-exact runs (docs/ARCHITECTURE.md, "Bit-exact
# runs"), and the nodes' matrices are far below the sizes where more threads pay on 2 cores.
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
# The same BLAS kernels on every machine: OpenBLAS picks them by CPU model, and its Zen and
# SkylakeX kernels give other last bits (the crawl's plans differ between an AMD EPYC and an
# Intel Xeon). SkylakeX's where the CPU has AVX-512, else Haswell's (AVX2): runs are bit-exact
# across the machines of each class (docs/ARCHITECTURE.md, "Bit-exact runs").
if [ -z "${OPENBLAS_CORETYPE:-}" ]; then
    if grep -qw avx512f /proc/cpuinfo 2>/dev/null; then
        export OPENBLAS_CORETYPE=SkylakeX
    else
        export OPENBLAS_CORETYPE=Haswell
    fi
fi
export MKL_NUM_THREADS="${MKL_NUM_THREADS:-1}"
# The interface packages of the ROS wheels live in the venv prefix: make them findable by
# ament_index (get_package_share_directory('sensor_msgs'), used for the bag schemas).
case ":${AMENT_PREFIX_PATH:-}:" in
    *":$VIRTUAL_ENV:"*) ;;
    *) export AMENT_PREFIX_PATH="${AMENT_PREFIX_PATH:+$AMENT_PREFIX_PATH:}$VIRTUAL_ENV" ;;
esac
export REPLAN_CONFIG="${REPLAN_CONFIG:-$REPLAN_ROOT/config}"
export REPLAN_URDF="${REPLAN_URDF:-$REPLAN_ROOT/urdf/hyq.urdf}"
