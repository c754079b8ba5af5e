# Source me: puts the project's venv (an ament prefix holding ROS 2 Jazzy from PyPI wheels) and the
# colcon install space on the paths, like `source /opt/ros/jazzy/setup.bash` on a full install.
_stealth_root="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." && pwd)"
export VIRTUAL_ENV="$_stealth_root/.venv"
export PATH="$_stealth_root/scripts/bin:$VIRTUAL_ENV/bin:$PATH"
export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export CMAKE_PREFIX_PATH="$VIRTUAL_ENV${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
export PYTHONNOUSERSITE=1
if [ -f "$_stealth_root/ros2_ws/install/local_setup.sh" ]; then
  COLCON_CURRENT_PREFIX="$_stealth_root/ros2_ws/install" . "$_stealth_root/ros2_ws/install/local_setup.sh"
fi
unset _stealth_root
