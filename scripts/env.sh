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
# Fast DDS with a shared-memory segment that holds a stereo pair and its matches (the default
# segment does not, and every hop of those topics then waits; README, "Large messages over
# DDS"). A profile of your own wins.
_sf_profiles="$_sf_root/src/stereo_fuzzy_perception/config/fastdds_large_messages.xml"
export FASTRTPS_DEFAULT_PROFILES_FILE=${FASTRTPS_DEFAULT_PROFILES_FILE:-$_sf_profiles}
# Every executable the READMEs name, callable by name: colcon installs them in
# install/<package>/lib/<package> (what `ros2 run <package> <executable>` starts), and
# scripts/bin holds launch_chain, this repository's stand-in for `ros2 launch`.
for _sf_dir in "$_sf_root/scripts/bin" "$_sf_root"/ros2_ws/install/*/lib/*; do
  [ -d "$_sf_dir" ] || continue
  case "$_sf_dir" in */lib/python*) continue ;; esac
  case ":$PATH:" in *":$_sf_dir:"*) ;; *) PATH="$_sf_dir:$PATH" ;; esac
done
export PATH
unset _sf_dir
unset _sf_root _sf_nounset _sf_profiles
