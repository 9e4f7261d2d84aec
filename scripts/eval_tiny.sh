#!/usr/bin/env bash
# The held-out comparison of the tiny weights with the SGM baseline, the invariance check
# (1, 2 and 3 input pairs, with the preset's pair fusion and without it), and how much the
# weights lean on stereo matching (the cost volume zeroed: match_views=0), as in
# results/stereosplat_tiny/README.md: two held-out drives (seeds 1000000 and 1000001, 300
# frames, 272x72), the paper's protocol with a bin starting every 5th frame, LPIPS on.
# Flags after the two folders go to every learned-model call (default: the shipped weights
# and preset), e.g. a stage's weights and settings:
#   bash scripts/eval_tiny.sh [DATA_DIR] [OUT_DIR] [--weights W] [--set KEY=VALUE ...]
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/heldout272}"
out="${2:-out/eval_tiny}"
extra=("${@:3}")
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
if [ ! -f "$data/data_poses/synth_drive_1000001_sync/poses.txt" ]; then
  "$bin" research synth-heldout --out "$data" --sequences 2 --frames 300 --width 272 --height 72
fi
"$bin" research eval --data "$data" --method sgm --stride 5 --out "$out/sgm"
for pairs in 1 2 3; do
  "$bin" research eval --data "$data" --method stereosplat --preset tiny --pairs "$pairs" --stride 5 \
    "${extra[@]}" --out "$out/tiny_pairs$pairs"
done
for pairs in 2 3; do
  "$bin" research eval --data "$data" --method stereosplat --preset tiny --pairs "$pairs" --stride 5 \
    --set pair_fusion_margin=null "${extra[@]}" --out "$out/tiny_pairs${pairs}_unfused"
done
"$bin" research eval --data "$data" --method stereosplat --preset tiny --stride 5 --set match_views=0 \
  "${extra[@]}" --out "$out/tiny_no_matching"
