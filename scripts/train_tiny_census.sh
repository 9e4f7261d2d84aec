#!/usr/bin/env bash
# The third stage of the shipped `tiny` weights' chain (results/stereosplat_tiny/README.md,
# "Stage 3"): the transfer stage's weights (runs/tiny_transfer/stereosplat_tiny.safetensors,
# scripts/train_tiny_transfer.sh) trained 1,500 more steps on the transfer mix
# (scripts/transfer_data.sh) with the soft census correlation in the matching term
# (`census_matching=true`) and the matching loss at weight 0.5, at seed 0: the
# `cv_census05` row of scripts/ablation_tiny.sh, in its own run folder
# runs/tiny_census/cv_census05 (scripts/train_tiny_guided.sh starts from
# runs/tiny_census/cv_census05/stereosplat_tiny.safetensors). Resumable: run it again after
# any interruption. About 45 minutes on a 2-core machine (0.57 steps/s).
#   bash scripts/train_tiny_census.sh
set -euo pipefail
cd "$(dirname "$0")/.."
# The training mix; builds the binary unless STEREOSPLAT_BIN names one.
bash scripts/transfer_data.sh data/transfer
ABLATION_RUNS=runs/tiny_census bash scripts/ablation_tiny.sh train cv_census05 1500
echo "weights: runs/tiny_census/cv_census05/stereosplat_tiny.safetensors (next: bash scripts/train_tiny_guided.sh)"
