#!/usr/bin/env bash
# `sgm_guidance` height x width on the two real pairs with ground truth (Aloe, Motorcycle),
# the learned model's own output (`--on-check-fail flag`), through `stereosplat reconstruct`
# with the calibrations of scripts/real_pairs.sh. One JSON object per line on stdout and in
# OUT/sweep.jsonl. Needs the pairs (bash scripts/real_data.sh).
#   [GRID="H:W ..."] bash scripts/guidance_sweep.sh [OUT] [--weights W] [--set KEY=VALUE ...]
# GRID: the height:width settings (height null turns the hints off); the default is the grid
# of results/sgm_guidance/sweep_census_weights.jsonl.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-out/guidance_sweep}"
shift || true
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
data=data/real
mkdir -p "$out"
: >"$out/sweep.jsonl"
for hw in ${GRID:-null:1 2:1 5:1 10:1 20:1 5:2 10:2 20:2}; do
  height=${hw%:*} width=${hw#*:}
  for pair in aloe motorcycle; do
    case "$pair" in
      aloe) args=(--left "$data/aloe/aloeL.jpg" --right "$data/aloe/aloeR.jpg" --fx 3740
        --baseline 0.1 --truth-disparity "$data/aloe/aloeGT.png") ;;
      motorcycle) args=(--left "$data/motorcycle/motorcycle_left.png"
        --right "$data/motorcycle/motorcycle_right.png" --fx 995 --baseline 0.193
        --truth-disparity "$data/motorcycle/motorcycle_disp.png" --truth-scale 0.00390625) ;;
    esac
    run="$out/$pair-$height-$width"
    "$bin" reconstruct --method stereosplat --on-check-fail flag "$@" \
      --set "sgm_guidance=$height" --set "sgm_guidance_width=$width" --out "$run" "${args[@]}" >/dev/null
    python3 - "$run/summary.json" "$pair" "$height" "$width" <<'PY' | tee -a "$out/sweep.jsonl"
import json, sys
s = json.load(open(sys.argv[1]))
t = s["truth"]
print(json.dumps({"pair": sys.argv[2], "sgm_guidance": sys.argv[3], "width": float(sys.argv[4]),
                  "bad1": round(t["bad1"], 2), "bad3": round(t["bad3"], 2), "epe": round(t["epe"], 2),
                  "density": round(t["density"], 1), "self_check": s["check"]["verdict"],
                  "seconds": round(s["reconstruct_s"], 2)}))
PY
  done
done
