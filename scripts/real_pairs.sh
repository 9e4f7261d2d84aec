#!/usr/bin/env bash
# The learned model and SGM on real stereo pairs, through `stereosplat reconstruct`:
# disparity scores against ground truth on Middlebury Aloe and Motorcycle, photometric
# consistency on the 12 OAK-D pairs. Writes results/real_pairs/ (README.md with the tables,
# scores.json, pictures/); each run's full outputs stay under out/real_pairs/.
#
#   bash scripts/real_pairs.sh [--weights W] [--preset P] [--set KEY=VALUE ...] [--out DIR] [--data DIR]
#
# Needs the pairs (bash scripts/real_data.sh); builds the release binary (a no-op when fresh)
# unless STEREOSPLAT_BIN names one.
# Calibrations passed (disparities are scored in pixels; the rig only sets the depth range):
#   Aloe: fx 3740 px (Middlebury 2006's focal at full size), a 0.10 m baseline, principal
#     point at the centre: the truth's 45..211 px become 8.3..1.8 m, inside the learned
#     model's candidates (1..100 m = 374..3.7 px) and SGM's 1.5..80 m.
#   Motorcycle: Middlebury 2014's calibration at quarter size, fx 995 px, baseline 0.193 m:
#     the truth's 7..60 px are 27..3.2 m.
#   OAK-D: the pairs' own calibration (stereodemo_calibration.json).
set -euo pipefail
command="bash scripts/real_pairs.sh${*:+ $*}"
weights=() preset=() sets=() out=results/real_pairs data=data/real
while [ $# -gt 0 ]; do
  case "$1" in
    --weights) weights=(--weights "$(realpath -m "$2")"); shift 2 ;;
    --preset) preset=(--preset "$2"); shift 2 ;;
    --set) sets+=(--set "$2"); shift 2 ;;
    --out) out="$(realpath -m "$2")"; shift 2 ;;
    --data) data="$(realpath -m "$2")"; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
cd "$(dirname "$0")/.."
[ -s "$data/aloe/aloeGT.png" ] || { echo "no real pairs in $data: run bash scripts/real_data.sh $data" >&2; exit 1; }
# STEREOSPLAT_BIN: a built binary to use as is (no cargo build).
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
runs=out/real_pairs
rm -rf "$runs"

# reconstruct NAME METHOD ARGS...: one pair through one method into $runs/NAME/METHOD.
reconstruct() {
  local name="$1" method="$2"
  shift 2
  local extra=()
  # The learned model's own output is scored (flagged where it fails the self-check), not
  # the SGM fallback that `reconstruct` writes by default.
  [ "$method" = stereosplat ] && extra=("${weights[@]}" "${preset[@]}" "${sets[@]}" --on-check-fail flag)
  "$bin" reconstruct --method "$method" "${extra[@]}" --out "$runs/$name/$method" "$@" >/dev/null
  echo "$name $method: $(python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); print("%.1f s" % s["reconstruct_s"])' "$runs/$name/$method/summary.json")"
}

for method in sgm stereosplat; do
  reconstruct aloe "$method" --left "$data/aloe/aloeL.jpg" --right "$data/aloe/aloeR.jpg" \
    --fx 3740 --baseline 0.1 --truth-disparity "$data/aloe/aloeGT.png"
  reconstruct motorcycle "$method" --left "$data/motorcycle/motorcycle_left.png" \
    --right "$data/motorcycle/motorcycle_right.png" --fx 995 --baseline 0.193 \
    --truth-disparity "$data/motorcycle/motorcycle_disp.png" --truth-scale 0.00390625
  calib=$(python3 -c 'import json,sys; c=json.load(open(sys.argv[1])); print(c["fx"], c["fy"], c["cx0"], c["cy"], c["baseline_meters"])' "$data/oak-d/stereodemo_calibration.json")
  read -r fx fy cx cy b <<<"$calib"
  for left in "$data"/oak-d/*_left.png; do
    name=$(basename "$left" _left.png)
    reconstruct "oak-d/$name" "$method" --left "$left" --right "$data/oak-d/${name}_right.png" \
      --fx "$fx" --fy "$fy" --cx "$cx" --cy "$cy" --baseline "$b"
  done
done
python3 scripts/real_pairs.py --runs "$runs" --data "$data" --out "$out" \
  --command "$command"
