#!/usr/bin/env bash
# Builds the ROS 2 bridge (ros2_bridge/: zenoh-plugin-ros2dds in a small binary) into
# target/release/stereosplat-ros2-bridge (the workspace's target directory; see
# ros2_bridge/Cargo.toml: the two builds still compile 173 crates each). It compiles Cyclone
# DDS from C, so it needs cmake and clang/libclang (bindgen); .ci/setup installs them. Not
# part of the workspace build: `cargo test --workspace` never compiles it;
# node/tests/ros2_bridge.rs runs it and fails, naming this script, when it is missing
# (.ci/setup builds it).
#   scripts/ros2_bridge.sh            build (incremental; from scratch about 11.5 CPU-minutes:
#                                     user 10m0s + sys 0m53s measured, 2 cores shared with other builds)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root/ros2_bridge"
CARGO_TARGET_DIR="$root/target" cargo build --release --locked "$@"
ls -l "$root/target/release/stereosplat-ros2-bridge"
