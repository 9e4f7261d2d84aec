#!/usr/bin/env bash
# Reproduces the shipped tiny weights (model/weights/stereosplat_tiny.safetensors, since stop
# 34; issue 14): the ablation's `cv_census05` row (scripts/ablation_tiny.sh), i.e. the weights
# shipped until then (results/stereosplat_tiny_transfer/, the transfer recipe) trained 1,500
# more steps on the transfer mix (scripts/transfer_data.sh) with the soft census correlation
# in the matching term (`census_matching=true`) and the matching loss at weight 0.5, at seed 0,
# in its own run folder runs/tiny_census/cv_census05, then copied into model/weights/. The
# `tiny` preset runs them with the census on, the depth range fitted to near scenes
# (`auto_depth_range=true`, `auto_depth_range_max_far=50`) and, since stop 35, SGM's matches
# guiding near scenes (`sgm_guidance=10`; trained without them). Resumable: run it again after any
# interruption. About 45 minutes on the 2-core machine (0.57 steps/s).
#   bash scripts/train_tiny_census.sh
set -euo pipefail
cd "$(dirname "$0")/.."
# The training mix; builds the binary unless STEREOSPLAT_BIN names one.
bash scripts/transfer_data.sh data/transfer
ABLATION_RUNS=runs/tiny_census bash scripts/ablation_tiny.sh train cv_census05 1500
cp runs/tiny_census/cv_census05/stereosplat_tiny.safetensors model/weights/stereosplat_tiny.safetensors
echo "weights: model/weights/stereosplat_tiny.safetensors"
