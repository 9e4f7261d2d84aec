#!/usr/bin/env python3
"""Whether one `stereosplat research eval` run beats another on the same bins, beyond noise.

The bin averages of two runs differ by a mean over bins; this script pairs the runs bin by
bin (and frame by frame, grouped by the frame's distance from the bin's input pair), reports
the mean difference, how many bins moved each way, and a 95% bootstrap interval of the mean
(10,000 resamples of the bins, seeded), so a small gain can be told from a draw.

    python3 scripts/paired_bins.py BASELINE/eval.json CANDIDATE/eval.json [--metrics psnr,lpips]

Prints one JSON object. Differences are candidate minus baseline; for LPIPS, AbsRel and SqRel
lower is better, for PSNR and SSIM higher.
"""
import argparse
import json
import sys

import numpy as np

LOWER_IS_BETTER = {"lpips", "abs_rel", "sq_rel"}


def frames(path):
    """{(sequence, first frame, frame, side): (offset from the bin's first frame, frame dict)}"""
    run = json.load(open(path))
    out = {}
    for b in run["bins"]:
        for f in b["frames"]:
            out[(b["sequence"], b["first"], f["frame"], f["side"])] = (f["frame"] - b["first"], f)
    return out


def interval(diffs, rng):
    means = rng.choice(diffs, (10_000, len(diffs))).mean(axis=1)
    return [round(float(x), 5) for x in np.percentile(means, [2.5, 97.5])]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("baseline")
    parser.add_argument("candidate")
    parser.add_argument("--metrics", default="psnr,lpips")
    args = parser.parse_args()
    base, cand = frames(args.baseline), frames(args.candidate)
    common = sorted(set(base) & set(cand))
    if not common:
        sys.exit("the two runs share no bins")
    rng = np.random.default_rng(0)
    report = {"baseline": args.baseline, "candidate": args.candidate, "frames": len(common)}
    for metric in args.metrics.split(","):
        per_bin, per_offset = {}, {}
        for key in common:
            b, c = base[key][1].get(metric), cand[key][1].get(metric)
            if b is None or c is None:
                continue
            per_bin.setdefault(key[:2], []).append(c - b)
            per_offset.setdefault(min(base[key][0] // 4, 4), []).append(c - b)
        diffs = np.array([np.mean(v) for v in per_bin.values()])
        sign = -1 if metric in LOWER_IS_BETTER else 1
        report[metric] = {
            "bins": len(diffs),
            "mean_difference": round(float(diffs.mean()), 5),
            "bins_better": int((sign * diffs > 0).sum()),
            "bins_worse": int((sign * diffs < 0).sum()),
            "ci95": interval(diffs, rng),
            "by_frame_offset": {
                f"{4 * k}-{4 * k + 3}" if k < 4 else "16+": {
                    "frames": len(v),
                    "mean_difference": round(float(np.mean(v)), 5),
                }
                for k, v in sorted(per_offset.items())
            },
        }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
