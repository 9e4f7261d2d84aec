#!/usr/bin/env bash
# The stage that trains a preset of the `tiny` family on every scale at the node's working
# size, 544x112 (scripts/scales_data.sh): desks, rooms and streets, each kind drawn equally
# often and cut into its own bins (0.1 m, 0.5 m, 8 m), with the preset's settings on every
# sample (depth candidates from each sample's rig, the fitted range for scenes nearer than
# 50 m, SGM's hints, and `tiny`'s census matching), the guided stage's losses (relative
# depth losses, the matching loss at 0.5), seed 0, in RUN_DIR (default runs/tiny_scales).
# For `tiny` (the default, stage 5 of its chain: results/stereosplat_tiny/scales/README.md,
# scripts/reproduce_weights.sh), from the guided stage's weights
# (runs/tiny_guided/stereosplat_tiny.safetensors, scripts/train_tiny_guided.sh), three
# phases: steps 1-1,500 on those three kinds; then, to step 2,100, with the plain streets at
# 272x72 (the demo's size) as a fourth kind, since the first phase alone cost the plain
# streets of the validation set their AbsRel; and from step 2,101 to STEPS (default 3,000)
# at a third of the rate (LR3, default 1e-4) with 4 more plain streets as a fifth kind
# (plain streets drawn 2 times in 5), since the second phase still left them short of the
# start on the validation drives. PLAIN_FROM (1,500), MORE_FROM (2,100) and SLOW_FROM
# (2,100) move those phase ends, and MOST_FROM (default: never) adds 4 plain streets more
# as a sixth kind (plain streets then drawn 3 times in 6): scripts/train_tiny_3d_scales.sh
# sets them for `tiny-3d`.
# The weights of every 100th step are kept under RUN_DIR/kept/ so one is chosen on the
# validation drives: bash scripts/choose_checkpoint.sh RUN_DIR INIT.
# Resumable: run it again after any interruption (a copy of the checkpoint of the `tiny`
# run in results/stereosplat_tiny/scales/checkpoint/ goes in RUN_DIR/checkpoint/).
#   bash scripts/train_tiny_scales.sh [RUN_DIR] [STEPS]   (default 3,000)
# Environment: PRESET (default tiny); INIT, the weights a fresh run starts from (default the
# guided stage's); LR (default 3e-4) before SLOW_FROM; SETTINGS, extra `--set` flags.
set -euo pipefail
cd "$(dirname "$0")/.."
run="${1:-runs/tiny_scales}" steps="${2:-3000}" preset="${PRESET:-tiny}"
plain_from="${PLAIN_FROM:-1500}" more_from="${MORE_FROM:-2100}" slow_from="${SLOW_FROM:-2100}"
most_from="${MOST_FROM:-$steps}"
init="${INIT:-runs/tiny_guided/stereosplat_tiny.safetensors}"
if [ ! -f "$run/checkpoint/state.json" ] && [ ! -f "$init" ]; then
  echo "missing $init: run bash scripts/train_tiny_guided.sh first, or set INIT" >&2
  exit 1
fi
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
STEREOSPLAT_BIN="$bin" bash scripts/scales_data.sh data/scales
kinds=(--data data/scales/desk --data data/scales/room --data data/scales/street
  --bin-length 0.1 --bin-length 0.5 --bin-length 8)
plain=(--data data/scales/plain272 --bin-length 8)
more=(--data data/scales/plain272b --bin-length 8)
most=(--data data/scales/plain272c --bin-length 8)
flags=(--preset "$preset" --out "$run" --warmup 100 --seed 0
  --checkpoint-every 100 --depth-loss relative --rendered-depth-weight 0.5
  --estimated-depth-weight 0.5 --matching-weight 0.5 --set view_subsampling=false
  ${SETTINGS:-})
# Trains in legs of 100 steps so every checkpoint's weights are kept for the choice.
mkdir -p "$run/kept"
for ((to = 100; to <= steps; to += 100)); do
  [ -f "$run/kept/step_$to.safetensors" ] && continue
  data=("${kinds[@]}")
  lr="${LR:-3e-4}"
  ((to > plain_from)) && data+=("${plain[@]}")
  ((to > more_from)) && data+=("${more[@]}")
  ((to > most_from)) && data+=("${most[@]}")
  ((to > slow_from)) && lr="${LR3:-1e-4}"
  if [ -f "$run/checkpoint/state.json" ]; then
    "$bin" research train "${data[@]}" "${flags[@]}" --lr "$lr" --resume --steps "$to"
  else
    "$bin" research train "${data[@]}" "${flags[@]}" --lr "$lr" --init "$init" --steps "$to"
  fi
  cp "$run/stereosplat_$preset.safetensors" "$run/kept/step_$to.safetensors"
done
