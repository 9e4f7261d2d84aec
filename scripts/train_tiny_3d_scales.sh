#!/usr/bin/env bash
# The `tiny-3d` preset's stage at every scale (results/tiny_3d/scales/README.md): the
# weights of its two-phase chain (INIT, default runs/tiny_3d/blends/chosen.safetensors,
# which scripts/train_tiny_3d.sh writes) trained by
# scripts/train_tiny_scales.sh on desks, rooms and streets at 544x112 with the 272x72
# plain streets in the mix from the first step (five kinds, plain streets 2 draws in 5:
# the `tiny` run showed the plain streets lose their AbsRel without them), at 2e-4 to step
# 600 and 1e-4 after; from step 1,501 with 4 more plain streets as a sixth kind (plain
# streets 3 draws in 6), since through step 1,500 the validation drives' plain streets
# stayed 0.3 dB under the start. The `tiny-3d` settings on every sample (its street-sized
# volume branch runs on far scenes only, as at inference). Every 100th step's weights are
# kept under RUN_DIR/kept/; then choose one on the validation drives:
#   bash scripts/train_tiny_3d_scales.sh [RUN_DIR] [STEPS]   (default runs/tiny_3d/scales, 2,400)
#   PRESET=tiny-3d bash scripts/choose_checkpoint.sh RUN_DIR INIT
# Resumable: run it again after any interruption. INIT, LR, LR3 and STEREOSPLAT_BIN pass on.
set -euo pipefail
cd "$(dirname "$0")/.."
export PRESET=tiny-3d PLAIN_FROM=0 MORE_FROM=0 MOST_FROM=1500 SLOW_FROM=600
export INIT="${INIT:-runs/tiny_3d/blends/chosen.safetensors}" LR="${LR:-2e-4}"
exec bash scripts/train_tiny_scales.sh "${1:-runs/tiny_3d/scales}" "${2:-2400}"
