#!/usr/bin/env bash
# Reproduces the one-step enhancer's weights (model/weights/enhancer_tiny.safetensors) from
# nothing, within 3 hours on the 2-core machine: 8 generated training drives (seeds 20-27:
# streets StereoSplat never trained on, so its renders there look like the
# node's; 300 frames, 272x72) and the 2 held-out drives of the other evaluations (seeds
# 1000000-1000001); `enhancer-data` makes PAIRS render -> truth pairs on the training drives
# with the StereoSplat `tiny` weights shipped until stop 34 (which it was trained on; kept in
# results/stereosplat_tiny_transfer/, run with their settings) and two earlier checkpoints
# (the street-only weights of stop 11 and the unbounded stop-10 weights, for variety),
# K ~ U{1..3} input pairs, and
# HELDOUT_PAIRS on the held-out drives; `train-enhancer` trains STEPS steps of batch 4;
# `eval-enhancer` scores raw against enhanced renders on the held-out pairs (JSON).
# Run it again after an interruption: drives, pairs and the training's checkpoint are kept
# and each stage goes on where it stopped.
#   bash scripts/train_enhancer.sh [DATA_DIR] [RUN_DIR]
#   PAIRS=3000 HELDOUT_PAIRS=300 STEPS=2500 (defaults; change them in the environment)
# Time, estimated from the smoke run (results/enhancer_tiny_smoke/README.md), which ran at
# 0.33-0.39 steps/s and 0.4 s a pair with the machine's load at 8-10: drives about 16 min,
# pairs about 22 min, 2500 steps about 2 h, scores 1 min: under 3 hours. Not yet measured
# end to end.
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/enhancer}"
run="${2:-runs/enhancer_tiny}"
pairs="${PAIRS:-3000}"
heldout_pairs="${HELDOUT_PAIRS:-300}"
steps="${STEPS:-2500}"
bin=target/release/stereosplat
cargo build --release --bin stereosplat
for seed in 20 21 22 23 24 25 26 27; do
  name=$(printf "synth_drive_%07d_sync" "$seed")
  if [ ! -f "$data/drives/data_poses/$name/poses.txt" ]; then
    "$bin" synth --out "$data/drives" --seed "$seed" --frames 300 --width 272 --height 72
  fi
done
if [ ! -f "$data/heldout/data_poses/synth_drive_1000001_sync/poses.txt" ]; then
  "$bin" synth-heldout --out "$data/heldout" --sequences 2 --frames 300 --width 272 --height 72
fi
before_census=census_matching=false,auto_depth_range=false,sgm_guidance=null,depth_window=null
shipped=results/stereosplat_tiny_transfer/train/checkpoint/weights.safetensors@$before_census
weights=(
  --weights "shipped=$shipped"
  --weights "street=results/stereosplat_tiny/train/checkpoint/weights.safetensors@$before_census"
  --weights "unbounded=results/stereosplat_tiny_unbounded/train/checkpoint/weights.safetensors@depth_logit_bound=null,$before_census"
)
"$bin" enhancer-data --data "$data/drives" --out "$data/pairs" --pairs "$pairs" --seed 0 "${weights[@]}"
# Held-out pairs: those weights only (what the node ran), another seed.
"$bin" enhancer-data --data "$data/heldout" --out "$data/heldout_pairs" --pairs "$heldout_pairs" \
  --seed 1 --weights "shipped=$shipped"
resume=()
[ -f "$run/checkpoint/state.json" ] && resume=(--resume)
"$bin" train-enhancer --pairs "$data/pairs" --preset tiny --out "$run" --steps "$steps" "${resume[@]}"
"$bin" eval-enhancer --pairs "$data/heldout_pairs" --preset tiny \
  --weights "$run/enhancer_tiny.safetensors" --out "$run/eval.json"
echo "weights: $run/enhancer_tiny.safetensors (copy to model/weights/ to ship them)"
