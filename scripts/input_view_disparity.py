#!/usr/bin/env python3
"""The real pairs' metric on generated validation drives: disparity at the input view.

The real pairs (scripts/real_pairs.sh) score one thing, the disparity of the reconstruction
seen from the input camera, against a dense truth; the validation drives score the rendered
frames of a whole bin. This runs `stereosplat reconstruct` on the first frames of generated
validation sequences (their left and right images, the rig from the root's calibration) with
each method (the learned ones' own output, flagged where the self-check fails, as the real
pairs score it) and scores them against the generator's exact depth turned into disparity
(fx * baseline / z): bad-1 and bad-3 with uncovered pixels counted wrong, bad-3 on covered
pixels, coverage, EPE; and the OAK-D pairs' metric, photometric consistency (`reconstruct`'s
right image warped into the left by the depth) on the pixels both a method and SGM score,
with the share of frames where the method is no worse than SGM. Validation seeds only (scripts/validation_data.sh): it says whether
the generated drives rank the methods as the real pairs do, and `reconstruct`'s depth rule
(`--depth`) is chosen on it (results/input_view/).

    python3 scripts/input_view_disparity.py --bin target/release/stereosplat \
        --data data/validation_choice --out results/input_view [--frames 0 10 20]
        [--methods sgm tiny] [--set KEY=VALUE ...] [--variant LABEL=BASE:ARG,ARG ...]
        [--note TEXT]

Writes OUT/scores.json and OUT/README.md; each run's outputs (PLY, depth, error maps) go
under --work (default out/input_view_runs).
"""
import argparse
import json
import pathlib
import re
import subprocess

import numpy as np
from PIL import Image

# Truth disparities are stored as 16-bit PNGs at this many units per pixel (desks reach
# several hundred pixels of disparity, beyond KITTI's 1/256 px units).
TRUTH_UNITS_PER_PX = 64.0
METHODS = {
    "sgm": ["--method", "sgm"],
    "tiny": ["--method", "stereosplat", "--preset", "tiny", "--on-check-fail", "flag"],
    "tiny-3d": ["--method", "stereosplat", "--preset", "tiny-3d", "--on-check-fail", "flag"],
}


def calibration(root: pathlib.Path) -> tuple:
    """fx, cx, cy and the baseline of the root's rectified rig."""
    text = (root / "calibration" / "perspective.txt").read_text()
    p0 = [float(v) for v in re.search(r"P_rect_00: (.*)", text).group(1).split()]
    p1 = [float(v) for v in re.search(r"P_rect_01: (.*)", text).group(1).split()]
    fx = p0[0]
    return fx, p0[2], p0[6], -p1[3] / fx


def scores(depth: np.ndarray, truth: np.ndarray, fx_baseline: float) -> dict:
    """The summary's truth scores from a z-depth map (0 = none) at the truth's size."""
    known = truth > 0
    has = known & (depth > 0)
    error = np.abs(fx_baseline / np.where(has, depth, 1.0) - truth)
    n = max(int(known.sum()), 1)
    predicted = max(int(has.sum()), 1)
    return {
        "bad1": 100.0 * (known.sum() - (has & (error <= 1)).sum()) / n,
        "bad3": 100.0 * (known.sum() - (has & (error <= 3)).sum()) / n,
        "bad3_predicted": 100.0 * (has & (error > 3)).sum() / predicted,
        "epe": float(error[has].mean()) if has.any() else None,
        "density": 100.0 * has.sum() / n,
    }


def rgb(path: pathlib.Path) -> np.ndarray:
    """An image file as height x width x 3 floats in [0, 1], as `reconstruct` reads it."""
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255


def photometric_errors(run: pathlib.Path) -> np.ndarray:
    """A run's per-pixel photometric error (`photometric_error16.png`), NaN where unscored."""
    raw = np.asarray(Image.open(run / "photometric_error16.png"), dtype=np.float64)
    return np.where(raw > 0, (raw - 1) / 65534.0, np.nan)


def warp_errors(left: np.ndarray, right: np.ndarray, disparity: np.ndarray) -> np.ndarray:
    """The photometric error of a disparity map as `reconstruct` scores a depth (the right
    image sampled at x - d, linear in x, |difference| averaged over the channels), NaN
    where there is no disparity or the match leaves the image."""
    h, w, _ = left.shape
    x = np.arange(w)[None, :] - disparity
    valid = (disparity > 0) & (x >= 0) & (x <= w - 1)
    x = np.clip(x, 0, w - 1)
    x0 = np.floor(x).astype(int)
    x1 = np.minimum(x0 + 1, w - 1)
    f = (x - x0)[..., None]
    rows = np.arange(h)[:, None]
    warped = right[rows, x0] * (1 - f) + right[rows, x1] * f
    return np.where(valid, np.abs(left - warped).mean(axis=-1), np.nan)


def photometric_vs_sgm(run: pathlib.Path, label: str, exact: np.ndarray) -> dict:
    """`label`'s, SGM's and the exact depth's (`exact`, per-pixel errors) mean photometric
    error on the pixels both the method and SGM score (the real pairs' OAK-D score,
    `scripts/real_pairs.py`)."""
    mine, sgm = photometric_errors(run / label), photometric_errors(run / "sgm")
    common = np.isfinite(mine) & np.isfinite(sgm) & np.isfinite(exact)
    if not common.any():
        return {"common": 0.0, "method": None, "sgm": None, "exact": None}
    return {"common": float(common.mean()), "method": float(mine[common].mean()),
            "sgm": float(sgm[common].mean()), "exact": float(exact[common].mean())}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--data", type=pathlib.Path, required=True)
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--frames", type=int, nargs="+", default=[0, 10, 20])
    ap.add_argument("--work", type=pathlib.Path, default=pathlib.Path("out/input_view_runs"),
                    help="folder of each run's outputs")
    ap.add_argument("--methods", nargs="+", default=list(METHODS))
    ap.add_argument("--variant", action="append", default=[], metavar="LABEL=BASE:ARG,ARG",
                    help="another row: a method above with more reconstruct arguments, e.g. "
                    "old-3d=tiny-3d:--weights,old.safetensors")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a preset setting every learned row runs with (`reconstruct --set`), "
                    "e.g. sgm_fill=false for the settings a table was made with")
    ap.add_argument("--note", default="Nothing is chosen on it.",
                    help="what the table is for, written into the README")
    args = ap.parse_args()
    command = ("python3 scripts/input_view_disparity.py --bin target/release/stereosplat "
               f"--data DATA --out OUT --frames {' '.join(map(str, args.frames))} "
               f"--methods {' '.join(args.methods)}"
               + "".join(f" --set {kv}" for kv in args.set)
               + "".join(f" --variant {v}" for v in args.variant)
               + (f" --note \"{args.note}\"" if args.note != ap.get_default("note") else ""))
    for label, method in METHODS.items():
        if "stereosplat" in method:
            METHODS[label] = method + [a for kv in args.set for a in ("--set", kv)]
    for spec in args.variant:
        label, rest = spec.split("=", 1)
        base, extra = rest.split(":", 1)
        METHODS[label] = METHODS[base] + extra.split(",")
        args.methods.append(label)
    rows = []
    for root in sorted(args.data.iterdir()):
        kind = root.name.split("_")[0]
        if kind not in ("desk", "room", "street"):
            continue
        fx, cx, cy, baseline = calibration(root)
        seq = next((root / "data_2d_raw").iterdir()).name
        for frame in args.frames:
            name = f"{frame:010d}.png"
            left = root / "data_2d_raw" / seq / "image_00" / "data_rect" / name
            right = root / "data_2d_raw" / seq / "image_01" / "data_rect" / name
            depth_png = root / "data_2d_exact_depth" / seq / "image_00" / name
            if not (left.exists() and depth_png.exists()):
                continue
            z = np.asarray(Image.open(depth_png), dtype=np.float64) / 256.0
            disparity = np.where(z > 0, fx * baseline / np.maximum(z, 1e-9), 0.0)
            run = args.work / f"{root.name}_{frame}"
            run.mkdir(parents=True, exist_ok=True)
            truth = run / "truth_disparity.png"
            units = np.clip(np.round(disparity * TRUTH_UNITS_PER_PX), 0, 65535).astype(np.uint16)
            Image.fromarray(units).save(truth)
            row = {"kind": kind, "root": root.name, "frame": frame, "baseline_m": baseline,
                   "max_disparity_px": float(disparity.max())}
            for label in args.methods:
                out = run / label
                cmd = [args.bin, "reconstruct", "--left", str(left), "--right", str(right),
                       "--fx", str(fx), "--cx", str(cx), "--cy", str(cy),
                       "--baseline", str(baseline), "--truth-disparity", str(truth),
                       "--truth-scale", str(1.0 / TRUTH_UNITS_PER_PX), "--out", str(out),
                       *METHODS[label]]
                subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
                summary = json.loads((out / "summary.json").read_text())
                row[label] = summary["truth"]
            if "sgm" in args.methods:
                exact = warp_errors(rgb(left), rgb(right), disparity)
                row["photometric"] = {m: photometric_vs_sgm(run, m, exact)
                                      for m in args.methods if m != "sgm"}
            if "sgm" in args.methods and "tiny" in args.methods:
                # SGM where it has a depth, `tiny` elsewhere: what a hybrid that keeps the
                # classical result where it is confident could reach at the input view.
                sgm = np.load(run / "sgm" / "depth.npy")
                learned = np.load(run / "tiny" / "depth.npy")
                row["sgm+tiny"] = scores(np.where(sgm > 0, sgm, learned), disparity, fx * baseline)
            rows.append(row)
            print(root.name, frame, {m: round(row[m]["bad3"], 1) for m in args.methods}, flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "scores.json").write_text(json.dumps(rows, indent=1))
    lines = [
        "# Disparity at the input view on generated validation drives",
        "",
        f"Made by `{command}` on the validation "
        "drives (`VALIDATION_SEQUENCES=2 VALIDATION_SIZE=\"544 112\" bash "
        "scripts/validation_data.sh data/validation_choice`, seeds from 2,000,000, randomised "
        "5-50 cm rigs): the real pairs' metric, disparity at the input view against a dense "
        "truth (here the generator's exact depth), on these frames of every desk, room and "
        "street sequence. Mean over each kind's frames; bad-1 and bad-3 count uncovered pixels "
        "as wrong; the learned rows are the network's own output (`--on-check-fail flag`). "
        f"{args.note} `scores.json` has every frame.",
        "",
        "| kind | frames | method | bad-1 % | bad-3 % | bad-3 on covered % | coverage % | EPE px |",
        "|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    for kind in ("desk", "room", "street"):
        sel = [r for r in rows if r["kind"] == kind]
        if not sel:
            continue
        for m in args.methods + (["sgm+tiny"] if "sgm+tiny" in sel[0] else []):
            mean = lambda key: float(np.mean([r[m][key] for r in sel if r[m][key] is not None]))
            lines.append(
                f"| {kind} | {len(sel)} | {m} | {mean('bad1'):.1f} | {mean('bad3'):.1f} | "
                f"{mean('bad3_predicted'):.1f} | {mean('density'):.1f} | {mean('epe'):.2f} |"
            )
    labels = args.methods + (["sgm+tiny"] if rows and "sgm+tiny" in rows[0] else [])
    lines += ["", "Mean over the three kinds (each kind's mean weighs the same):", "",
              "| method | bad-3 % | bad-3 on covered % | coverage % |", "|---|---:|---:|---:|"]
    for m in labels:
        kinds = [[r[m] for r in rows if r["kind"] == k] for k in ("desk", "room", "street")]
        kinds = [k for k in kinds if k]
        mean = lambda key: float(np.mean([np.mean([s[key] for s in k]) for k in kinds]))
        lines.append(f"| {m} | {mean('bad3'):.2f} | {mean('bad3_predicted'):.2f} | "
                     f"{mean('density'):.1f} |")
    photometric = [m for m in args.methods if m != "sgm" and rows and "photometric" in rows[0]]
    if photometric:
        lines += ["", "Photometric consistency against SGM on the pixels both score (mean "
                  "|left - right warped by the depth|, [0, 1], per kind the mean over frames; "
                  "no worse: frames where the method's error is at most SGM's; exact: the "
                  "generator's exact depth scored the same way on the same pixels, the score a "
                  "perfect geometry gets):", "",
                  "| method | kind | frames | common % | method | SGM | exact | no worse | exact no worse |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for m in photometric:
            for kind in ("desk", "room", "street", "all"):
                sel = [r["photometric"][m] for r in rows if kind in ("all", r["kind"])]
                sel = [p for p in sel if p["method"] is not None]
                if not sel:
                    continue
                wins = sum(p["method"] <= p["sgm"] for p in sel)
                exact_wins = sum(p["exact"] <= p["sgm"] for p in sel)
                mean = lambda key: np.mean([p[key] for p in sel])
                lines.append(
                    f"| {m} | {kind} | {len(sel)} | {100 * mean('common'):.1f} | "
                    f"{mean('method'):.4f} | {mean('sgm'):.4f} | {mean('exact'):.4f} | "
                    f"{wins} of {len(sel)} | {exact_wins} of {len(sel)} |")
    (args.out / "README.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
