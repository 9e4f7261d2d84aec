#!/usr/bin/env bash
# Runs a command with the ROS 2 Jazzy wheels (scripts/requirements.txt) and the message
# packages of scripts/ros2_msgs.sh on its paths, as a sourced ROS 2 setup file would:
# AMENT_PREFIX_PATH (rclpy finds the rmw implementation and type descriptions through the
# ament index), PYTHONPATH and LD_LIBRARY_PATH (the generated typesupport), and
# RMW_IMPLEMENTATION=rmw_fastrtps_cpp. Usage: scripts/ros2_env.sh CMD [ARGS...]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
prefix="$(python3 -c 'import sys; print(sys.prefix)')"
install="$root/ros2_msgs/install"
site="$(ls -d "$install"/lib/python3*/site-packages 2>/dev/null | head -1 || true)"
export AMENT_PREFIX_PATH="$install:$prefix"
export PYTHONPATH="${site}${PYTHONPATH:+:$PYTHONPATH}"
export LD_LIBRARY_PATH="$install/lib:$prefix/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
exec "$@"
