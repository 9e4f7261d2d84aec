#!/usr/bin/env bash
# Stage 5 of `tiny`'s chain, the shipped one (results/stereosplat_tiny/scales/README.md,
# scripts/reproduce_weights.sh): the guided stage's weights
# (runs/tiny_guided/stereosplat_tiny.safetensors, scripts/train_tiny_guided.sh) trained on
# desks, rooms and streets at the node's working size, 544x112 (scripts/scales_data.sh),
# each kind drawn equally often and cut into its own bins (0.1 m, 0.5 m, 8 m), with the
# preset's settings on every sample: depth candidates from each sample's rig, the fitted
# range for scenes nearer than 50 m, census matching and SGM's hints; the guided stage's
# losses, seed 0, in RUN_DIR (default runs/tiny_scales).
# Three phases: steps 1-1,500 on those three kinds; then, to step 2,100, with the
# plain streets at 272x72 (the demo's size) as a fourth kind, since the first phase alone
# cost the plain streets of the validation set their AbsRel; and from step 2,101 to
# STEPS (default 3,000) at a third of the rate (LR3, default 1e-4) with 4 more plain
# streets as a fifth kind (plain streets drawn 2 times in 5), since the second phase still
# left them short of the start on the validation drives. The weights of every 100th
# step are kept under RUN_DIR/kept/ so one is chosen on the validation drives:
# bash scripts/choose_checkpoint.sh RUN_DIR runs/tiny_guided/stereosplat_tiny.safetensors.
# Resumable: run it again after any interruption (a copy of the checkpoint of the run in
# results/stereosplat_tiny/scales/checkpoint/ goes in RUN_DIR/checkpoint/).
#   bash scripts/train_tiny_scales.sh [RUN_DIR] [STEPS]   (default 3,000)
# Environment: INIT, the weights a fresh run starts from (default the guided stage's);
# LR (default 3e-4) for the first two phases; SETTINGS, extra `--set` flags.
set -euo pipefail
cd "$(dirname "$0")/.."
run="${1:-runs/tiny_scales}" steps="${2:-3000}"
init="${INIT:-runs/tiny_guided/stereosplat_tiny.safetensors}"
if [ ! -f "$run/checkpoint/state.json" ] && [ ! -f "$init" ]; then
  echo "missing $init: run bash scripts/train_tiny_guided.sh first" >&2
  exit 1
fi
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
STEREOSPLAT_BIN="$bin" bash scripts/scales_data.sh data/scales
kinds=(--data data/scales/desk --data data/scales/room --data data/scales/street
  --bin-length 0.1 --bin-length 0.5 --bin-length 8)
plain=(--data data/scales/plain272 --bin-length 8)
more=(--data data/scales/plain272b --bin-length 8)
flags=(--preset tiny --out "$run" --warmup 100 --seed 0
  --checkpoint-every 100 --depth-loss relative --rendered-depth-weight 0.5
  --estimated-depth-weight 0.5 --matching-weight 0.5 --set volume_branch=false
  --set view_subsampling=false ${SETTINGS:-})
# Trains in legs of 100 steps so every checkpoint's weights are kept for the choice.
mkdir -p "$run/kept"
for ((to = 100; to <= steps; to += 100)); do
  [ -f "$run/kept/step_$to.safetensors" ] && continue
  data=("${kinds[@]}")
  lr="${LR:-3e-4}"
  ((to > 1500)) && data+=("${plain[@]}")
  ((to > 2100)) && data+=("${more[@]}") && lr="${LR3:-1e-4}"
  if [ -f "$run/checkpoint/state.json" ]; then
    "$bin" train "${data[@]}" "${flags[@]}" --lr "$lr" --resume --steps "$to"
  else
    "$bin" train "${data[@]}" "${flags[@]}" --lr "$lr" --init "$init" --steps "$to"
  fi
  cp "$run/stereosplat_tiny.safetensors" "$run/kept/step_$to.safetensors"
done
