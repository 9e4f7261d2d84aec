#!/usr/bin/env bash
# The paper's branch ablation at the `tiny` preset (results/ablation_tiny/README.md): four rows
# trained with the same data (the transfer mix of scripts/transfer_data.sh), seed, schedule
# and warm start (the transfer stage's weights, runs/tiny_transfer/stereosplat_tiny.safetensors
# from scripts/train_tiny_transfer.sh; the volume branch starts from its seeded
# initialisation), then evaluated on the same held-out drives as results/unseen_psnr (seeds
# 1000000 and 1000001, 272x72, a bin every 5th frame, one input pair, LPIPS on):
#   cv          Branch_CV: the cost-volume branch alone, no view subsampling
#   3d          Branch_3D: the volume branch's Gaussians alone, no view subsampling
#   cv3d        CV + 3D, no view subsampling (the first phase of `tiny-3d`,
#               scripts/train_tiny_3d.sh)
#   stereosplat CV + 3D + stochastic view subsampling (1..3 input pairs per sample)
# and one cost-volume-only row that is a stage of the shipped `tiny` chain, not a row of
# the paper's table (scripts/train_tiny_census.sh runs it):
#   cv_census05    the matching loss at weight 0.5 with `census_matching` (a soft census
#                  correlation of the grey images in the matching term, blind to the
#                  cameras' gain)
# Every row is resumable: run the same command again after an interruption.
#   bash scripts/ablation_tiny.sh train ROW [STEPS]   one row (rows may run side by side)
#   bash scripts/ablation_tiny.sh eval [ROW ...]      evaluate trained rows (default: all)
#   bash scripts/ablation_tiny.sh all [STEPS]         train every row, then evaluate
# Runs go to $ABLATION_RUNS/<row> (default runs/ablation), evaluations to
# out/<basename of $ABLATION_RUNS>/<row>. ABLATION_SEED (default 0) sets the training seed, to
# measure how far a row moves with the draw of samples alone (run it in its own ABLATION_RUNS).
set -euo pipefail
cd "$(dirname "$0")/.."
data=data/transfer
heldout=data/heldout272
# Every row starts from the transfer stage's weights (scripts/train_tiny_transfer.sh), with
# the settings they were trained with: no census correlation, the preset's fixed depth range
# in metres, no SGM hints (the shipped `tiny` turns all on).
base=runs/tiny_transfer/stereosplat_tiny.safetensors
before_census="--set census_matching=false --set auto_depth_range=false --set sgm_guidance=null --set rig_disparity_fraction=null"
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build), e.g. a copy that edits of
# the tree cannot break while rows train.
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
runs="${ABLATION_RUNS:-runs/ablation}"
seed="${ABLATION_SEED:-0}"
rows=(cv 3d cv3d stereosplat)

# The settings of a row: the same on every train, resume and eval call.
settings() {
  echo -n "$before_census "
  case "$1" in
    cv) echo "--set volume_branch=false --set view_subsampling=false" ;;
    3d) echo "--set volume_branch=true --set cost_volume_branch=false --set view_subsampling=false" ;;
    cv3d) echo "--set volume_branch=true --set view_subsampling=false" ;;
    stereosplat) echo "--set volume_branch=true --set view_subsampling=true" ;;
    cv_census05) echo "--set volume_branch=false --set view_subsampling=false --set census_matching=true" ;;
    *)
      echo "unknown row '$1' (rows: ${rows[*]} cv_census05)" >&2
      exit 2
      ;;
  esac
}

# The training-only flags of a row (loss weights; the network's settings are `settings`).
train_flags() {
  case "$1" in
    cv_census05) echo "--matching-weight 0.5" ;;
    *) echo "" ;;
  esac
}

train_row() {
  local row="$1" steps="${2:-1500}" run="$runs/$1"
  read -ra set <<<"$(settings "$row")"
  read -ra extra <<<"$(train_flags "$row")"
  local flags=(--data "$data" --preset tiny --out "$run" --steps "$steps" --lr 5e-4
    --warmup 100 --seed "$seed" --depth-loss relative --rendered-depth-weight 0.5
    --estimated-depth-weight 0.5 "${set[@]}" "${extra[@]}")
  if [ -f "$run/checkpoint/state.json" ]; then
    "$bin" research train "${flags[@]}" --resume
  else
    if [ ! -f "$base" ]; then
      echo "missing $base: run bash scripts/train_tiny.sh, then bash scripts/train_tiny_transfer.sh" >&2
      exit 1
    fi
    "$bin" research train "${flags[@]}" --init "$base"
  fi
}

eval_row() {
  local row="$1"
  read -ra set <<<"$(settings "$row")"
  "$bin" research eval --data "$heldout" --method stereosplat --preset tiny --stride 5 \
    --weights "$runs/$row/stereosplat_tiny.safetensors" "${set[@]}" \
    --out "out/$(basename "$runs")/$row"
}

prepare() {
  if [ ! -f "$data/rand_115/data_poses/synth_drive_0000115_sync/poses.txt" ]; then
    bash scripts/transfer_data.sh "$data"
  fi
  if [ ! -f "$heldout/data_poses/synth_drive_1000001_sync/poses.txt" ]; then
    "$bin" research synth-heldout --out "$heldout" --sequences 2 --frames 300 --width 272 --height 72
  fi
}

[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
prepare
case "${1:-all}" in
  train) train_row "$2" "${3:-1500}" ;;
  eval)
    shift
    for row in "${@:-${rows[@]}}"; do eval_row "$row"; done
    ;;
  all)
    for row in "${rows[@]}"; do train_row "$row" "${2:-1500}"; done
    for row in "${rows[@]}"; do eval_row "$row"; done
    ;;
  *) echo "usage: $0 train ROW [STEPS] | eval [ROW ...] | all [STEPS]" >&2; exit 2 ;;
esac
