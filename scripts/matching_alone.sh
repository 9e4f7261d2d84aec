#!/usr/bin/env bash
# How much of a learned model's depth its cost volume's matching gets right on its own
# (issue 14's diagnosis, results/transfer_diagnosis/). The depth head adds the U-Net's
# bounded logits to the correlation times a learned temperature; here a copy of the weights
# has its temperature set to 50 (the softmax becomes the correlation's winner) and runs with
# depth_logit_bound=0.25 (the U-Net's logits nearly off). Measured, beside the weights as
# they are and SGM:
#   - AbsRel on 6 held-out generated bins (data/heldout272, no LPIPS);
#   - the Aloe left image against itself shifted 12 px at 451x390: a fronto-parallel plane
#     at 400 px x 0.1 m / 12 px = 3.33 m (bad-3, EPE, depth percentiles).
# Writes OUT/matching_alone.json (one object per line) and prints it.
#   bash scripts/matching_alone.sh [WEIGHTS] [OUT] [--set KEY=VALUE ...]
# Settings after OUT go to both learned runs (e.g. `--set census_matching=false --set
# auto_depth_range=false --set sgm_guidance=null` for the weights shipped before stop 34).
set -euo pipefail
cd "$(dirname "$0")/.."
weights="$(realpath -m "${1:-model/weights/stereosplat_tiny.safetensors}")"
out="$(realpath -m "${2:-out/matching_alone}")"
extra=("${@:3}")
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
[ -s data/real/aloe/aloeL.jpg ] || { echo "no real pairs: run bash scripts/real_data.sh" >&2; exit 1; }
mkdir -p "$out"
python3 - "$weights" "$out" <<'EOF'
import json, struct, sys
import numpy as np
from PIL import Image
weights, out = sys.argv[1], sys.argv[2]
raw = bytearray(open(weights, "rb").read())
n = struct.unpack("<Q", raw[:8])[0]
start, end = json.loads(raw[8:8 + n])["depth_head.log_temperature"]["data_offsets"]
raw[8 + n + start:8 + n + end] = np.array([np.log(50.0)], dtype=np.float32).tobytes()
open(f"{out}/matching_alone.safetensors", "wb").write(raw)
left = np.array(Image.open("data/real/aloe/aloeL.jpg").convert("RGB").resize((451, 390)))
right = left.copy()
right[:, :-12] = left[:, 12:]
Image.fromarray(left).save(f"{out}/shift_left.png")
Image.fromarray(right).save(f"{out}/shift_right.png")
Image.fromarray(np.full(left.shape[:2], 12, np.uint8)).save(f"{out}/shift_truth.png")
EOF
: >"$out/matching_alone.json"
# run NAME ARGS...: the held-out bins and the shifted plane with one method.
run() {
  local name="$1"
  shift
  "$bin" eval --data data/heldout272 --stride 5 --max-bins 6 --pictures 0 --no-lpips \
    --out "$out/$name/eval" "$@" >/dev/null
  local learned=()
  [ "$2" = stereosplat ] && learned=(--on-check-fail flag "${@:3}")
  "$bin" reconstruct --method "$2" "${learned[@]}" --left "$out/shift_left.png" \
    --right "$out/shift_right.png" --fx 400 --baseline 0.1 \
    --truth-disparity "$out/shift_truth.png" --out "$out/$name/shift" >/dev/null
  python3 - "$name" "$out" <<'EOF' | tee -a "$out/matching_alone.json"
import json, sys
name, out = sys.argv[1], sys.argv[2]
summary = json.load(open(f"{out}/{name}/eval/eval.json"))["summary"]
absrel = round(summary["average"]["abs_rel"], 4)
first = round(summary["first"]["abs_rel"], 4)
shift = json.load(open(f"{out}/{name}/shift/summary.json"))
print(json.dumps({"what": name, "heldout_bin_avg_absrel": absrel, "heldout_first_absrel": first,
    "shift_bad3": round(shift["truth"]["bad3"], 2), "shift_epe_px": round(shift["truth"]["epe"], 3),
    "shift_depth_p5_p50_p95_m": [round(x, 2) for x in shift["depth_percentiles_m"]]}))
EOF
}
run sgm --method sgm
run as_is --method stereosplat --weights "$weights" "${extra[@]}"
run matching_alone --method stereosplat --weights "$out/matching_alone.safetensors" \
  --set depth_logit_bound=0.25 "${extra[@]}"
