# Source this at the repository root: `source env.sh`.
# Gives a shell with the project's venv, the built ROS 2 workspace (bracing_msgs, bracing_sim,
# bracing_controller, bracing_analysis, bracing_experiments, bracing_recorder, bracing_view,
# bracing_mujoco, bracing_bringup) and the bracing-* commands on PATH.
_bracing_root=$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")" && pwd)
if [ ! -f "$_bracing_root/install/setup.bash" ]; then
  echo "env.sh: workspace not built yet; run 'make setup' first" >&2
  return 1 2>/dev/null || exit 1
fi
# shellcheck disable=SC1091
source "$_bracing_root/.venv/bin/activate"
# shellcheck disable=SC1091
source "$_bracing_root/install/setup.bash"
# The ROS wheels live in the venv prefix; keep it on the ament index after the workspace.
case ":${AMENT_PREFIX_PATH:-}:" in
  *":$VIRTUAL_ENV:"*) ;;
  *) export AMENT_PREFIX_PATH="${AMENT_PREFIX_PATH:+$AMENT_PREFIX_PATH:}$VIRTUAL_ENV" ;;
esac
# ament_python installs console scripts to install/<pkg>/lib/<pkg> (where `ros2 run` looks).
for _d in "$_bracing_root"/install/bracing_*/lib/bracing_*; do
  [ -d "$_d" ] && case ":$PATH:" in *":$_d:"*) ;; *) PATH="$_d:$PATH" ;; esac
done
export PATH
# Keep DDS discovery on this machine unless the user says otherwise.
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export BRACING_ROOT="$_bracing_root"
unset _bracing_root _d
