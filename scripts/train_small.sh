#!/usr/bin/env bash
# Trains the `small` preset from scratch (results/stereosplat_small/README.md): twice tiny's
# channels, 64 depth candidates, two transformer layers. Data: the transfer mix of
# `scripts/transfer_data.sh` (plain streets plus domain-randomised drives), so the weights
# transfer to real photographs from the start. Schedule: tiny's three phases
# (`scripts/train_tiny.sh`): steps 1-1600 with stochastic view subsampling, then to 3000 on
# the bin's first pair, then to STEPS on the first pair at half the rate with the relative
# depth loss. The run folder (default runs/small: checkpoint, log.csv, loss_curve.png and the
# exported weights) is git-ignored: run the script again after any interruption and it
# resumes from the last checkpoint.
#   bash scripts/train_small.sh [DATA_DIR] [RUN_DIR] [STEPS]
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/transfer}"
run="${2:-runs/small}"
steps="${3:-8000}"
# STEREOSPLAT_BIN: a built binary to use as is, e.g. a copy that edits of the tree cannot break.
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
bash scripts/transfer_data.sh "$data"
step() { sed -n 's/.*"step": *\([0-9]*\).*/\1/p' "$run/checkpoint/state.json" 2>/dev/null || echo 0; }
train() { "$bin" research train --data "$data" --preset small --out "$run" "$@"; }
resume=()
[ -f "$run/checkpoint/state.json" ] && resume=(--resume)
if [ "$(step)" -lt 1600 ]; then
  train --steps 1600 "${resume[@]}"
fi
if [ "$(step)" -lt 3000 ]; then
  train --steps 3000 --resume --no-subsample
fi
train --steps "$steps" --resume --no-subsample --lr 5e-4 --depth-loss relative \
  --rendered-depth-weight 0.5 --estimated-depth-weight 0.5
echo "weights: $run/stereosplat_small.safetensors (copy to model/weights/ to ship them)"
