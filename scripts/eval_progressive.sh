#!/usr/bin/env bash
# The paper's last two rows (results/progressive/) beside the current default, on the same held-out
# drives as every other table (seeds 1000000 and 1000001, 272x72, a bin every 5th frame, one
# input pair, LPIPS on; `eval` knows each bin's poses, so the pseudo pairs go to the bin's
# own later poses):
#   default          the shipped tiny weights, no pass
#   progressive      the pass with raw renders re-injected (--set enhancer=false), two
#                    pseudo pairs (centre and last pose)
#   plus             StereoSplat+: the pass with the shipped one-step enhancer, two pairs
#   progressive_one  raw renders, one pseudo pair (last pose): the `tiny-plus` preset's count
#   plus_one         StereoSplat+ as the `tiny-plus` preset runs it (one pair, enhancer)
# The enhancer rows are skipped, and said so, while model/weights/enhancer_tiny.safetensors
# does not exist (ENHANCER=FILE names other weights).
#   bash scripts/eval_progressive.sh [DATA_DIR] [OUT_DIR] [--set KEY=VALUE ...]
# Flags after the two folders go to every row's `stereosplat research eval`, e.g.
# `--set pseudo_fusion_margin=0.3` or `--weights FILE`.
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/heldout272}"
out="${2:-out/progressive}"
extra=("${@:3}")
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
enhancer="${ENHANCER:-model/weights/enhancer_tiny.safetensors}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
if [ ! -f "$data/data_poses/synth_drive_1000001_sync/poses.txt" ]; then
  "$bin" research synth-heldout --out "$data" --sequences 2 --frames 300 --width 272 --height 72
fi
run() {
  local name="$1"
  shift
  "$bin" research eval --data "$data" --method stereosplat --preset tiny --stride 5 "${extra[@]}" "$@" \
    --out "$out/$name"
}
run default
run progressive --set progressive=true --set enhancer=false
run progressive_one --set progressive=true --set enhancer=false --set "pseudo_poses=[8.0]"
if [ -f "$enhancer" ]; then
  run plus --set progressive=true --set "enhancer_weights=$enhancer"
  run plus_one --set progressive=true --set "enhancer_weights=$enhancer" --set "pseudo_poses=[8.0]"
else
  echo "no enhancer weights at $enhancer: the StereoSplat+ rows are skipped (bash scripts/train_enhancer.sh)"
fi
