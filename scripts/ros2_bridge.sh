#!/usr/bin/env bash
# Builds the ROS 2 bridge (ros2_bridge/: zenoh-plugin-ros2dds in a small binary) into
# ros2_bridge/target/release/stereosplat-ros2-bridge. It compiles Cyclone DDS from C, so it
# needs cmake and clang/libclang (bindgen); .ci/setup installs them. Not part of the
# workspace build: `cargo test --workspace` never compiles it; node/tests/ros2_bridge.rs runs
# it when it has been built (CI builds it in .ci/run before the tests).
#   scripts/ros2_bridge.sh            build (incremental; from scratch about 11.5 CPU-minutes:
#                                     user 10m0s + sys 0m53s measured, 2 cores shared with other builds)
set -euo pipefail
cd "$(dirname "$0")/../ros2_bridge"
cargo build --release --locked "$@"
ls -l target/release/stereosplat-ros2-bridge
