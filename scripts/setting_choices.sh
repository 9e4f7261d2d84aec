#!/usr/bin/env bash
# The learned default's settings, each switched off (or changed) alone, on two generated
# validation sets (seeds from 2,000,000: never trained on, never the held-out evaluation),
# beside SGM, the classical floor:
# - fixed rigs: desks (0.2-1 m, 10 cm rig, 320x96), rooms (1-10 m, 320x96) and streets
#   (KITTI-360's rig, 272x72), seeds 2,000,000 and 2,000,001 (out/rig_range/data);
# - randomised rigs at the node's working size, 544x112: desks, rooms and streets with
#   5-50 cm baselines (scripts/validation_data.sh) and plain streets at 272x72, the drives
#   scripts/choose_checkpoint.sh chooses checkpoints on (data/validation_choice).
# Every inference setting of `tiny` is kept, changed or removed on these figures by the
# rule of scripts/setting_choices.py; real pairs are only reported (scripts/real_pairs.sh).
# Writes results/setting_choices/ (README.md, scores.json).
#
#   bash scripts/setting_choices.sh [OUT_DIR]   (default results/setting_choices)
#
# SETTING_PRESET runs another preset than `tiny` (its runs are kept apart):
#   SETTING_PRESET=tiny-3d bash scripts/setting_choices.sh results/setting_choices/tiny-3d
#
# Builds the release binary unless STEREOSPLAT_BIN names one; drives and runs go to
# out/rig_range/ and data/validation_choice/.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-results/setting_choices}"
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
work=out/rig_range
preset="${SETTING_PRESET:-tiny}"
# Runs of `tiny` keep their folder names; other presets' are prefixed with the preset.
prefix=""
[ "$preset" = tiny ] || prefix="$preset-"
mkdir -p "$work" "$out"

# name|settings (space-separated KEY=VALUE) : each variant is the default with these changed.
# The variant named SGM runs `--method sgm` instead.
variants=(
  "default|"
  "SGM|"
  "candidates in metres|rig_disparity_fraction=null"
  "no sgm_snap|sgm_snap=false"
  "no sgm_fill|sgm_fill=false"
  "no sgm_guidance|sgm_guidance=null sgm_snap=false"
  "sgm_guidance 5|sgm_guidance=5"
  "sgm_guidance 20|sgm_guidance=20"
  "no auto_depth_range|auto_depth_range=false"
  "fit every scene|auto_depth_range_max_far=null"
)
# `tiny-3d` (SETTING_PRESET=tiny-3d) is `tiny` with the volume branch and its own weights:
# its rows are the choices its preset makes beyond `tiny`'s.
if [ "${SETTING_PRESET:-tiny}" = tiny-3d ]; then
  variants=(
    "default|"
    "SGM|"
    "candidates in metres|rig_disparity_fraction=null"
    "no sgm_snap|sgm_snap=false"
    "no sgm_fill|sgm_fill=false"
    "volume branch on near scenes|volume_branch_far_only=false"
    "no volume branch|volume_branch=false"
  )
fi
# SETTING_VARIANTS (lines of name|settings) replaces the list; SETTING_BASE (KEY=VALUE ...)
# is applied to every variant before its own settings.
[ -n "${SETTING_VARIANTS:-}" ] && mapfile -t variants <<<"$SETTING_VARIANTS"

# scene, frames, size, bin length (m), stride: desks move about 1 cm per frame, rooms a few cm.
scenes=("desk 24 320 96 0.1 1" "room 24 320 96 0.5 1" "street 80 272 72 8 5")
for row in "${scenes[@]}"; do
  read -r scene frames width height bin_length stride <<<"$row"
  for seed in 2000000 2000001; do
    [ -d "$work/data/$scene/data_2d_raw" ] && ls "$work/data/$scene/data_2d_raw" | grep -q "$seed" && continue
    "$bin" research synth --scene "$scene" --seed "$seed" --frames "$frames" --width "$width" \
      --height "$height" --out "$work/data/$scene" >/dev/null
  done
  for variant in "${variants[@]}"; do
    name="${variant%%|*}"
    sets=()
    for kv in ${SETTING_BASE:-} ${variant#*|}; do sets+=(--set "$kv"); done
    dir="$work/choices/$prefix$scene-${name// /_}"
    [ -f "$dir/eval.json" ] && continue
    method=(--method stereosplat --preset "$preset" "${sets[@]}")
    [ "$name" = SGM ] && method=(--method sgm)
    "$bin" research eval --data "$work/data/$scene" "${method[@]}" \
      --bin-length "$bin_length" --stride "$stride" --max-bins 6 --pictures 0 --no-lpips \
      --out "$dir" >/dev/null
  done
done

# The randomised rigs: each sequence in its own root (its own rig), scored alone.
random=data/validation_choice
VALIDATION_SEQUENCES=2 VALIDATION_SIZE="544 112" VALIDATION_PLAIN=2 STEREOSPLAT_BIN="$bin" \
  bash scripts/validation_data.sh "$random" >/dev/null
# kind, bin length (m), stride: as scripts/choose_checkpoint.sh.
for row in "desk 0.1 1" "room 0.5 1" "street 8 5" "plain 8 5"; do
  read -r kind bin_length stride <<<"$row"
  for variant in "${variants[@]}"; do
    name="${variant%%|*}"
    sets=()
    for kv in ${SETTING_BASE:-} ${variant#*|}; do sets+=(--set "$kv"); done
    method=(--method stereosplat --preset "$preset" "${sets[@]}")
    [ "$name" = SGM ] && method=(--method sgm)
    for root in "$random/${kind}_"*; do
      dir="$work/randomised/$prefix$kind-${name// /_}/$(basename "$root")"
      [ -f "$dir/eval.json" ] && continue
      "$bin" research eval --data "$root" "${method[@]}" \
        --bin-length "$bin_length" --stride "$stride" --max-bins 6 --pictures 0 --no-lpips \
        --out "$dir" >/dev/null
    done
  done
done

# The README names the command with the environment that changed what ran.
command="bash scripts/setting_choices.sh $out"
[ "$preset" = tiny ] || command="SETTING_PRESET=$preset $command"
[ -z "${SETTING_BASE:-}" ] || command="SETTING_BASE=\"$SETTING_BASE\" $command"
own=()
if [ -n "${SETTING_VARIANTS:-}" ]; then
  command="SETTING_VARIANTS=\$'${SETTING_VARIANTS//$'\n'/\\n}' $command"
  own=(--no-notes)
fi
python3 scripts/setting_choices.py --fixed "$work/choices" --randomised "$work/randomised" \
  --out "$out" --preset "$preset" --prefix "$prefix" --command "$command" "${own[@]}" \
  -- "${variants[@]}"
