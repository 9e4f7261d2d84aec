#!/usr/bin/env bash
# Writes the training mix of every scale at the node's working size, 544x112: desks (seeds
# 300-311, 0.2-1 m, handheld rigs of 5-50 cm), rooms (seeds 400-411, 1-10 m) and streets
# (seeds 500-511 domain-randomised, 5-60 cm rigs; seeds 0-3 plain, KITTI-360's rig), each
# randomised sequence in its own KITTI-360 root (its own rig) under DATA/desk, DATA/room and
# DATA/street, so `train --data DATA/desk --data DATA/room --data DATA/street` draws the
# three kinds equally often, each cut with its own bin length; and the same 4 plain streets
# at 272x72, 300 frames, under DATA/plain272 (the demo's size, which the second phase of
# scripts/train_tiny_scales.sh keeps in the mix), with 4 more (seeds 4-7) under
# DATA/plain272b for its third phase, and 4 more (seeds 8-11) under DATA/plain272c, which
# scripts/train_tiny_3d_scales.sh adds so plain streets are half its draws. Randomised
# sequences keep
# their drawn field of view and baseline at the fixed size. Sequences already written are
# kept, so an interrupted run goes on.
#   bash scripts/scales_data.sh [DATA_DIR]   (default data/scales)
# SCALES_SEQUENCES (default 12) sets the randomised sequences per kind.
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/scales}"
count="${SCALES_SEQUENCES:-12}"
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
size=(--width 544 --height 112)
written() { [ -f "$1/data_poses/$2/poses.txt" ]; }
for seed in 0 1 2 3; do
  name=$(printf "synth_drive_%07d_sync" "$seed")
  written "$data/street/plain" "$name" ||
    "$bin" research synth --out "$data/street/plain" --seed "$seed" --frames 120 "${size[@]}"
done
for seed in 0 1 2 3 4 5 6 7 8 9 10 11; do
  name=$(printf "synth_drive_%07d_sync" "$seed")
  root="$data/plain272"
  ((seed < 4)) || root="$data/plain272b"
  ((seed < 8)) || root="$data/plain272c"
  written "$root" "$name" ||
    "$bin" research synth --out "$root" --seed "$seed" --frames 300 --width 272 --height 72
done
# kind, first seed, word in the sequence name, frames
for row in "desk 300 desk 40" "room 400 room 40" "street 500 drive 80"; do
  read -r kind first word frames <<<"$row"
  for ((k = 0; k < count; k++)); do
    seed=$((first + k))
    root="$data/$kind/rand_$seed"
    name=$(printf "synth_%s_%07d_sync" "$word" "$seed")
    written "$root" "$name" ||
      "$bin" research synth --out "$root" --scene "$kind" --seed "$seed" --frames "$frames" --randomise "${size[@]}"
  done
done
echo "training mix of every scale under $data"
