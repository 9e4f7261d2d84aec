#!/usr/bin/env bash
# Writes the generated validation set: every setting, threshold, weight blend and checkpoint
# is chosen on it, never on real pairs and never on the held-out drives it is reported on.
# Seeds start at 2,000,000 (training seeds lie below 1,000,000, held-out evaluation seeds
# from 1,000,000 to 1,999,999): per kind, desk 2000000-2000003, room 2000100-2000103 and
# street 2000200-2000203, each a 40-frame sequence with a randomised rig (5-50 cm baselines
# and 320-1408 px widths for desks and rooms; the street's randomisation for streets), each
# in its own KITTI-360 root DATA/KIND_SEED (its own rig). Sequences already written are kept,
# so an interrupted run goes on where it stopped; run it in the background with nohup.
#   bash scripts/validation_data.sh [DATA_DIR]
# VALIDATION_SEQUENCES (default 4) sets how many sequences per kind, VALIDATION_FRAMES
# (default 40) their length, VALIDATION_SIZE ("WIDTH HEIGHT", e.g. "544 112": the node's
# working size) fixes the image size the randomised rigs would draw (their field of view
# and baseline are still drawn). VALIDATION_PLAIN (default 0) adds that many plain streets on
# KITTI-360's rig at 272x72, 80 frames each (seeds from 2,000,300, roots DATA/plain_SEED):
# the size of the demo and of the held-out streets.
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/validation}"
count="${VALIDATION_SEQUENCES:-4}"
frames="${VALIDATION_FRAMES:-40}"
size=()
if [ -n "${VALIDATION_SIZE:-}" ]; then
  read -r width height <<<"$VALIDATION_SIZE"
  size=(--width "$width" --height "$height")
fi
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
base=2000000
for kind in desk room street; do
  case "$kind" in
    desk) first=$base; word=desk ;;
    room) first=$((base + 100)); word=room ;;
    street) first=$((base + 200)); word=drive ;;
  esac
  for ((k = 0; k < count; k++)); do
    seed=$((first + k))
    root="$data/${kind}_$seed"
    name=$(printf "synth_%s_%07d_sync" "$word" "$seed")
    if [ ! -f "$root/data_poses/$name/poses.txt" ]; then
      "$bin" research synth --out "$root" --scene "$kind" --seed "$seed" --frames "$frames" --randomise "${size[@]}"
    fi
  done
done
for ((k = 0; k < ${VALIDATION_PLAIN:-0}; k++)); do
  seed=$((base + 300 + k))
  name=$(printf "synth_drive_%07d_sync" "$seed")
  [ -f "$data/plain_$seed/data_poses/$name/poses.txt" ] ||
    "$bin" research synth --out "$data/plain_$seed" --seed "$seed" --frames 80 --width 272 --height 72
done
echo "validation set under $data"
