"""Where a reconstruction's disparity errors are, against a ground-truth disparity: bad-3 over
the truth's pixels split into those the right camera does not see (half-occluded: a nearer
truth pixel of the row lands on or left of their match) and the rest, the rest banded by
distance to the nearest truth depth edge (a jump of over 3 px to the next pixel).

    python3 scripts/disparity_errors.py TRUTH.png FX_BASELINE RUN_DIR [RUN_DIR ...] [--truth-scale S]

TRUTH.png: disparity in input pixels times 1/S (0: unknown); FX_BASELINE: fx (input pixels)
times the baseline (metres), so disparity = FX_BASELINE / depth; each RUN_DIR holds the
`depth.png` of `stereosplat reconstruct` (16-bit, depth x 256, 0: none). A pixel without a
prediction counts as wrong, as in `reconstruct`'s own bad-3. Prints one JSON object per run.

Two more splits tell where a wrong disparity comes from. `too_near_visible`: the share of the
visible pixels whose disparity is over 3 px too large (a nearer surface drawn over them).
`centres`: the same bad-3 taken at the centres of the run's Gaussians (`gaussians.ply`,
projected into the left camera of `summary.json`) on the visible pixels they land on: the
depth the network put on each Gaussian, before the rendering blends neighbours, so the gap
between it and the rendered figure is what the Gaussians' extent adds; `gaussian_extent_px`
is the median over the Gaussians of their largest standard deviation in input pixels.
"""
import argparse
import json
import pathlib

import numpy as np
from PIL import Image, ImageFilter

from ply import load_ply

EDGE_JUMP_PX = 3.0
BAD_PX = 3.0
BANDS_PX = (3, 7, 15, 31)


def half_occluded(truth: np.ndarray) -> np.ndarray:
    """Known pixels whose match in the right image is hidden by a nearer pixel of the row or
    falls outside it."""
    h, w = truth.shape
    occluded = np.zeros(truth.shape, bool)
    columns = np.arange(w, dtype=np.float64)
    for y in range(h):
        row = truth[y]
        known = row > 0
        landing = np.where(known, columns - row, np.inf)
        # Leftmost landing of the known pixels to the right of each pixel.
        right_min = np.minimum.accumulate(landing[::-1])[::-1]
        right_min = np.append(right_min[1:], np.inf)
        occluded[y] = known & ((right_min < landing - 1.0) | (landing < 0))
    return occluded


def edge_distance_bands(truth: np.ndarray) -> list:
    """Masks of the pixels within each of BANDS_PX of a truth depth edge (cumulative): a jump
    of over EDGE_JUMP_PX between two known neighbours (the border of an unknown hole is not an
    edge)."""
    known = truth > 0
    edges = np.zeros(truth.shape, bool)
    jump_x = (np.abs(np.diff(truth, axis=1)) > EDGE_JUMP_PX) & known[:, 1:] & known[:, :-1]
    jump_y = (np.abs(np.diff(truth, axis=0)) > EDGE_JUMP_PX) & known[1:] & known[:-1]
    edges[:, :-1] |= jump_x
    edges[:-1] |= jump_y
    edges = (edges * 255).astype(np.uint8)
    image, grown, masks = Image.fromarray(edges), 0, []
    for r in BANDS_PX:
        # r passes of a 3x3 maximum: the square of half-width r about every edge pixel.
        for _ in range(r - grown):
            image = image.filter(ImageFilter.MaxFilter(3))
        grown = r
        masks.append(np.asarray(image) > 0)
    return masks


def gaussian_centres(run: pathlib.Path, shape: tuple) -> tuple:
    """Pixel rows, columns, depths and extents (largest standard deviation, in pixels) of
    the run's Gaussians (`gaussians.ply`, in the left camera's frame) projected with
    the intrinsics of its `summary.json`, those that land in an image of `shape`."""
    ply = load_ply(run / "gaussians.ply")
    column = lambda *names: np.stack([ply[n] for n in names], axis=1).astype(np.float64)
    xyz, log_scales = column("x", "y", "z"), column("scale_0", "scale_1", "scale_2")
    s = json.loads((run / "summary.json").read_text())
    z = xyz[:, 2]
    ahead = z > 1e-9
    xyz, z, log_scales = xyz[ahead], z[ahead], log_scales[ahead]
    col = np.round(s["fx"] * xyz[:, 0] / z + s["cx"] - 0.5).astype(np.int64)
    row = np.round(s["fy"] * xyz[:, 1] / z + s["cy"] - 0.5).astype(np.int64)
    extent = s["fx"] * np.exp(log_scales.max(axis=1)) / z
    inside = (col >= 0) & (col < shape[1]) & (row >= 0) & (row < shape[0])
    return row[inside], col[inside], z[inside], extent[inside]


def breakdown(truth: np.ndarray, fx_baseline: float, run: pathlib.Path) -> dict:
    """The run's bad-3 (%) over the truth's known pixels, its half-occluded share and bad-3
    there, bad-3 on the visible rest and per edge-distance band (each band's share of the
    known pixels beside it), and the median signed disparity error of predicted pixels."""
    depth = np.asarray(Image.open(run / "depth.png"), dtype=np.float64) / 256.0
    disparity = np.where(depth > 0, fx_baseline / np.maximum(depth, 1e-12), 0.0)
    known = truth > 0
    wrong = (depth <= 0) | (np.abs(disparity - truth) > BAD_PX)
    occluded = half_occluded(truth)
    total = known.sum()
    out = {
        "bad3": 100.0 * wrong[known].mean(),
        "occluded_share": 100.0 * occluded[known].mean(),
        "bad3_occluded": 100.0 * wrong[known & occluded].mean(),
        "bad3_visible": 100.0 * wrong[known & ~occluded].mean(),
        "signed_median_px": float(np.median((disparity - truth)[known & (depth > 0)])),
        "too_near_visible": 100.0 * (disparity - truth > BAD_PX)[known & ~occluded].mean(),
        "bands": [],
    }
    if (run / "gaussians.ply").exists():
        row, col, z, extent = gaussian_centres(run, truth.shape)
        out["gaussian_extent_px"] = float(np.median(extent))
        at = truth[row, col]
        seen = (at > 0) & ~occluded[row, col]
        error = fx_baseline / z[seen] - at[seen]
        out["centres_bad3_visible"] = 100.0 * (np.abs(error) > BAD_PX).mean()
        out["centres_too_near_visible"] = 100.0 * (error > BAD_PX).mean()
    labels = [f"{low}-{high}" for low, high in zip((0,) + tuple(b + 1 for b in BANDS_PX), BANDS_PX)]
    labels.append(f">{BANDS_PX[-1]}")
    within = edge_distance_bands(truth) + [np.ones(truth.shape, bool)]
    inside = np.zeros(truth.shape, bool)
    for label, band in zip(labels, within):
        ring = known & ~occluded & band & ~inside
        inside |= band
        out["bands"].append({
            "edge_distance_px": label,
            "share": round(100.0 * ring.sum() / total, 2),
            "bad3": round(100.0 * wrong[ring].mean(), 2) if ring.any() else None,
        })
    for key in ("bad3", "occluded_share", "bad3_occluded", "bad3_visible", "signed_median_px",
                "too_near_visible", "centres_bad3_visible", "centres_too_near_visible",
                "gaussian_extent_px"):
        if key in out:
            out[key] = round(float(out[key]), 2)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("truth")
    parser.add_argument("fx_baseline", type=float)
    parser.add_argument("runs", nargs="+", type=pathlib.Path)
    parser.add_argument("--truth-scale", type=float, default=1.0)
    args = parser.parse_args()
    truth = np.asarray(Image.open(args.truth), dtype=np.float64) * args.truth_scale
    for run in args.runs:
        print(json.dumps({"run": str(run), **breakdown(truth, args.fx_baseline, run)}))


if __name__ == "__main__":
    main()
