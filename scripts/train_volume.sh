#!/usr/bin/env bash
# Trains the `tiny` preset with both branches (cost volume + 3D volume), warm-started from the
# transfer stage's cost-volume weights (runs/tiny_transfer/stereosplat_tiny.safetensors from
# scripts/train_tiny_transfer.sh, with their settings: no census correlation, the fixed depth
# range): every tensor of that file is loaded, the volume branch (`volume.*`) starts from the
# seeded initialisation (the run prints which tensors were fresh). Data: the transfer mix of
# `scripts/transfer_data.sh` (those weights' own data). Schedule: the transfer
# fine-tuning's settings (lr 5e-4 after 100 warm-up steps, relative depth loss at weight 0.5)
# with stochastic view subsampling (the paper's full StereoSplat row); the volume branch adds
# its occupancy loss (LiDAR of the whole bin, weight 0.05) and the volume-only render on
# in-volume pixels (weight 1). Resumable: run it again after an interruption and training
# continues from the last checkpoint. Flags after the three positional arguments (e.g.
# `--set volume.top_k=2048`, `--set view_subsampling=false`, `--set cost_volume_branch=false`)
# go to every `stereosplat research train` call, the same on each resume.
#   bash scripts/train_volume.sh [DATA_DIR] [RUN_DIR] [STEPS] [--set KEY=VALUE ...]
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/transfer}"
run="${2:-runs/tiny_volume}"
steps="${3:-3000}"
extra=("${@:4}")
base=runs/tiny_transfer/stereosplat_tiny.safetensors
bin=target/release/stereosplat
if [ ! -f "$run/checkpoint/state.json" ] && [ ! -f "$base" ]; then
  echo "missing $base: run bash scripts/train_tiny.sh, then bash scripts/train_tiny_transfer.sh" >&2
  exit 1
fi
if [ ! -f "$data/rand_115/data_poses/synth_drive_0000115_sync/poses.txt" ]; then
  bash scripts/transfer_data.sh "$data"
fi
cargo build --release --workspace
flags=(--data "$data" --preset tiny --out "$run" --steps "$steps" --lr 5e-4 --warmup 100
  --depth-loss relative --rendered-depth-weight 0.5 --estimated-depth-weight 0.5
  --set census_matching=false --set auto_depth_range=false --set sgm_guidance=null --set volume_branch=true
  "${extra[@]}")
if [ -f "$run/checkpoint/state.json" ]; then
  "$bin" research train "${flags[@]}" --resume
else
  "$bin" research train "${flags[@]}" --init "$base"
fi
echo "weights: $run/stereosplat_tiny.safetensors (evaluate with --set volume_branch=true)"
