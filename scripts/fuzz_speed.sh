#!/usr/bin/env bash
# How fast two builds of the fuzz targets fuzz: each target of each build runs SECONDS from a
# fresh copy of the same corpus, one after the other, and the executed inputs are tabulated
# with their ratio (B / A). For comparing fuzz profiles (docs/fuzzing.md); build each into
# its own target directory first (`cargo fuzz build ... --target-dir DIR` from `fuzz/`'s
# parent, with the flags of scripts/fuzz.sh).
#   bash scripts/fuzz_speed.sh TARGET_DIR_A TARGET_DIR_B [SECONDS] [CORPUS_DIR]
# (default 8 s, corpus fuzz/corpus as scripts/fuzz.sh leaves it).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "$#" -lt 2 ]; then
  sed -n '2,8p' "$0" >&2
  exit 2
fi
a="$1/x86_64-unknown-linux-gnu/release"
b="$2/x86_64-unknown-linux-gnu/release"
seconds="${3:-8}"
corpus="${4:-fuzz/corpus}"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT

runs() {
  rm -rf "$scratch/corpus"
  mkdir -p "$scratch/corpus"
  if [ -d "$corpus/$2" ]; then cp -r "$corpus/$2/." "$scratch/corpus/"; fi
  "$1/$2" "$scratch/corpus" -max_total_time="$seconds" -timeout=25 -rss_limit_mb=2048 \
    -malloc_limit_mb=4200 -print_final_stats=1 2>&1 |
    sed -n 's/^stat::number_of_executed_units: *//p'
}

echo "| target | A: $1 | B: $2 | B / A |"
echo "| --- | ---: | ---: | ---: |"
for source in fuzz/fuzz_targets/*.rs; do
  target="$(basename "$source" .rs)"
  ra="$(runs "$a" "$target")"
  rb="$(runs "$b" "$target")"
  awk -v t="$target" -v a="$ra" -v b="$rb" 'BEGIN { printf "| `%s` | %d | %d | %.2f |\n", t, a, b, b / a }'
done
