#!/usr/bin/env bash
# The `tiny-3d` preset's two-phase chain (results/tiny_3d/README.md), the start of its stage
# at every scale, from the transfer stage of the `tiny` chain
# (runs/tiny_transfer/stereosplat_tiny.safetensors: scripts/train_tiny.sh, then
# scripts/train_tiny_transfer.sh), in three steps:
# 1. The first phase, runs/tiny_3d/cv3d: exactly the ablation's CV + 3D row
#    (scripts/ablation_tiny.sh: warm start from the transfer stage's weights, the volume
#    branch from its seeded initialisation, the transfer mix, 1,500 steps at lr 5e-4,
#    relative depth losses, one input pair, seed 0). Longer is not better: run on to 4,000
#    steps the same row loses 0.2 dB and its AbsRel edge (results/ablation_tiny/README.md).
# 2. The near-scene phase, runs/tiny_3d/near: 1,800 steps at lr 2e-4 from the first phase's
#    weights with the `tiny-3d` preset's own settings on every sample, so near samples of the
#    mix are fitted, hinted and run without the volume branch as real rooms are at inference
#    (the first phase's cost-volume Gaussians, trained beside the branch, left a quarter of a
#    room uncovered). About 70 min on a 2-core machine shared with other work.
# 3. The chain's file, runs/tiny_3d/blends/chosen.safetensors (which
#    scripts/train_tiny_3d_scales.sh trains on every scale for the shipped file): a point
#    on the straight line from the first phase's weights to the second's, tensor by tensor
#    (`stereosplat research interpolate-weights`, t = 0.25, 0.5, 0.75, 0.85 and 0.9, and the two
#    ends), chosen on generated validation drives by the rule of
#    scripts/choose_checkpoint.sh with the preset's settings (never on real pairs or the
#    held-out drives; runs/tiny_3d/blends/choice/README.md).
# Resumable: run it again after any interruption; a finished phase is skipped.
#   bash scripts/train_tiny_3d.sh
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
export STEREOSPLAT_BIN="$bin"
# The step a run folder's checkpoint has reached (0 without one).
step() {
  local s
  s=$(sed -n 's/.*"step": *\([0-9]*\).*/\1/p' "$1/checkpoint/state.json" 2>/dev/null | head -n 1 || true)
  echo "${s:-0}"
}
first=runs/tiny_3d/cv3d near_run=runs/tiny_3d/near
if [ "$(step "$first")" -lt 1500 ]; then
  ABLATION_RUNS=runs/tiny_3d bash scripts/ablation_tiny.sh train cv3d 1500
fi
near=(--data data/transfer --preset tiny-3d --out "$near_run" --steps 1800 --lr 2e-4
  --warmup 50 --seed 0 --depth-loss relative --rendered-depth-weight 0.5
  --estimated-depth-weight 0.5)
if [ -f "$near_run/checkpoint/state.json" ]; then
  [ "$(step "$near_run")" -ge 1800 ] || "$bin" research train "${near[@]}" --resume
else
  "$bin" research train "${near[@]}" --init "$first/stereosplat_tiny.safetensors"
fi
blends=runs/tiny_3d/blends
mkdir -p "$blends"
candidates=("t1|$near_run/stereosplat_tiny-3d.safetensors")
for t in 0.25 0.5 0.75 0.85 0.9; do
  file="$blends/t$t.safetensors"
  [ -f "$file" ] || "$bin" research interpolate-weights --from "$first/stereosplat_tiny.safetensors" \
    --to "$near_run/stereosplat_tiny-3d.safetensors" --t "$t" --out "$file"
  candidates+=("t$t|$file")
done
PRESET=tiny-3d CANDIDATES="${candidates[*]}" bash scripts/choose_checkpoint.sh "$blends" \
  "$first/stereosplat_tiny.safetensors"
chosen=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["file"])' \
  "$blends/choice/scores.json")
cp "$chosen" "$blends/chosen.safetensors"
echo "weights: $blends/chosen.safetensors ($chosen)"
