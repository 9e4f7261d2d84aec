#!/usr/bin/env bash
# The first stage of the shipped `tiny` weights' chain (results/stereosplat_tiny/README.md,
# "Stage 1"): the street-trained weights, from scratch, written to RUN_DIR (default
# runs/tiny; scripts/train_tiny_transfer.sh starts from runs/tiny/stereosplat_tiny.safetensors).
# Eight generated training drives (seeds 0-7, 300 frames each, 272x72), then `stereosplat
# train` with the defaults (seed 0, lr 1e-3 after 200 warm-up steps, 2 targets per step) in
# three phases: steps 1-PHASE1 with stochastic view subsampling (m ~ U{1..3} pairs); then to
# 3000 with the bin's first pair as input (`--no-subsample`, the evaluation protocol's input);
# then to 7000 on the first pair at half the rate with the relative depth loss
# (|d - d*| / d*, weight 0.5 on the rendered and the estimated depth), which the
# evaluation's AbsRel scores. The settings the `tiny` preset has gained since these weights
# were trained are turned off (no census correlation, the fixed depth range, no SGM hints).
# Run it again after an interruption: the drives already written are kept and training
# resumes from its last checkpoint. Flags after the two folders go to every `stereosplat
# train` call, the same in each phase and on each resume; the enhancer's chain
# (scripts/reproduce_weights.sh enhancer) also runs it with unbounded depth logits:
#   bash scripts/train_tiny.sh data/train272 runs/tiny_unbounded --set depth_logit_bound=null
#   bash scripts/train_tiny.sh [DATA_DIR] [RUN_DIR] [--set KEY=VALUE ...]
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/train272}"
run="${2:-runs/tiny}"
extra=(--set census_matching=false --set auto_depth_range=false --set sgm_guidance=null "${@:3}")
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
for seed in 0 1 2 3 4 5 6 7; do
  name=$(printf "synth_drive_%07d_sync" "$seed")
  if [ ! -f "$data/data_poses/$name/poses.txt" ]; then
    "$bin" research synth --out "$data" --seed "$seed" --frames 300 --width 272 --height 72
  fi
done
phase1=1600
step() { sed -n 's/.*"step": *\([0-9]*\).*/\1/p' "$run/checkpoint/state.json" 2>/dev/null || echo 0; }
resume=()
[ -f "$run/checkpoint/state.json" ] && resume=(--resume)
if [ "$(step)" -lt "$phase1" ]; then
  "$bin" research train --data "$data" --preset tiny --out "$run" --steps "$phase1" "${resume[@]}" "${extra[@]}"
fi
phase2=3000
if [ "$(step)" -lt "$phase2" ]; then
  "$bin" research train --data "$data" --preset tiny --out "$run" --steps "$phase2" --resume --no-subsample \
    "${extra[@]}"
fi
"$bin" research train --data "$data" --preset tiny --out "$run" --steps 7000 --resume --no-subsample \
  --lr 5e-4 --depth-loss relative --rendered-depth-weight 0.5 --estimated-depth-weight 0.5 \
  "${extra[@]}"
echo "weights: $run/stereosplat_tiny.safetensors (next: bash scripts/train_tiny_transfer.sh)"
