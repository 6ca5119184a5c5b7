# Source this file (bash) to use the set-up environment: the venv and the colcon workspace.
#   source scripts/env.sh
_sf_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# shellcheck disable=SC1091
source "$_sf_root/.venv/bin/activate"
# colcon's setup scripts read unset variables, so do not run them under `set -u`.
_sf_nounset=$([[ $- == *u* ]] && echo 1 || true)
set +u
# shellcheck disable=SC1091
source "$_sf_root/ros2_ws/install/setup.bash"
[ -n "$_sf_nounset" ] && set -u
export RMW_IMPLEMENTATION=${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}
export ROS_AUTOMATIC_DISCOVERY_RANGE=${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}
export SF_ROOT="$_sf_root"
unset _sf_root _sf_nounset
