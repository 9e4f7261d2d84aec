#!/usr/bin/env bash
# The last stage of the shipped `tiny` weights' chain (model/weights/stereosplat_tiny.safetensors;
# results/stereosplat_tiny/README.md, "Stage 5"): the guided stage's weights
# (runs/tiny_guided/stereosplat_tiny.safetensors, scripts/train_tiny_guided.sh) trained on
# desks, rooms and streets at the node's working size, 544x112 (scripts/scales_data.sh),
# the three kinds drawn equally often, each cut into its own bins (0.1 m, 0.5 m, 8 m), with
# the preset's settings on every sample: depth candidates from each sample's rig, the
# fitted range for scenes nearer than 50 m, census matching and SGM's hints; the guided
# stage's losses, seed 0, in RUN_DIR (default runs/tiny_scales). Checkpoints every 100
# steps are kept under RUN_DIR/kept/ so the shipped one can be chosen on the validation
# drives (scripts/setting_choices.sh); SHIP=1 copies the run's last weights into
# model/weights/. Resumable: run it again after any interruption.
#   bash scripts/train_tiny_scales.sh [RUN_DIR] [STEPS]
# Environment: INIT, the weights a fresh run starts from (default the guided stage's);
# LR (default 3e-4); SETTINGS, extra `--set` flags.
set -euo pipefail
cd "$(dirname "$0")/.."
run="${1:-runs/tiny_scales}" steps="${2:-1500}"
init="${INIT:-runs/tiny_guided/stereosplat_tiny.safetensors}"
if [ ! -f "$run/checkpoint/state.json" ] && [ ! -f "$init" ]; then
  echo "missing $init: run bash scripts/train_tiny_guided.sh first" >&2
  exit 1
fi
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
STEREOSPLAT_BIN="$bin" bash scripts/scales_data.sh data/scales
flags=(--data data/scales/desk --data data/scales/room --data data/scales/street
  --bin-length 0.1 --bin-length 0.5 --bin-length 8 --preset tiny --out "$run" --lr "${LR:-3e-4}" --warmup 100 --seed 0 --checkpoint-every 100
  --depth-loss relative --rendered-depth-weight 0.5 --estimated-depth-weight 0.5
  --matching-weight 0.5 --set volume_branch=false --set view_subsampling=false ${SETTINGS:-})
# Trains in legs of 100 steps so every checkpoint's weights are kept for the choice.
mkdir -p "$run/kept"
for ((to = 100; to <= steps; to += 100)); do
  [ -f "$run/kept/step_$to.safetensors" ] && continue
  if [ -f "$run/checkpoint/state.json" ]; then
    "$bin" train "${flags[@]}" --resume --steps "$to"
  else
    "$bin" train "${flags[@]}" --init "$init" --steps "$to"
  fi
  cp "$run/stereosplat_tiny.safetensors" "$run/kept/step_$to.safetensors"
done
if [ "${SHIP:-0}" != 0 ]; then
  cp "$run/stereosplat_tiny.safetensors" model/weights/stereosplat_tiny.safetensors
  echo "weights: model/weights/stereosplat_tiny.safetensors"
fi
