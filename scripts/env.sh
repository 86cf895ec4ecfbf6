# Source this to use the project's environment in a shell: the venv with ROS 2 Jazzy,
# the built workspace and safe DDS defaults. scripts/sdbc sources it for you.
#
#   source scripts/env.sh
#
# It does what `source install/setup.bash` does on a full ROS 2 install, without
# the per-process re-exec of the wheels' bootstrapper (which costs ~1 s per Python).

_sdbc_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
_sdbc_venv="$_sdbc_root/.venv"
_sdbc_pyver="$(ls -d "$_sdbc_venv"/lib/python3.* 2>/dev/null | head -n 1 | xargs -r basename)"
_sdbc_site="$_sdbc_venv/lib/$_sdbc_pyver/site-packages"

export SDBC_ROOT="$_sdbc_root"
export VIRTUAL_ENV="$_sdbc_venv"
export PATH="$_sdbc_venv/bin:$_sdbc_root/install/sdbc_sim/lib/sdbc_sim:$_sdbc_root/install/sdbc_evolution/lib/sdbc_evolution:$PATH"

# ROS 2: the workspace overlays the venv, as install/setup.bash would order them.
export AMENT_PREFIX_PATH="$_sdbc_root/install/sdbc_evolution:$_sdbc_root/install/sdbc_sim:$_sdbc_root/install/sdbc_msgs:$_sdbc_venv"
# Sources first; build/<pkg> holds the symlink-installed packages' metadata (egg-info),
# which their console scripts look up, as colcon's develop hook would add it.
_sdbc_py="$_sdbc_root/src/sdbc_sim:$_sdbc_root/src/sdbc_evolution"
_sdbc_py="$_sdbc_py:$_sdbc_root/build/sdbc_sim:$_sdbc_root/build/sdbc_evolution"
_sdbc_py="$_sdbc_py:$_sdbc_root/install/sdbc_msgs/lib/$_sdbc_pyver/site-packages"
export PYTHONPATH="$_sdbc_py${PYTHONPATH:+:$PYTHONPATH}"
_sdbc_ld="$_sdbc_venv/lib:$_sdbc_root/install/sdbc_msgs/lib"
for _d in "$_sdbc_site"/ros_*.libs; do [ -d "$_d" ] && _sdbc_ld="$_sdbc_ld:$_d"; done
export LD_LIBRARY_PATH="$_sdbc_ld${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"

# DDS stays on this machine unless the user says otherwise. Fast DDS reads its
# profile from FASTRTPS_DEFAULT_PROFILES_FILE (2.14, Jazzy's) or, in newer versions,
# FASTDDS_DEFAULT_PROFILES_FILE: unless either is set (an empty value included),
# both point at scripts/fastdds_localhost.xml, which puts every socket on loopback.
# ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST does not: rmw_fastrtps then adds a UDP
# transport of its own, on every interface, beside the profile's (measured with
# /proc/net; tests/test_sockets.py). So while the profile is in force the range is
# SYSTEM_DEFAULT (the profile decides), LOCALHOST exported before this script
# included; the project's nodes do the same at start-up for a LOCALHOST exported
# after it (sdbc_sim.nodes.startup.keep_dds_on_loopback). Without the profile the
# range defaults to LOCALHOST.
# Multi-machine graphs: export FASTRTPS_DEFAULT_PROFILES_FILE= (empty) before
# sourcing this, and ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET (docs/reliability.md).
_sdbc_profile="$_sdbc_root/scripts/fastdds_localhost.xml"
if [ -z "${FASTRTPS_DEFAULT_PROFILES_FILE+set}" ] && [ -z "${FASTDDS_DEFAULT_PROFILES_FILE+set}" ]; then
  export FASTRTPS_DEFAULT_PROFILES_FILE="$_sdbc_profile"
  export FASTDDS_DEFAULT_PROFILES_FILE="$_sdbc_profile"
fi
if [ "${FASTRTPS_DEFAULT_PROFILES_FILE:-$FASTDDS_DEFAULT_PROFILES_FILE}" = "$_sdbc_profile" ]; then
  case "${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}" in
    LOCALHOST) export ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT ;;
  esac
else
  export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
fi
export ROS_HOME="${ROS_HOME:-$_sdbc_root/.ros}"
export MPLBACKEND="${MPLBACKEND:-Agg}"

unset _sdbc_profile _sdbc_root _sdbc_venv _sdbc_pyver _sdbc_site _sdbc_ld _sdbc_py _d
