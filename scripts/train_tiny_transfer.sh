#!/usr/bin/env bash
# The second stage of the shipped `tiny` weights' chain (results/stereosplat_tiny/README.md,
# "Stage 2"), also the start of scripts/train_tiny_3d.sh, scripts/ablation_tiny.sh,
# scripts/train_volume.sh and scripts/train_enhancer.sh: the street-trained weights of
# scripts/train_tiny.sh (runs/tiny/stereosplat_tiny.safetensors) fine-tuned on a mix of the
# plain generated streets (seeds 0-7, as before) and domain-randomised drives (seeds 100-115:
# photo textures, random lighting and colours, rigs of 45-100 degrees and 5-60 cm baselines at
# six image sizes, exposure, white balance, noise, blur, vignetting, JPEG, grey cameras and
# floating textured objects; `scripts/transfer_data.sh` writes them), so that the network
# transfers to real photographs while keeping its street quality. Writes RUN_DIR (default
# runs/tiny_transfer; the next stages read runs/tiny_transfer/stereosplat_tiny.safetensors).
# Resumable: drives already written are kept, training resumes from its checkpoint.
#   bash scripts/train_tiny_transfer.sh [DATA_DIR] [RUN_DIR] [STEPS] [TRAIN FLAGS ...]
# Flags after STEPS go to every `stereosplat research train` call, after the settings these weights
# were trained with (`census_matching=false`, `auto_depth_range=false`, `sgm_guidance=null`).
# INIT: the weights a fresh run starts from (default the street-trained ones).
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/transfer}"
run="${2:-runs/tiny_transfer}"
steps="${3:-6000}"
extra=(--set census_matching=false --set auto_depth_range=false --set sgm_guidance=null "${@:4}")
base="${INIT:-runs/tiny/stereosplat_tiny.safetensors}"
# STEREOSPLAT_BIN: a built binary to use as is, e.g. a copy that edits of the tree cannot break.
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
if [ ! -f "$run/checkpoint/state.json" ] && [ ! -f "$base" ]; then
  echo "missing $base: run bash scripts/train_tiny.sh first" >&2
  exit 1
fi
bash scripts/transfer_data.sh "$data"
flags=(--data "$data" --preset tiny --out "$run" --steps "$steps" --no-subsample --lr 5e-4
  --warmup 100 --depth-loss relative --rendered-depth-weight 0.5 --estimated-depth-weight 0.5
  "${extra[@]}")
if [ -f "$run/checkpoint/state.json" ]; then
  "$bin" research train "${flags[@]}" --resume
else
  "$bin" research train "${flags[@]}" --init "$base"
fi
echo "weights: $run/stereosplat_tiny.safetensors (next: bash scripts/train_tiny_census.sh)"
