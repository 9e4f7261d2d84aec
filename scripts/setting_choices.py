#!/usr/bin/env python3
"""The tables and the choices of scripts/setting_choices.sh, from its `stereosplat research eval` runs.

Two validation sets: fixed rigs (one run per scene over its two drives) and randomised rigs
(one run per sequence, each its own rig). For each set and variant, the AbsRel of desks,
rooms and streets relative to the default's (per run, averaged over a kind's runs), summed
over the three: the rule of scripts/choose_checkpoint.sh, geometry first. A variant replaces the
default only when it lowers that sum by more than 1% on both sets and costs no kind of either
set more than 0.3 dB of PSNR: differences under 1% are within what 6-12 bins per kind
resolve, so they keep what is shipped.

    python3 scripts/setting_choices.py --fixed RUNS --randomised RUNS --out DIR \
        --preset P --prefix X -- "NAME|SETTINGS" ...
"""

import argparse
import json
import pathlib

FIXED_KINDS = ["desk", "room", "street"]
RANDOMISED_KINDS = ["desk", "room", "street", "plain"]
# The kinds whose relative AbsRel is summed, in both sets (scripts/choose_checkpoint.sh's);
# the plain streets only guard PSNR.
SUMMED_KINDS = ["desk", "room", "street"]
# A change must lower the relative sum by more than this share on both sets.
MIN_GAIN = 0.01
# No kind may lose more PSNR than this (dB).
MAX_PSNR_LOSS = 0.3


def folder(name):
    return name.replace(" ", "_")


def load(path):
    d = json.loads(path.read_text())
    a = d["summary"]["average"]
    return {"psnr": a["psnr"], "abs_rel": a["abs_rel"], "bins": len(d["bins"]),
            "ms": d["mean_reconstruct_ms"]}


def fixed_runs(root, prefix, names):
    """{(kind, variant): {"all": run}} of the fixed-rig set: one run per kind."""
    return {(k, n): {"all": load(root / f"{prefix}{k}-{folder(n)}" / "eval.json")}
            for k in FIXED_KINDS for n in names}


def randomised_runs(root, prefix, names):
    """{(kind, variant): {sequence: run}} of the randomised set, one run per sequence."""
    return {(k, n): {p.parent.name: load(p)
                     for p in sorted((root / f"{prefix}{k}-{folder(n)}").glob("*/eval.json"))}
            for k in RANDOMISED_KINDS for n in names}


def mean(xs):
    return sum(xs) / len(xs)


def judge(runs, kinds, name):
    """Relative AbsRel summed over [`SUMMED_KINDS`] and the PSNR change of every kind of
    `kinds`, against the default, run by run (the same sequences)."""
    total, psnr = 0.0, {}
    for k in kinds:
        base, var = runs[(k, "default")], runs[(k, name)]
        if var.keys() != base.keys():
            raise SystemExit(f"{name} on {k}: runs {sorted(var)} but the default has {sorted(base)}")
        if k in SUMMED_KINDS:
            total += mean([var[s]["abs_rel"] / base[s]["abs_rel"] for s in base])
        psnr[k] = mean([v["psnr"] for v in var.values()]) - mean([b["psnr"] for b in base.values()])
    return total, psnr


def rows(runs, kinds, names, variants):
    out = []
    for k in kinds:
        for n in names:
            rs = list(runs[(k, n)].values())
            sets = variants[n]
            shown = "`--method sgm`" if n == "SGM" else f"`{sets or '-'}`"
            out.append(f"| {k} | {n} | {shown} | {len(rs)} | {sum(r['bins'] for r in rs)} | "
                       f"{mean([r['psnr'] for r in rs]):.2f} | "
                       f"{mean([r['abs_rel'] for r in rs]):.4f} | "
                       f"{mean([r['ms'] for r in rs]):.0f} |")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fixed", type=pathlib.Path, required=True)
    ap.add_argument("--randomised", type=pathlib.Path, required=True)
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--preset", required=True)
    ap.add_argument("--prefix", default="")
    ap.add_argument("--command", default="bash scripts/setting_choices.sh",
                    help="the command that made the table, as the README names it")
    ap.add_argument("--no-notes", action="store_true",
                    help="leave out the notes on the script's own variants (another list ran)")
    ap.add_argument("variants", nargs="+")
    a = ap.parse_args()
    variants = dict(v.split("|", 1) for v in a.variants)
    names = list(variants)
    fixed = fixed_runs(a.fixed, a.prefix, names)
    randomised = randomised_runs(a.randomised, a.prefix, names)

    scores, decisions = {}, []
    for n in names:
        scores[n] = {
            "settings": "--method sgm" if n == "SGM" else variants[n],
            "fixed": {k: fixed[(k, n)]["all"] for k in FIXED_KINDS},
            "randomised": {k: randomised[(k, n)] for k in RANDOMISED_KINDS},
        }
        if n in ("default", "SGM"):
            continue
        f_sum, f_psnr = judge(fixed, FIXED_KINDS, n)
        r_sum, r_psnr = judge(randomised, RANDOMISED_KINDS, n)
        f_gain = 1 - f_sum / len(SUMMED_KINDS)
        r_gain = 1 - r_sum / len(SUMMED_KINDS)
        worst = min([*f_psnr.values(), *r_psnr.values()])
        take = f_gain > MIN_GAIN and r_gain > MIN_GAIN and worst >= -MAX_PSNR_LOSS
        scores[n]["rule"] = {"fixed_sum_change": -f_gain, "randomised_sum_change": -r_gain,
                             "worst_psnr_change_db": worst, "replaces_default": take}
        verdict = "**replaces the default**" if take else "keeps the default"
        decisions.append(f"| {n} | `{variants[n]}` | {-100 * f_gain:+.1f}% | "
                         f"{-100 * r_gain:+.1f}% | {worst:+.2f} | {verdict} |")

    title = ("# The learned default's settings on generated validation drives"
             if a.preset == "tiny" else f"# `{a.preset}`'s settings on generated validation drives")
    lines = [
        title,
        "",
        "Made by `" + a.command + "`: the shipped `" + a.preset + "` weights, each",
        "row the default with the settings shown changed (SGM: `--method sgm`, the classical",
        "floor). Bin-average PSNR of the bin's frames rendered from its map, AbsRel of the",
        "rendered depth against the generator's LiDAR, mean reconstruction time (wall time on a",
        "shared machine, not a benchmark: `stereosplat bench model`). At most 6 bins per drive.",
        "Seeds from 2,000,000: training uses seeds below 1,000,000 and the held-out evaluation",
        "1,000,000 to 1,999,999.",
        "",
        "## The rule",
        "",
        "For each set, the AbsRel of desks, rooms and streets relative to the default's (run by",
        "run, averaged per kind), summed over the three (the rule `scripts/choose_checkpoint.sh`",
        "chooses checkpoints by; plain streets only guard PSNR). A variant",
        f"replaces the default only when it lowers that sum by more than {MIN_GAIN:.0%} on both",
        f"sets and costs no kind of either set more than {MAX_PSNR_LOSS} dB of PSNR; smaller",
        "differences are within what 6-12 bins per kind resolve, and keep what is shipped.",
        "Real pairs are never used (`results/real_pairs/` reports them).",
        "",
        "| variant | settings | AbsRel sum, fixed rigs | AbsRel sum, randomised rigs | worst PSNR change (dB) | |",
        "| --- | --- | ---: | ---: | ---: | --- |",
        *decisions,
        "",
        "## Fixed rigs",
        "",
        "Desks: 320x96, 10 cm rig, 0.1 m bins; rooms: 320x96, 0.5 m bins; streets: 272x72,",
        "KITTI-360's rig, 8 m bins every 5 frames; seeds 2,000,000 and 2,000,001 per scene.",
        "",
        "| scene | variant | settings | runs | bins | PSNR | AbsRel | ms |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |",
        *rows(fixed, FIXED_KINDS, names, variants),
        "",
        "## Randomised rigs",
        "",
        "Desks, rooms and streets at 544x112 with randomised rigs (5-50 cm baselines for desks",
        "and rooms; `scripts/validation_data.sh`, seeds 2,000,000-2,000,001, 2,000,100-2,000,101",
        "and 2,000,200-2,000,201), plain streets on KITTI-360's rig at 272x72 (seeds 2,000,300",
        "and 2,000,301): the drives `scripts/choose_checkpoint.sh` chooses checkpoints on. A run",
        "per sequence; PSNR and AbsRel are the mean over the runs.",
        "",
        "| scene | variant | settings | runs | bins | PSNR | AbsRel | ms |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |",
        *rows(randomised, RANDOMISED_KINDS, names, variants),
    ]
    notes = None if a.no_notes else NOTES.get(a.preset)
    if notes:
        lines += ["", "## What each row decides", "", *notes]
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "README.md").write_text("\n".join(lines) + "\n")
    (a.out / "scores.json").write_text(json.dumps(scores, indent=2) + "\n")
    print("\n".join(lines))


NOTES = {
    "tiny": [
        "- `rig_disparity_fraction` 0.233181 (candidates from the rig): desks and the randomised",
        "  rigs' streets need it; rooms and streets on KITTI-360's rig are the same either way,",
        "  since there it gives the metres the weights learned.",
        "- `sgm_guidance` 10: switching the hints off raises the near scenes' AbsRel on both",
        "  sets. Strength 5 lowers the fixed rigs' sum but not the randomised rigs' beyond what",
        "  the rule resolves, 20 raises both, so the strength the weights were trained with",
        "  stays. The hints' width is the constant `GUIDANCE_WIDTH` (2 candidates; widths 1 and",
        "  4 moved AbsRel by at most 0.002 on an earlier run of this script, commit ca50ad6).",
        "- `sgm_snap`: it lowers the desks' AbsRel and raises the rooms' a little; the sums move",
        "  by less than the rule resolves, so it stays.",
        "- `sgm_fill`: without it the near scenes' AbsRel rises on both sets (the desks' most);",
        "  the rule's own run: [sgm_fill/](sgm_fill/).",
        "- `auto_depth_range`: desks need the fitted range. `auto_depth_range_max_far` 50 m:",
        "  fitting every scene costs the streets PSNR and AbsRel, so streets keep the rig's range.",
        "- `tiny-3d`'s choices beyond these: [tiny-3d/](tiny-3d/) (`SETTING_PRESET=tiny-3d`).",
    ],
    "tiny-3d": [
        "- `rig_disparity_fraction` 0.233181, as `tiny`: with candidates in metres (1-100 m, what",
        "  its weights were trained with) desks fall outside them; streets on KITTI-360's rig",
        "  are the same either way.",
        "- `sgm_snap`: switching it off raises the desks' and rooms' AbsRel.",
        "- `volume_branch_far_only`: the branch's grid is street-sized; on near scenes it does",
        "  not lower AbsRel and costs time, so it runs on streets only (where, beside the",
        "  no-branch row, it is what the preset is for).",
    ],
}

if __name__ == "__main__":
    main()
