#!/usr/bin/env bash
# Coverage-guided fuzzing (cargo-fuzz, libFuzzer, AddressSanitizer) of every decoder of outside
# input: the targets in fuzz/fuzz_targets (CDR messages, MCAP, PLY, KITTI-360 text files,
# launch TOML). Builds every target once, seeds each corpus with the project's own encoder
# output (`--example fuzz_seeds`), runs each target for SECONDS, and fails if any input
# crashed, panicked, hung (over $FUZZ_TIMEOUT_S s) or asked for more than $FUZZ_RSS_MB MiB.
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
#   bash scripts/fuzz.sh --build      # only install cargo-fuzz and build the targets
# (default 20 s, every target). The targets of decoders in the running node's modules (worker
# protocol, input path, region queries, live view, camera-info YAML) need `node`'s runtime
# feature and a much larger build: FUZZ_FEATURES=runtime builds and runs them too. Corpora grow in fuzz/corpus/<target>; a failing input is
# kept in fuzz/artifacts/<target>/ and `cargo fuzz run TARGET FILE` replays it. `--build`
# touches neither the workspace's target directory nor the corpora, so CI runs it beside
# the tests (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
build_only=false
if [ "${1:-}" = "--build" ]; then
  build_only=true
  shift
fi
seconds="${1:-20}"
shift || true
timeout_s="${FUZZ_TIMEOUT_S:-25}"
rss_mb="${FUZZ_RSS_MB:-2048}"

# cargo-fuzz passes -Z flags (sanitizer, coverage passes) to rustc; the stable compiler takes
# them with RUSTC_BOOTSTRAP=1, so no nightly toolchain is needed. Only cargo-fuzz gets it:
# cargo fingerprints it, and the workspace build would start again from scratch.
if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked --version 0.13.2
fi
# The fuzz profile's own debug setting stands (line numbers in a crash's report), whatever
# the caller set for the workspace's release builds (.ci/run).
fuzz() { env -u CARGO_PROFILE_RELEASE_DEBUG RUSTC_BOOTSTRAP=1 cargo fuzz "$@"; }
# Sixteen codegen units: a much faster build of the instrumented tree, a little slower runs.
flags=(--release --sanitizer address --codegen-units 16)
features="${FUZZ_FEATURES:-}"
if [ -n "$features" ]; then flags+=(--features "$features"); fi

fuzz build "${flags[@]}"
if $build_only; then
  exit 0
fi
# The seeds, from the workspace's own (uninstrumented) build.
cargo run --release --example fuzz_seeds -- fuzz/corpus
if [ "$#" -gt 0 ]; then
  targets=("$@")
else
  mapfile -t targets < <(fuzz list)
  if [ -z "$features" ]; then
    # Without the runtime feature its targets are not built: leave them out.
    mapfile -t runtime < <(awk '/^name = /{n=$3} /^required-features/{gsub(/"/, "", n); print n}' fuzz/Cargo.toml)
    kept=()
    for t in "${targets[@]}"; do
      [[ " ${runtime[*]} " == *" $t "* ]] || kept+=("$t")
    done
    targets=("${kept[@]}")
  fi
fi

failed=()
for target in "${targets[@]}"; do
  log="fuzz/logs/$target.log"
  mkdir -p fuzz/logs
  echo "== $target: $seconds s"
  if fuzz run "${flags[@]}" "$target" "fuzz/corpus/$target" -- \
    -max_total_time="$seconds" -timeout="$timeout_s" -rss_limit_mb="$rss_mb" \
    -print_final_stats=1 >"$log" 2>&1; then
    runs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")"
    echo "   ok: ${runs:-?} executions, corpus $(find "fuzz/corpus/$target" -type f | wc -l) inputs"
  else
    failed+=("$target")
    tail -n 40 "$log"
    echo "   FAILED: see $log and fuzz/artifacts/$target/"
  fi
done

if [ "${#failed[@]}" -gt 0 ]; then
  echo "fuzz: ${#failed[@]} of ${#targets[@]} targets failed: ${failed[*]}"
  exit 1
fi
echo "fuzz: ${#targets[@]} targets, $seconds s each, no crash"
