#!/usr/bin/env bash
# The one-step enhancer's weights (model/weights/enhancer_tiny.safetensors;
# results/enhancer_tiny/README.md), from three StereoSplat `tiny` weight files under runs/:
# the transfer stage's (runs/tiny_transfer, scripts/train_tiny_transfer.sh), the
# street-trained stage's (runs/tiny, scripts/train_tiny.sh) and the same street training with
# unbounded depth logits (runs/tiny_unbounded: `bash scripts/train_tiny.sh data/train272
# runs/tiny_unbounded --set depth_logit_bound=null`), each run with the settings it was
# trained with. 8 generated training drives (seeds 20-27: streets StereoSplat never trained
# on, so its renders there look like the node's; 300 frames, 272x72) and the 2 held-out
# drives of the other evaluations (seeds 1000000-1000001); `enhancer-data` makes PAIRS
# render -> truth pairs on the training drives with the three weight files (the transfer
# stage's, which the enhancer is for, and the other two for variety), K ~ U{1..3} input
# pairs, and HELDOUT_PAIRS on the held-out drives with the transfer stage's weights alone;
# `train-enhancer` trains STEPS steps of batch 4 in RUN_DIR (default runs/enhancer_tiny);
# `eval-enhancer` scores raw against enhanced renders on the held-out pairs
# (RUN_DIR/eval.json). About 15 minutes of data and 55 minutes of training on a 2-core
# machine with other work beside it. Run it again after an interruption: drives, pairs and
# the training's checkpoint are kept and each stage goes on where it stopped.
# scripts/reproduce_weights.sh enhancer runs the whole chain and copies the result into
# model/weights/.
#   bash scripts/train_enhancer.sh [DATA_DIR] [RUN_DIR]
#   PAIRS=3000 HELDOUT_PAIRS=300 STEPS=2500 (defaults; change them in the environment)
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/enhancer}"
run="${2:-runs/enhancer_tiny}"
pairs="${PAIRS:-3000}"
heldout_pairs="${HELDOUT_PAIRS:-300}"
steps="${STEPS:-2500}"
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
transfer=runs/tiny_transfer/stereosplat_tiny.safetensors
street=runs/tiny/stereosplat_tiny.safetensors
unbounded=runs/tiny_unbounded/stereosplat_tiny.safetensors
for w in "$transfer:bash scripts/train_tiny_transfer.sh" "$street:bash scripts/train_tiny.sh" \
  "$unbounded:bash scripts/train_tiny.sh data/train272 runs/tiny_unbounded --set depth_logit_bound=null"; do
  if [ ! -f "${w%%:*}" ]; then
    echo "missing ${w%%:*}: run ${w#*:} first" >&2
    exit 1
  fi
done
for seed in 20 21 22 23 24 25 26 27; do
  name=$(printf "synth_drive_%07d_sync" "$seed")
  if [ ! -f "$data/drives/data_poses/$name/poses.txt" ]; then
    "$bin" research synth --out "$data/drives" --seed "$seed" --frames 300 --width 272 --height 72
  fi
done
if [ ! -f "$data/heldout/data_poses/synth_drive_1000001_sync/poses.txt" ]; then
  "$bin" research synth-heldout --out "$data/heldout" --sequences 2 --frames 300 --width 272 --height 72
fi
before_census=census_matching=false,auto_depth_range=false,sgm_guidance=null,rig_disparity_fraction=null
shipped=$transfer@$before_census
weights=(
  --weights "shipped=$shipped"
  --weights "street=$street@$before_census"
  --weights "unbounded=$unbounded@depth_logit_bound=null,$before_census"
)
"$bin" research enhancer-data --data "$data/drives" --out "$data/pairs" --pairs "$pairs" --seed 0 "${weights[@]}"
# Held-out pairs: the transfer stage's weights only (what the node ran), another seed.
"$bin" research enhancer-data --data "$data/heldout" --out "$data/heldout_pairs" --pairs "$heldout_pairs" \
  --seed 1 --weights "shipped=$shipped"
resume=()
[ -f "$run/checkpoint/state.json" ] && resume=(--resume)
"$bin" research train-enhancer --pairs "$data/pairs" --preset tiny --out "$run" --steps "$steps" "${resume[@]}"
"$bin" research eval-enhancer --pairs "$data/heldout_pairs" --preset tiny \
  --weights "$run/enhancer_tiny.safetensors" --out "$run/eval.json"
echo "weights: $run/enhancer_tiny.safetensors (scripts/reproduce_weights.sh enhancer copies them into model/weights/)"
