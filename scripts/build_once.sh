#!/usr/bin/env bash
# Checks that the README's two commands build the dependency tree once: every dependency unit
# (a crate with its features and profile: one fingerprint under target/release/.fingerprint)
# of a package (name and version) the run command built, that the test command uses, must be
# one that the run command built. Builds whatever is not built yet (on a fresh clone that is
# the whole tree, once), then prints the units only the test build uses, by package, and the
# crates it compiled; exits 1 if a package of the run build is among them, compiled again.
# Allowed: the workspace's own crates (their test targets), and the host copies of eleven
# packages the node also uses, that bindgen (the ROS 2 bridge's build-time tool) needs: built
# with the build-time profile and, for eight of them, other features (`cargo tree --workspace
# -e normal,build,dev -f '{p}|{f}'` lists both copies). Packages only the test build needs
# (the bridge's Cyclone DDS, plugin and bindgen) are new, not built again.
set -euo pipefail
cd "$(dirname "$0")/.."
run_log="$(mktemp)"
test_log="$(mktemp)"
# "name version|fingerprint" per unit.
units() {
  sed -n 's|.*package_id=\([^ ]* v[^ ]*\).*fingerprint at: .*/\.fingerprint/\([^ ]*\)|\1\|\2|p' "$1" \
    | sort -u
}
CARGO_LOG=cargo::core::compiler::fingerprint=debug cargo build --release --bin stereosplat 2>"$run_log"
CARGO_LOG=cargo::core::compiler::fingerprint=debug cargo test --workspace --release --no-run 2>"$test_log"
only_test="$(comm -13 <(units "$run_log") <(units "$test_log") | cut -d'|' -f1)"
echo "units of the run build: $(units "$run_log" | wc -l); of the test build: $(units "$test_log" | wc -l)"
echo "units only the test build uses, by package:"
echo "$only_test" | sort | uniq -c
echo "crates the test build compiled: $(grep -cE '^ *Compiling ' "$test_log" || true)"
grep -E '^ *Compiling ' "$test_log" || true
own='(renderer|model|node|system-tests|stereosplat-ros2-bridge) .*'
bindgen_host='(bitflags|home|lazy_static|libloading|log|minimal-lexical|nom|regex|regex-automata|regex-syntax|rustc-hash) .*'
run_packages="$(units "$run_log" | cut -d'|' -f1 | sort -u)"
twice="$(echo "$only_test" | sort -u | grep -xF "$run_packages" \
  | grep -vxE "$own|$bindgen_host" || true)"
if [ -n "$twice" ]; then
  echo "dependencies the test command builds again: $twice" >&2
  exit 1
fi
echo "no dependency of the run build is built again"
