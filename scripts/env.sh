# Source this file (after scripts/setup.sh) to get the project environment in a shell:
#   . scripts/env.sh
# It activates .venv, points AMENT_PREFIX_PATH at the venv and the colcon install,
# and sources ros_ws/install/setup.bash so the built executables and packages are found.
_CATH_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# shellcheck disable=SC1091
. "$_CATH_ROOT/.venv/bin/activate"
export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
if [ -f "$_CATH_ROOT/ros_ws/install/setup.bash" ]; then
  # shellcheck disable=SC1091
  . "$_CATH_ROOT/ros_ws/install/setup.bash"
fi
export CATHETER_WS_ROOT="$_CATH_ROOT"
unset _CATH_ROOT
