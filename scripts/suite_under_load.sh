#!/usr/bin/env bash
# The whole test suite RUNS times in a row (default 3), each with a second CPU-bound job
# beside it (one busy loop per core), as a loaded CI machine runs it: the evidence that no
# test depends on a quiet machine (docs/ci.md, "On a loaded machine"). Prints one line per
# run and exits non-zero if any run failed; each run's output is in $OUT_DIR/run_N.log.
#
#   bash scripts/suite_under_load.sh [RUNS]
set -uo pipefail
cd "$(dirname "$0")/.."
runs="${1:-3}"
out="${OUT_DIR:-$(mktemp -d)}"
mkdir -p "$out"
export CARGO_PROFILE_RELEASE_DEBUG=false
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
chmod 700 "$XDG_RUNTIME_DIR"
export WGPU_BACKEND="${WGPU_BACKEND:-vulkan}"
cargo test --workspace --release --no-run >"$out/build.log" 2>&1 || { cat "$out/build.log"; exit 1; }
failed=0
for i in $(seq 1 "$runs"); do
  hogs=()
  for _ in $(seq 1 "$(nproc)"); do
    sh -c 'while :; do :; done' &
    hogs+=($!)
  done
  start=$(date +%s)
  cargo test --workspace --release --no-fail-fast >"$out/run_$i.log" 2>&1
  rc=$?
  kill "${hogs[@]}" 2>/dev/null
  wait "${hogs[@]}" 2>/dev/null
  counts=$(awk '/^test result:/ { p += $4; f += $6 } END { printf "%d passed, %d failed", p, f }' "$out/run_$i.log")
  echo "run $i: exit $rc, $(($(date +%s) - start)) s, $counts"
  [ "$rc" -eq 0 ] || failed=1
done
exit "$failed"
