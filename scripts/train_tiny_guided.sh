#!/usr/bin/env bash
# The last stage of the shipped `tiny` weights' chain (model/weights/stereosplat_tiny.safetensors;
# results/stereosplat_tiny/README.md, "Stage 4"): the census stage's weights
# (runs/tiny_census/cv_census05/stereosplat_tiny.safetensors, scripts/train_tiny_census.sh)
# trained 2,400 more steps on the transfer mix (scripts/transfer_data.sh) with the shipped
# settings on every sample (census correlation, depth range fitted to scenes nearer than
# 50 m, `sgm_guidance` 10 with width 2), so the near samples of the mix (small-baseline rigs,
# near objects) are fitted and guided as real rooms are at inference, and the streets are
# not; the census stage's losses (matching loss at 0.5), seed 0, in RUN_DIR (default
# runs/tiny_guided), then copied into model/weights/. Resumable: run it again after any
# interruption. About 40 minutes on a 2-core machine (1.08 steps/s).
#   bash scripts/train_tiny_guided.sh [RUN_DIR] [STEPS]
# Environment: INIT, the weights a fresh run starts from (default the census stage's);
# SETTINGS, extra `--set` flags (e.g. "--set sgm_guidance=20"); SHIP=0 leaves
# model/weights/ alone (an experiment).
set -euo pipefail
cd "$(dirname "$0")/.."
run="${1:-runs/tiny_guided}" steps="${2:-2400}"
init="${INIT:-runs/tiny_census/cv_census05/stereosplat_tiny.safetensors}"
if [ ! -f "$run/checkpoint/state.json" ] && [ ! -f "$init" ]; then
  echo "missing $init: run bash scripts/train_tiny_census.sh first" >&2
  exit 1
fi
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
bash scripts/transfer_data.sh data/transfer
flags=(--data data/transfer --preset tiny --out "$run" --steps "$steps" --lr 5e-4 --warmup 100
  --seed 0 --depth-loss relative --rendered-depth-weight 0.5 --estimated-depth-weight 0.5
  --matching-weight 0.5 --set volume_branch=false --set view_subsampling=false ${SETTINGS:-})
if [ -f "$run/checkpoint/state.json" ]; then
  "$bin" research train "${flags[@]}" --resume
else
  "$bin" research train "${flags[@]}" --init "$init"
fi
if [ "${SHIP:-1}" != 0 ]; then
  cp "$run/stereosplat_tiny.safetensors" model/weights/stereosplat_tiny.safetensors
  echo "weights: model/weights/stereosplat_tiny.safetensors"
fi
