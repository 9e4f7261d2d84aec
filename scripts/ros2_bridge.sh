#!/usr/bin/env bash
# Builds the ROS 2 bridge alone (ros2_bridge/: zenoh-plugin-ros2dds in a small binary) into
# target/release/stereosplat-ros2-bridge, for running it beside the node (docs/ros2.md, "On DDS,
# through the zenoh ROS 2 bridge").
# `cargo test --workspace` builds it too (a workspace member), from the crates the tests
# share. It compiles Cyclone DDS from C, so it needs cmake and clang/libclang (bindgen);
# .ci/setup installs them.
#   scripts/ros2_bridge.sh            build (incremental)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p stereosplat-ros2-bridge "$@"
ls -l target/release/stereosplat-ros2-bridge
