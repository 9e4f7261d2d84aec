#!/usr/bin/env bash
# Trains the `tiny-3d` preset's weights (issue 17's second operating point, issue 15's CV + 3D
# row): exactly the ablation's CV + 3D row (scripts/ablation_tiny.sh: warm start from the
# shipped cost-volume weights, the volume branch from its seeded initialisation, the transfer
# mix, 1,500 steps at lr 5e-4, relative depth losses, one input pair), in its own run folder
# runs/tiny_3d/cv3d, then copied to model/weights/stereosplat_tiny-3d.safetensors. Longer is
# not better: run on to 4,000 steps the same row loses 0.2 dB and its AbsRel edge
# (results/tiny_3d/README.md). Resumable: run it again after any interruption.
#   bash scripts/train_tiny_3d.sh
set -euo pipefail
cd "$(dirname "$0")/.."
ABLATION_RUNS=runs/tiny_3d bash scripts/ablation_tiny.sh train cv3d 1500
cp runs/tiny_3d/cv3d/stereosplat_tiny.safetensors model/weights/stereosplat_tiny-3d.safetensors
echo "weights: model/weights/stereosplat_tiny-3d.safetensors"
