#!/usr/bin/env bash
# Reproduces the tiny weights shipped at stop 34, kept in
# results/stereosplat_tiny_census_gate/ (issue 14; since stop 35 they are the start of
# scripts/train_tiny_guided.sh, which reproduces the shipped ones): the ablation's
# `cv_census05` row (scripts/ablation_tiny.sh), i.e. the weights shipped until then
# (results/stereosplat_tiny_transfer/, the transfer recipe) trained 1,500 more steps on the
# transfer mix (scripts/transfer_data.sh) with the soft census correlation in the matching
# term (`census_matching=true`) and the matching loss at weight 0.5, at seed 0, in its own run
# folder runs/tiny_census/cv_census05, then copied there. At stop 34 the `tiny` preset ran
# them with the census on and the depth range fitted to near scenes (`auto_depth_range=true`,
# `auto_depth_range_max_far=50`). Resumable: run it again after any interruption. About 45
# minutes on the 2-core machine (0.57 steps/s).
#   bash scripts/train_tiny_census.sh
set -euo pipefail
cd "$(dirname "$0")/.."
# The training mix; builds the binary unless STEREOSPLAT_BIN names one.
bash scripts/transfer_data.sh data/transfer
ABLATION_RUNS=runs/tiny_census bash scripts/ablation_tiny.sh train cv_census05 1500
cp runs/tiny_census/cv_census05/stereosplat_tiny.safetensors results/stereosplat_tiny_census_gate/stereosplat_tiny.safetensors
echo "weights: results/stereosplat_tiny_census_gate/stereosplat_tiny.safetensors"
