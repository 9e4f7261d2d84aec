#!/usr/bin/env bash
# Chooses a training run's shipped checkpoint on generated validation drives, never on real
# pairs and never on the held-out evaluation: randomised desks, rooms and streets at the
# node's working size, 544x112 (seeds 2,000,000 and 2,000,001 per kind,
# scripts/validation_data.sh), and plain streets on KITTI-360's rig at 272x72 (seeds
# 2,000,300 and 2,000,301, the size of the demo and of the held-out streets). Scores the
# run's starting weights and each kept checkpoint (RUN_DIR/kept/step_N.safetensors, every
# EVERY-th, default 300) with the `tiny` preset's settings (`stereosplat research eval`, at most 6
# bins per sequence), and picks by this rule: the lowest sum over desks, rooms and streets
# of AbsRel relative to the starting weights' (geometry is the product; per kind, each
# sequence's AbsRel over the start's on it, averaged), among checkpoints whose PSNR on
# both street kinds is within 0.3 dB of the start's and whose plain-street AbsRel is at
# most the start's + 0.005 (the streets may not pay for the near scenes).
# Writes OUT_DIR/README.md and scores.json (`chosen`, its `file`, every score).
#   bash scripts/choose_checkpoint.sh RUN_DIR INIT_WEIGHTS [OUT_DIR]
# PRESET (default tiny) scores another preset's settings; CANDIDATES ("NAME|FILE ...")
# scores those files instead of the run's kept checkpoints (the starting weights are always
# scored and may be chosen), e.g. the blends of scripts/train_tiny_3d.sh.
# Builds the release binary unless STEREOSPLAT_BIN names one; the validation drives go to
# data/validation_choice, the runs to RUN_DIR/choice_runs.
set -euo pipefail
cd "$(dirname "$0")/.."
run="$1" init="$2" out="${3:-$1/choice}" every="${EVERY:-300}" preset="${PRESET:-tiny}"
bin="${STEREOSPLAT_BIN:-target/release/stereosplat}"
[ -n "${STEREOSPLAT_BIN:-}" ] || cargo build --release --quiet --bin stereosplat
data=data/validation_choice
VALIDATION_SEQUENCES=2 VALIDATION_SIZE="544 112" VALIDATION_PLAIN=2 STEREOSPLAT_BIN="$bin" \
  bash scripts/validation_data.sh "$data" >/dev/null
mkdir -p "$out" "$run/choice_runs"
weights=("start|$init")
if [ -n "${CANDIDATES:-}" ]; then
  read -r -a listed <<<"$CANDIDATES"
  weights+=("${listed[@]}")
else
  for f in $(ls "$run"/kept/step_*.safetensors 2>/dev/null | sort -V); do
    step=${f##*step_}; step=${step%.safetensors}
    if ((step % every == 0)); then weights+=("$step|$f"); fi
  done
fi
# kind, bin length (m), stride
for row in "desk 0.1 1" "room 0.5 1" "street 8 5" "plain 8 5"; do
  read -r kind bin_length stride <<<"$row"
  for w in "${weights[@]}"; do
    name="${w%%|*}" file="${w#*|}"
    for root in "$data/${kind}_"*; do
      dir="$run/choice_runs/$kind-$name/$(basename "$root")"
      [ -f "$dir/eval.json" ] && continue
      "$bin" research eval --data "$root" --method stereosplat --preset "$preset" --weights "$file" \
        --bin-length "$bin_length" --stride "$stride" --max-bins 6 --pictures 0 --no-lpips \
        --out "$dir" >/dev/null
    done
  done
done
python3 - "$run/choice_runs" "$out" "$preset" "${weights[@]}" <<'PY'
import json, pathlib, sys
runs, out, preset, weights = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]), sys.argv[3], sys.argv[4:]
kinds = ["desk", "room", "street"]
guards = ["street", "plain"]
def parts(kind, name):
    return {p.parent.name: json.loads(p.read_text())["summary"]["average"]
            for p in sorted((runs / f"{kind}-{name}").glob("*/eval.json"))}
def score(kind, name):
    # Frame-weighted means over the kind's sequences, as `eval` averages one sequence.
    seqs = parts(kind, name).values()
    count = sum(a["count"] for a in seqs)
    mean = lambda k: sum(a[k] * a["count"] for a in seqs) / count
    return {"frames": count, "psnr": mean("psnr"), "abs_rel": mean("abs_rel")}
names = [w.split("|", 1)[0] for w in weights]
files = dict(w.split("|", 1) for w in weights)
scores = {n: {k: score(k, n) for k in kinds + ["plain"]} for n in names}
start = scores["start"]
def rel(n):
    # Per kind, the mean over its sequences of AbsRel relative to the start's on the same
    # sequence, so one sequence of large errors does not outweigh the others.
    total = 0.0
    for k in kinds:
        now, before = parts(k, n), parts(k, "start")
        total += sum(now[s]["abs_rel"] / before[s]["abs_rel"] for s in now) / len(now)
    return total
allowed = [n for n in names
           if all(scores[n][k]["psnr"] >= start[k]["psnr"] - 0.3 for k in guards)
           and scores[n]["plain"]["abs_rel"] <= start["plain"]["abs_rel"] + 0.005]
chosen = min(allowed, key=rel)
rows = [f"| {n} | " + " | ".join(f"{scores[n][k]['psnr']:.2f} / {scores[n][k]['abs_rel']:.3f}" for k in kinds + ["plain"])
        + f" | {rel(n):.3f} | {'chosen' if n == chosen else ('' if n in allowed else 'streets got worse')} |" for n in names]
lines = [
    "# Checkpoint choice on generated validation drives at 544x112",
    "",
    "Made by `bash scripts/choose_checkpoint.sh`: 2 validation sequences per kind (seeds",
    "2,000,000 and 2,000,001, randomised rigs at the node's working size, 544x112; plain:",
    "streets on KITTI-360's rig at 272x72, seeds 2,000,300 and 2,000,301), the",
    f"`{preset}` preset's settings, at most 6 bins per sequence. Each cell: bin-average PSNR /",
    "AbsRel of the rendered depth against the generator's LiDAR (frame-weighted over the",
    "kind's sequences). The rule, fixed before any checkpoint was scored: the lowest sum",
    "over the three kinds of AbsRel relative to the starting weights' (per kind, each",
    "sequence's ratio, averaged), among checkpoints whose PSNR on both street kinds is",
    "within 0.3 dB of the start's and whose plain-street AbsRel is at most the start's + 0.005.",
    "",
    "| weights | desk | room | street | plain street | relative AbsRel sum | |",
    "| --- | ---: | ---: | ---: | ---: | ---: | --- |",
    *rows,
    "",
    f"Chosen: {chosen}.",
]
out.mkdir(parents=True, exist_ok=True)
(out / "README.md").write_text("\n".join(lines) + "\n")
(out / "scores.json").write_text(json.dumps({"chosen": chosen, "file": files[chosen], "scores": scores}, indent=2) + "\n")
print("\n".join(lines))
PY
