#!/usr/bin/env python3
"""Reference values for `model::metrics`, computed by scikit-image and NumPy.

Writes small deterministic image pairs as 8-bit PNGs and `reference.json` into
`model/tests/fixtures/metrics/`. PSNR and SSIM are computed exactly as the feed-forward
3DGS papers do (`peak_signal_noise_ratio(data_range=1.0)`, `structural_similarity(
win_size=11, gaussian_weights=True, data_range=1.0, channel_axis=2)`) on the images read
back from the PNGs, twice:

* `*_f64`: on `uint8 / 255` in float64, the papers' input;
* `*_f32`: on `uint8 / 255` rounded to float32 first, which is exactly what the Rust
  `RgbImage` holds, so the Rust result must match it to rounding error.

Depth fixtures are small float32 arrays with AbsRel, SqRel and RMSE by the rule documented
on `model::metrics::depth_errors`.

Run from the repository root: `python3 scripts/metrics_fixture.py`.
"""

import json
import os
import sys

import numpy as np
import scipy
import skimage
from PIL import Image
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

OUT = os.path.join("model", "tests", "fixtures", "metrics")
SEED = 20261123


def to_u8(img):
    """Float image in roughly [0, 1] to uint8, clipped and rounded."""
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


def gradient(h, w):
    """A smooth colour gradient with a soft diagonal wave."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    r = x / (w - 1)
    g = y / (h - 1)
    b = 0.5 + 0.4 * np.sin((x + y) / 7.0)
    return np.stack([r, g, b], axis=2)


def pairs(rng):
    """(name, a, b) float images; both are quantised to uint8 before saving."""
    out = []
    a = gradient(48, 64)
    out.append(("gradient_noisy", a, a + rng.normal(0.0, 0.05, a.shape)))

    a = gradient(53, 97)
    a = 0.6 * a + 0.4 * rng.uniform(0.0, 1.0, a.shape)
    out.append(("odd_shifted", a, np.roll(a, shift=(2, 3), axis=(0, 1))))

    a = np.full((48, 64, 3), 0.3)
    b = np.full((48, 64, 3), 0.7)
    out.append(("constant", a, b))

    a = 1.6 * gradient(53, 97) - 0.3  # clips to 0 and 1 over large regions
    b = a + rng.normal(0.0, 0.1, a.shape)
    out.append(("saturated", a, b))

    a = rng.uniform(0.0, 1.0, (11, 13, 3))  # just above the 11 x 11 window
    b = a * 0.8 + 0.1 + rng.normal(0.0, 0.08, a.shape)
    out.append(("tiny", a, b))
    return out


def depth_rule(pred, gt, lo, hi):
    """AbsRel, SqRel, RMSE, valid, missing by the rule of `depth_errors`."""
    pred = pred.astype(np.float64)
    gt = gt.astype(np.float64)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(gt) & (gt >= lo) & (gt <= hi)
    g = gt[valid]
    p = pred[valid]
    with np.errstate(invalid="ignore"):
        missing = ~(np.isfinite(p) & (p > 0))
    p = np.clip(np.where(np.isnan(p), 0.0, p), lo, hi)
    d = p - g
    return {
        "abs_rel": float(np.mean(np.abs(d) / g)),
        "sq_rel": float(np.mean(d * d / g)),
        "rmse": float(np.sqrt(np.mean(d * d))),
        "valid": int(valid.sum()),
        "missing": int(missing.sum()),
    }


def json_depth(arr):
    """A float32 array as nested lists; JSON has no NaN or infinity, so those are written
    as the strings "nan", "inf" and "-inf"."""
    return [[float(v) if np.isfinite(v) else str(v) for v in row] for row in arr]


def depth_fixture(rng):
    h, w = 6, 8
    gt = rng.uniform(2.0, 60.0, (h, w)).astype(np.float32)
    gt[rng.uniform(size=(h, w)) < 0.3] = 0.0  # sparse LiDAR
    gt[0, 0] = -1.0
    gt[0, 1] = np.nan
    gt[0, 2] = 95.0  # beyond 80 m
    gt[0, 3] = 80.0  # on the limit: counts
    pred = (gt * rng.uniform(0.8, 1.25, (h, w))).astype(np.float32)
    pred[gt <= 0] = rng.uniform(1.0, 50.0)
    pred[0, 3] = 120.0  # clamped to 80
    pred[1, 0:4] = [0.0, np.nan, -3.0, np.inf]
    gt[1, 0:4] = [5.0, 12.0, 30.0, 40.0]
    lo, hi = float(np.float32(1e-3)), float(np.float32(80.0))
    return {
        "min_depth": 1e-3,
        "max_depth": 80.0,
        "pred": json_depth(pred),
        "gt": json_depth(gt),
        **depth_rule(pred, gt, lo, hi),
    }


def main():
    rng = np.random.default_rng(SEED)
    os.makedirs(OUT, exist_ok=True)
    entries = []
    for name, a, b in pairs(rng):
        files = []
        for tag, img in (("a", a), ("b", b)):
            path = os.path.join(OUT, f"{name}_{tag}.png")
            Image.fromarray(to_u8(img), mode="RGB").save(path, optimize=True)
            files.append(os.path.basename(path))
        u8 = [np.asarray(Image.open(os.path.join(OUT, f)).convert("RGB")) for f in files]
        f64 = [x.astype(np.float64) / 255.0 for x in u8]
        f32 = [(x.astype(np.float32) / np.float32(255.0)).astype(np.float64) for x in u8]
        entry = {"name": name, "a": files[0], "b": files[1]}
        for tag, (x, y) in (("f64", f64), ("f32", f32)):
            entry[f"psnr_{tag}"] = float(peak_signal_noise_ratio(x, y, data_range=1.0))
            entry[f"ssim_{tag}"] = float(
                structural_similarity(
                    x, y, win_size=11, gaussian_weights=True, data_range=1.0, channel_axis=2
                )
            )
        if name == "tiny":
            # The whole map, averaged over channels, checks the reflect boundary too.
            _, full = structural_similarity(
                *f32, win_size=11, gaussian_weights=True, data_range=1.0, channel_axis=2, full=True
            )
            entry["ssim_map_f32"] = [float(v) for v in full.mean(axis=2).ravel()]
        entries.append(entry)
    reference = {
        "generator": "scripts/metrics_fixture.py",
        "seed": SEED,
        "versions": {
            "python": sys.version.split()[0],
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "scikit-image": skimage.__version__,
        },
        "images": entries,
        "depth": depth_fixture(rng),
    }
    with open(os.path.join(OUT, "reference.json"), "w") as f:
        json.dump(reference, f, indent=1, allow_nan=False)
        f.write("\n")


if __name__ == "__main__":
    main()
