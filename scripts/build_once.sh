#!/usr/bin/env bash
# Checks that the README's two commands build the dependency tree once: every dependency unit
# (a crate with its features and profile: one fingerprint under target/release/.fingerprint)
# that the test command uses must be one that the run command built. Builds whatever is not
# built yet (on a fresh clone that is the whole tree, once), then prints the units only the
# test build uses, by crate, and how many crates it compiled; exits 1 if a dependency (not
# renderer, model, node or system-tests) is among them.
set -euo pipefail
cd "$(dirname "$0")/.."
run_log="$(mktemp)"
test_log="$(mktemp)"
units() { grep -o 'fingerprint at: [^ ]*' "$1" | sed 's|.*/\.fingerprint/||' | sort -u; }
CARGO_LOG=cargo::core::compiler::fingerprint=debug cargo build --release --bin stereosplat 2>"$run_log"
CARGO_LOG=cargo::core::compiler::fingerprint=debug cargo test --workspace --release --no-run 2>"$test_log"
only_test="$(comm -13 <(units "$run_log") <(units "$test_log") | sed 's|-[0-9a-f]*/.*||' | sort | uniq -c)"
echo "units of the run build: $(units "$run_log" | wc -l); of the test build: $(units "$test_log" | wc -l)"
echo "units only the test build uses, by crate:"
echo "$only_test"
echo "crates the test build compiled: $(grep -cE '^ *Compiling ' "$test_log" || true)"
grep -E '^ *Compiling ' "$test_log" || true
twice="$(echo "$only_test" | awk 'NF { print $2 }' | grep -vxE 'renderer|model|node|system-tests' || true)"
if [ -n "$twice" ]; then
  echo "dependencies the test command builds again: $twice" >&2
  exit 1
fi
