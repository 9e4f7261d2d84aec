#!/usr/bin/env bash
# Generates ROS 2 Jazzy typesupport (C, C++, Python) for the message packages no wheel ships:
# stereosplat_msgs (the node's own types, from node/src/msg/*.msg) and tf2_msgs (TFMessage),
# with rosidl's own CMake generators from the ros-jazzy-* wheels (scripts/requirements.txt),
# into ros2_msgs/install/. scripts/ros2_env.sh puts that install on the paths. About 30 s on
# 2 cores; skipped when the install is newer than its sources.
#
# The wheels were built in a manylinux image: their CMake exports name include folders under
# /opt/python/cp311-cp311 (Python's headers, numpy's). When that folder is missing, it is made
# a link to this Python's prefix, which holds the same folders.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
src="$root/ros2_msgs"
install="$src/install"
prefix="$(python3 -c 'import sys; print(sys.prefix)')"
stamp="$install/.built"
if [ -f "$stamp" ] && [ -z "$(find "$src"/stereosplat_msgs "$src"/tf2_msgs "$root"/node/src/msg -newer "$stamp" -type f)" ]; then
  echo "ros2_msgs: up to date ($install)"; exit 0
fi
wheel_prefix=/opt/python/cp311-cp311
if [ ! -e "$wheel_prefix" ]; then
  mkdir -p "$(dirname "$wheel_prefix")" && ln -s "$prefix" "$wheel_prefix"
fi
mkdir -p "$src/stereosplat_msgs/msg"
cp "$root"/node/src/msg/*.msg "$src/stereosplat_msgs/msg/"
export AMENT_PREFIX_PATH="$prefix"
for pkg in tf2_msgs stereosplat_msgs; do
  build="$src/build/$pkg"
  mkdir -p "$build"
  (cd "$build" &&
    cmake "$src/$pkg" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_INSTALL_PREFIX="$install" \
      -DPython3_EXECUTABLE="$(python3 -c 'import sys; print(sys.executable)')" -DBUILD_TESTING=OFF >cmake.log &&
    make -j"$(nproc)" install >make.log) || { echo "ros2_msgs: building $pkg failed, see $build/*.log" >&2; exit 1; }
done
touch "$stamp"
echo "ros2_msgs: installed in $install"
