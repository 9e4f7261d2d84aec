#!/usr/bin/env bash
# The SGM baseline against OpenCV's StereoSGBM on the real pairs (Aloe and Motorcycle with
# ground truth, the 12 OAK-D pairs without), its accuracy against time by working size on
# generated drives, and its time by image size: writes results/sgm/ (README.md, table.md,
# table.json, sizes.md, sizes.json); each run's files stay under out/. About 10 minutes on
# 2 cores (most of it generating the drives and bench pairs once).
#
#   bash scripts/sgm_vs_opencv.sh [--out DIR] [--data DIR]
#
# Needs the pairs (bash scripts/real_data.sh) and opencv-python-headless, numpy and pillow
# (scripts/requirements.txt); builds the release binary (a no-op when fresh) unless
# STEREOSPLAT_BIN names one.
set -euo pipefail
command="bash scripts/sgm_vs_opencv.sh${*:+ $*}"
out=results/sgm data=data/real
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$(realpath -m "$2")"; shift 2 ;;
    --data) data="$(realpath -m "$2")"; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
cd "$(dirname "$0")/.."
[ -s "$data/aloe/aloeGT.png" ] || { echo "no real pairs in $data: run bash scripts/real_data.sh $data" >&2; exit 1; }
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
runs=out/sgm_vs_opencv
rm -rf "$runs" out/sgm_sizes/runs
mkdir -p "$out" "$runs"
# SGM's own time (`bench model --preset sgm`, default settings, generated pairs kept under
# out/sgm_bench/): the node's 544x112, the real pairs' working sizes under `reconstruct`'s
# default pixel budget, and their input sizes.
for size in 544x112 451x390 511x345 484x363 741x500 640x480 1282x1110; do
  "$bin" bench model --preset sgm --width "${size%x*}" --height "${size#*x}" --runs 5 --warmup 1 \
    --cache "out/sgm_bench/$size"
done >"$runs/bench.jsonl"
# The working size and the median, chosen on generated validation drives only (sizes.md).
python3 scripts/sgm_sizes.py --bin "$bin" --data out/sgm_sizes/validation --out "$out" \
  --runs out/sgm_sizes/runs --command "$command"
python3 scripts/sgm_vs_opencv.py --bin "$bin" --data "$data" --out "$out" --runs "$runs" \
  --bench "$runs/bench.jsonl" --command "$command"
