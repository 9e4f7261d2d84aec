#!/usr/bin/env bash
# Makes one shipped weight file from nothing by running its whole training chain, each stage
# in its own git-ignored folder under runs/ (the next stage reads the previous one's
# exported weights there), then copies the result into model/weights/.
#   bash scripts/reproduce_weights.sh tiny       # model/weights/stereosplat_tiny.safetensors
#   bash scripts/reproduce_weights.sh tiny-3d    # model/weights/stereosplat_tiny-3d.safetensors
#   bash scripts/reproduce_weights.sh enhancer   # model/weights/enhancer_tiny.safetensors
# The chains (times on a 2-core machine with other work beside it, from the runs in results/):
#   tiny      train_tiny.sh (runs/tiny, 7,000 steps, about 105 min)
#             -> train_tiny_transfer.sh (runs/tiny_transfer, 6,000 steps, about 67 min)
#             -> train_tiny_census.sh (runs/tiny_census/cv_census05, 1,500 steps, about 45 min)
#             -> train_tiny_guided.sh (runs/tiny_guided, 2,400 steps, about 40 min)
#             -> train_tiny_scales.sh (runs/tiny_scales, 3,000 steps on desks, rooms and
#             streets, about 2.5 h) -> choose_checkpoint.sh (the kept step the validation
#             drives choose, about 40 min)
#             results/stereosplat_tiny/README.md, results/stereosplat_tiny/scales/README.md
#   tiny-3d   train_tiny.sh -> train_tiny_transfer.sh
#             -> train_tiny_3d.sh (runs/tiny_3d/cv3d, 1,500 steps, 41-50 min; runs/tiny_3d/near,
#             1,800 steps, 40-70 min; the blend of the two chosen on validation drives,
#             runs/tiny_3d/blends, about 40 min)
#             -> train_tiny_3d_scales.sh (runs/tiny_3d/scales, 2,400 steps on desks, rooms and
#             streets at 544x112 and plain streets at 272x72, about 2.5 h)
#             -> choose_checkpoint.sh (the kept step the validation drives choose)
#             results/tiny_3d/README.md, results/tiny_3d/scales/README.md
#   enhancer  train_tiny.sh -> train_tiny_transfer.sh, and train_tiny.sh with unbounded depth
#             logits (runs/tiny_unbounded, 7,000 steps, about 107 min)
#             -> train_enhancer.sh (data/enhancer, runs/enhancer_tiny, about 70 min)
#             -> train_enhancer_scales.sh (the street enhancer fine-tuned on the shipped
#             tiny's renders of desks, rooms and streets at 544x112, and the kept step the
#             validation pairs choose; data/enhancer_scales, runs/enhancer_scales, about 2 h)
#             results/enhancer_tiny/README.md
# Resumable: run the same command again after any interruption. A stage whose run folder's
# checkpoint has reached its last step is skipped; an unfinished one resumes from its
# checkpoint; generated drives and pairs already written are kept. Training is seeded, but
# thread counts and the machine change the last digits, so a rerun's weights score close to,
# not exactly, the shipped file's figures.
# STEREOSPLAT_BIN: a built binary to use as is (otherwise the release binary is built once).
set -euo pipefail
cd "$(dirname "$0")/.."
target="${1:-}"
case "$target" in
  tiny | tiny-3d | enhancer) ;;
  *) echo "usage: $0 tiny|tiny-3d|enhancer" >&2; exit 2 ;;
esac
if [ -z "${STEREOSPLAT_BIN:-}" ]; then
  cargo build --release --bin stereosplat
  export STEREOSPLAT_BIN=target/release/stereosplat
fi

# The step a run folder's checkpoint has reached (0 without one).
step() {
  local s
  s=$(sed -n 's/.*"step": *\([0-9]*\).*/\1/p' "$1/checkpoint/state.json" 2>/dev/null | head -n 1 || true)
  echo "${s:-0}"
}

# stage RUN_DIR STEPS COMMAND...: runs COMMAND unless RUN_DIR's checkpoint is at STEPS.
stage() {
  local run="$1" steps="$2"
  shift 2
  if [ "$(step "$run")" -ge "$steps" ]; then
    echo "== $run: done (step $steps)"
  else
    echo "== $run: $*"
    "$@"
  fi
}

# ship RUN_DIR INIT DEST: chooses RUN_DIR's kept step on the validation drives
# (scripts/choose_checkpoint.sh, PRESET passes on) and copies it, or INIT if the start
# wins, to DEST.
ship() {
  local run="$1" init="$2" dest="$3" from
  bash scripts/choose_checkpoint.sh "$run" "$init"
  from=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["file"])' \
    "$run/choice/scores.json")
  cp "$from" "$dest"
  echo "weights: $dest ($from)"
}

stage runs/tiny 7000 bash scripts/train_tiny.sh data/train272 runs/tiny
stage runs/tiny_transfer 6000 bash scripts/train_tiny_transfer.sh data/transfer runs/tiny_transfer 6000
case "$target" in
  tiny)
    stage runs/tiny_census/cv_census05 1500 bash scripts/train_tiny_census.sh
    stage runs/tiny_guided 2400 env SHIP=0 bash scripts/train_tiny_guided.sh runs/tiny_guided 2400
    stage runs/tiny_scales 3000 bash scripts/train_tiny_scales.sh runs/tiny_scales 3000
    ship runs/tiny_scales runs/tiny_guided/stereosplat_tiny.safetensors \
      model/weights/stereosplat_tiny.safetensors
    ;;
  tiny-3d)
    # Skips its finished phases itself; writes runs/tiny_3d/blends/chosen.safetensors.
    bash scripts/train_tiny_3d.sh
    stage runs/tiny_3d/scales 2400 bash scripts/train_tiny_3d_scales.sh runs/tiny_3d/scales 2400
    PRESET=tiny-3d ship runs/tiny_3d/scales runs/tiny_3d/blends/chosen.safetensors \
      model/weights/stereosplat_tiny-3d.safetensors
    ;;
  enhancer)
    stage runs/tiny_unbounded 7000 bash scripts/train_tiny.sh data/train272 runs/tiny_unbounded \
      --set depth_logit_bound=null
    # Each skips the drives and pairs already written and resumes its training.
    bash scripts/train_enhancer.sh data/enhancer runs/enhancer_tiny
    bash scripts/train_enhancer_scales.sh data/enhancer_scales runs/enhancer_scales
    chosen=$(python3 scripts/enhancer_choice.py runs/enhancer_scales/choice)
    cp "runs/enhancer_scales/kept/$chosen.safetensors" model/weights/enhancer_tiny.safetensors
    echo "weights: model/weights/enhancer_tiny.safetensors ($chosen)"
    ;;
esac
