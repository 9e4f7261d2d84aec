#!/usr/bin/env bash
# Writes the training mix every transfer-trained preset learns from: the 8 plain generated
# streets of scripts/train_tiny.sh (seeds 0-7, 300 frames, 272x72) under DATA/plain, and 16
# domain-randomised drives (seeds 100-115, 250 frames, `synth --randomise`: photo textures,
# random light and colours, rigs of 45-100 degrees and 5-60 cm baselines at six image sizes,
# camera effects, floating textured objects), each in its own KITTI-360 root DATA/rand_SEED
# (its own rig). Drives already written are kept, so an interrupted run goes on.
#   bash scripts/transfer_data.sh [DATA_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/transfer}"
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
name() { printf "synth_drive_%07d_sync" "$1"; }
for seed in 0 1 2 3 4 5 6 7; do
  if [ ! -f "$data/plain/data_poses/$(name "$seed")/poses.txt" ]; then
    "$bin" research synth --out "$data/plain" --seed "$seed" --frames 300 --width 272 --height 72
  fi
done
for seed in $(seq 100 115); do
  if [ ! -f "$data/rand_$seed/data_poses/$(name "$seed")/poses.txt" ]; then
    "$bin" research synth --out "$data/rand_$seed" --seed "$seed" --frames 250 --randomise
  fi
done
