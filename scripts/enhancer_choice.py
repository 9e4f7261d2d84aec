#!/usr/bin/env python3
"""Chooses the enhancer's kept step on the validation pairs (scripts/train_enhancer_scales.sh).

Reads CHOICE_DIR/step_N_KIND.json (`eval-enhancer` reports) for the kinds desk, room, street
and plain. The rule: among the steps whose enhanced PSNR on no kind is more than 0.1 dB under
step 0's (the enhancer the fine-tune starts from), the one with the lowest enhanced LPIPS
averaged over the kinds; step 0 itself is always eligible, so a fine-tune that helps nowhere
keeps it. Writes CHOICE_DIR/scores.json and CHOICE_DIR/README.md and prints the chosen step's
name (step_N).

    python3 scripts/enhancer_choice.py CHOICE_DIR
"""

import json
import re
import sys
from pathlib import Path

KINDS = ["desk", "room", "street", "plain"]
PSNR_SLACK_DB = 0.1


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    folder = Path(sys.argv[1])
    steps: dict[int, dict[str, dict]] = {}
    for path in folder.glob("step_*_*.json"):
        m = re.fullmatch(r"step_(\d+)_(\w+)\.json", path.name)
        if m and m.group(2) in KINDS:
            steps.setdefault(int(m.group(1)), {})[m.group(2)] = json.loads(path.read_text())
    if 0 not in steps:
        print(f"no step_0 reports in {folder}", file=sys.stderr)
        return 1
    for step, kinds in sorted(steps.items()):
        missing = [k for k in KINDS if k not in kinds]
        if missing:
            print(f"step {step} lacks {', '.join(missing)} in {folder}", file=sys.stderr)
            return 1
    base = steps[0]
    rows = []
    for step, kinds in sorted(steps.items()):
        lpips = sum(kinds[k]["enhanced"]["lpips"] for k in KINDS) / len(KINDS)
        worst = min(kinds[k]["enhanced"]["psnr"] - base[k]["enhanced"]["psnr"] for k in KINDS)
        rows.append(
            {
                "step": step,
                "mean_lpips": lpips,
                "worst_psnr_change_db": worst,
                "eligible": step == 0 or worst >= -PSNR_SLACK_DB,
                "kinds": {k: kinds[k]["enhanced"] | {"pairs": kinds[k]["pairs"]} for k in KINDS},
            }
        )
    chosen = min((r for r in rows if r["eligible"]), key=lambda r: r["mean_lpips"])["step"]
    raw = {k: base[k]["raw"] for k in KINDS}
    (folder / "scores.json").write_text(
        json.dumps({"rule": __doc__.split("\n\n")[1], "chosen": chosen, "raw": raw, "steps": rows}, indent=2)
    )
    lines = [
        "# The enhancer's kept steps on the validation pairs",
        "",
        "`python3 scripts/enhancer_choice.py` on the reports `bash scripts/train_enhancer_scales.sh`",
        "writes here. Rule: the lowest LPIPS averaged over the four kinds, among the steps whose",
        f"PSNR on no kind is more than {PSNR_SLACK_DB} dB under step 0's. Chosen: **step {chosen}**.",
        "",
        "| step | " + " | ".join(f"{k} PSNR / LPIPS" for k in KINDS) + " | mean LPIPS | eligible |",
        "|---|" + "---:|" * (len(KINDS) + 2),
        "| raw render | "
        + " | ".join(f"{raw[k]['psnr']:.2f} / {raw[k]['lpips']:.3f}" for k in KINDS)
        + " | | |",
    ]
    for r in rows:
        cells = " | ".join(
            f"{r['kinds'][k]['psnr']:.2f} / {r['kinds'][k]['lpips']:.3f}" for k in KINDS
        )
        lines.append(
            f"| {r['step']} | {cells} | {r['mean_lpips']:.4f} | {'yes' if r['eligible'] else 'no'} |"
        )
    (folder / "README.md").write_text("\n".join(lines) + "\n")
    print(f"step_{chosen}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
