#!/usr/bin/env bash
# The network's rig-derived depth candidates (`rig_disparity_fraction`) on generated
# validation drives (seeds from 2,000,000: never trained or evaluated on): desks
# (0.2-1 m, 10 cm rig), rooms (1-10 m) and streets (KITTI-360's rig), each scored with the
# candidates in metres (off), at the KITTI-360 rig's share (0.233181, tiny's default) and at
# a third of the width, beside SGM. Writes results/rig_range/ (README.md, scores.json).
#
#   bash scripts/rig_range_validation.sh [OUT_DIR]   (default results/rig_range)
#
# Builds the release binary unless STEREOSPLAT_BIN names one; drives and runs go to
# out/rig_range/.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-results/rig_range}"
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
work=out/rig_range
mkdir -p "$work" "$out"

# scene, frames, size, bin length (m), stride: desks move about 1 cm per frame, rooms a few cm.
scenes=("desk 24 320 96 0.1 1" "room 24 320 96 0.5 1" "street 80 272 72 8 5")
for row in "${scenes[@]}"; do
  read -r scene frames width height bin_length stride <<<"$row"
  for seed in 2000000 2000001; do
    [ -d "$work/data/$scene/data_2d_raw" ] && ls "$work/data/$scene/data_2d_raw" | grep -q "$seed" && continue
    "$bin" synth --scene "$scene" --seed "$seed" --frames "$frames" --width "$width" \
      --height "$height" --out "$work/data/$scene" >/dev/null
  done
  for variant in off 0.233181 0.333333 sgm; do
    args=(--method stereosplat)
    case "$variant" in
      off) args+=(--set rig_disparity_fraction=null) ;;
      sgm) args=(--method sgm) ;;
      *) args+=(--set "rig_disparity_fraction=$variant") ;;
    esac
    "$bin" eval --data "$work/data/$scene" "${args[@]}" --bin-length "$bin_length" \
      --stride "$stride" --max-bins 6 --pictures 0 --no-lpips \
      --out "$work/eval/$scene-$variant" >/dev/null
  done
done

python3 - "$work/eval" "$out" <<'PY'
import json, pathlib, sys
runs, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
names = {"off": "metres (1-100 m)", "0.233181": "rig, 0.233181 (tiny)", "0.333333": "rig, a third", "sgm": "SGM"}
rows, scores = [], {}
for scene in ["desk", "room", "street"]:
    for v, label in names.items():
        d = json.loads((runs / f"{scene}-{v}" / "eval.json").read_text())
        a = d["summary"]["average"]
        scores[f"{scene}/{v}"] = {"bins": len(d["bins"]), "psnr": a["psnr"], "abs_rel": a["abs_rel"]}
        rows.append(f"| {scene} | {label} | {len(d['bins'])} | {a['psnr']:.2f} | {a['abs_rel']:.3f} |")
lines = [
    "# Rig-derived depth candidates on generated validation drives",
    "",
    "Made by `bash scripts/rig_range_validation.sh`: 2 validation drives per scene (seeds",
    "2,000,000 and 2,000,001; training uses seeds below 1,000,000 and the held-out",
    "evaluation 1,000,000 to 1,999,999), the shipped `tiny` weights with the candidates in",
    "metres, at the KITTI-360 rig's share of the width (0.233181: on that rig exactly the",
    "1-100 m the weights learned) and at a third of the width, beside SGM. Bin-average PSNR of",
    "the bin's frames rendered from its map, AbsRel of the rendered depth against the",
    "generator's LiDAR. Desks: 320x96, 10 cm rig, 0.1 m bins; rooms: 320x96, 0.5 m bins;",
    "streets: 272x72, KITTI-360's rig, 8 m bins every 5 frames; at most 6 bins per drive.",
    "",
    "| scene | candidates | bins | PSNR | AbsRel |",
    "| --- | --- | ---: | ---: | ---: |",
    *rows,
    "",
    "Not yet the default: 0.233181 leaves streets and rooms unchanged (their depths lie inside",
    "both ranges) and turns desks from every depth at 1 m or more into a useful map, but it also",
    "moves the SGM range fit on real pairs and adds float noise far from the world origin, so",
    "`tiny` keeps metres until the weights are retrained with the candidates following each",
    "sample's rig. A third of the width costs the streets now because the weights learned the",
    "candidates of one rig.",
]
(out / "README.md").write_text("\n".join(lines) + "\n")
(out / "scores.json").write_text(json.dumps(scores, indent=2) + "\n")
print("\n".join(lines))
PY
