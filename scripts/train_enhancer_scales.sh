#!/usr/bin/env bash
# The one-step enhancer at every scale (model/weights/enhancer_tiny.safetensors,
# results/enhancer_tiny/README.md): the street enhancer of scripts/train_enhancer.sh
# (runs/enhancer_tiny) fine-tuned on renders by the shipped `tiny`
# (model/weights/stereosplat_tiny.safetensors) at the node's working size, 544x112, of desks,
# rooms and streets, and the kept step the validation drives choose.
# - Training drives, none of which StereoSplat trained on: desks (seeds 600-605, randomised
#   5-50 cm rigs, 40 frames, bins of 0.1 m), rooms (700-705, 40 frames, 0.3 m), streets
#   (800-805 randomised, 80 frames, 8 m) and plain streets on KITTI-360's rig (20-23, 120
#   frames), each in its own root under DATA/drives; PAIRS_PER_ROOT render -> truth pairs of
#   each (`enhancer-data`, K ~ U{1..3} input pairs) into one folder, DATA/pairs.
# - Validation pairs (the choice is made on them): VALIDATION_PAIRS per root of the validation
#   drives (scripts/validation_data.sh with VALIDATION_SEQUENCES=2 VALIDATION_SIZE="544 112"
#   VALIDATION_PLAIN=2, seeds 2,000,000 and up), one folder per kind (a batch holds one size).
# - Held-out pairs (reported, never chosen on): a randomised desk, room and street at
#   544x112 (`synth-heldout --scene KIND --randomise`, seed 1,000,000 each) and the two
#   held-out streets at 272x72 of every other table (seeds 1,000,000-1), one folder per kind.
# - `train-enhancer --init runs/enhancer_tiny/enhancer_tiny.safetensors` in RUN_DIR, STEPS
#   steps at LR, in segments of KEEP_EVERY steps, each segment's weights kept as
#   RUN_DIR/kept/step_N.safetensors (step 0: the street enhancer itself).
# - The choice (RUN_DIR/choice/scores.json, README.md): every kept step scored with
#   `eval-enhancer` on the validation pairs of each kind; the step with the lowest LPIPS
#   averaged over the four kinds is chosen, among the steps whose PSNR on no kind is more
#   than 0.1 dB under step 0's (a fine-tune that trades pixels away for texture is refused).
#   The held-out pairs then score the chosen step and step 0 side by side.
# Resumable: drives, pairs, the checkpoint and the kept steps already written are kept.
#   bash scripts/train_enhancer_scales.sh [DATA_DIR] [RUN_DIR]
#   (defaults data/enhancer_scales, runs/enhancer_scales)
#   PAIRS_PER_ROOT=120 VALIDATION_PAIRS=60 HELDOUT_PAIRS=60 STEPS=500 KEEP_EVERY=125 LR=3e-4
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-data/enhancer_scales}"
run="${2:-runs/enhancer_scales}"
per_root="${PAIRS_PER_ROOT:-120}"
validation_pairs="${VALIDATION_PAIRS:-60}"
heldout_pairs="${HELDOUT_PAIRS:-60}"
steps="${STEPS:-500}"
keep_every="${KEEP_EVERY:-125}"
lr="${LR:-3e-4}"
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --bin stereosplat
start=runs/enhancer_tiny/enhancer_tiny.safetensors
tiny=model/weights/stereosplat_tiny.safetensors
if [ ! -f "$start" ]; then
  echo "missing $start: run bash scripts/train_enhancer.sh first" >&2
  exit 1
fi
size=(--width 544 --height 112)
written() { [ -f "$1/data_poses/$2/poses.txt" ]; }
# Bins as training cuts them, but 0.3 m for rooms: a handheld room path of 40 frames may
# never lie 0.5 m from any of its frames (seed 700's reaches 0.42 m).
bin_length() {
  case "$1" in
    desk) echo 0.1 ;;
    room) echo 0.3 ;;
    *) echo 8 ;;
  esac
}

# pairs ROOT OUT TOTAL SEED KIND: pairs of ROOT's bins, rendered by `tiny`, until OUT holds
# TOTAL (the roots of one folder are filled in a fixed order, so a rerun goes on where it
# stopped).
pairs() {
  "$bin" research enhancer-data --data "$1" --out "$2" --pairs "$3" --seed "$4" \
    --bin-length "$(bin_length "$5")" --weights "tiny=$tiny" >/dev/null
}

# 1. Training drives and pairs.
roots=()
for seed in 20 21 22 23; do
  root="$data/drives/plain_$seed"
  written "$root" "$(printf "synth_drive_%07d_sync" "$seed")" ||
    "$bin" research synth --out "$root" --seed "$seed" --frames 120 "${size[@]}"
  roots+=("plain:$root")
done
for row in "desk 600 desk 40" "room 700 room 40" "street 800 drive 80"; do
  read -r kind first word frames <<<"$row"
  for ((k = 0; k < 6; k++)); do
    seed=$((first + k))
    root="$data/drives/${kind}_$seed"
    written "$root" "$(printf "synth_%s_%07d_sync" "$word" "$seed")" ||
      "$bin" research synth --out "$root" --scene "$kind" --seed "$seed" --frames "$frames" --randomise "${size[@]}"
    roots+=("$kind:$root")
  done
done
total=0
for entry in "${roots[@]}"; do
  total=$((total + per_root))
  pairs "${entry#*:}" "$data/pairs" "$total" 0 "${entry%%:*}"
done
echo "training pairs: $(($(wc -l <"$data/pairs/pairs.csv") - 1))"

# 2. Validation and held-out pairs, one folder per kind.
VALIDATION_SEQUENCES=2 VALIDATION_SIZE="544 112" VALIDATION_PLAIN=2 STEREOSPLAT_BIN="$bin" \
  bash scripts/validation_data.sh data/validation_choice >/dev/null
for kind in desk room street; do
  frames=40
  [ "$kind" = street ] && frames=80
  word=$kind
  [ "$kind" = street ] && word=drive
  written "$data/heldout_drives/$kind" "$(printf "synth_%s_1000000_sync" "$word")" ||
    "$bin" research synth-heldout --out "$data/heldout_drives/$kind" --scene "$kind" --frames "$frames" \
      --randomise "${size[@]}"
done
written "$data/heldout_drives/plain" synth_drive_1000001_sync ||
  "$bin" research synth-heldout --out "$data/heldout_drives/plain" --sequences 2 --frames 300 --width 272 --height 72
for kind in desk room street plain; do
  total=0
  for root in data/validation_choice/"${kind}"_*; do
    total=$((total + validation_pairs))
    pairs "$root" "$data/validation/$kind" "$total" 1 "$kind"
  done
  total=0
  for root in "$data"/heldout_drives/"$kind"*; do
    total=$((total + heldout_pairs))
    [ "$kind" = plain ] && total=$((2 * heldout_pairs))  # two sequences in its one root
    pairs "$root" "$data/heldout/$kind" "$total" 2 "$kind"
  done
done

# 3. Fine-tuning in segments; each segment's weights kept.
mkdir -p "$run/kept"
cp -n "$start" "$run/kept/step_0.safetensors"
for ((s = keep_every; s <= steps; s += keep_every)); do
  [ -f "$run/kept/step_$s.safetensors" ] && continue
  from=(--init "$start")
  [ -f "$run/checkpoint/state.json" ] && from=(--resume)
  "$bin" research train-enhancer --pairs "$data/pairs" --preset tiny --out "$run" --steps "$s" --lr "$lr" \
    "${from[@]}"
  cp "$run/enhancer_tiny.safetensors" "$run/kept/step_$s.safetensors"
done

# 4. Every kept step on the validation pairs, then the chosen one and step 0 on the held-out.
# score SET STEP: kept step STEP's reports on the pairs of SET (validation, heldout), per kind.
score() {
  local set="$1" step="$2" folder="$run/choice" kind out
  [ "$set" = heldout ] && folder="$run/heldout"
  mkdir -p "$folder"
  for kind in desk room street plain; do
    out="$folder/${step}_$kind.json"
    [ -f "$out" ] || "$bin" research eval-enhancer --pairs "$data/$set/$kind" --preset tiny \
      --weights "$run/kept/$step.safetensors" --out "$out" >/dev/null
  done
}
for w in "$run"/kept/step_*.safetensors; do
  score validation "$(basename "$w" .safetensors)"
done
chosen=$(python3 scripts/enhancer_choice.py "$run/choice")
score heldout step_0
score heldout "$chosen"
echo "chosen: $run/kept/$chosen.safetensors ($run/choice/README.md)"
