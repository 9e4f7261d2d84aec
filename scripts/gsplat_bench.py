#!/usr/bin/env python3
"""gsplat's forward pass timed on the scenes `stereosplat bench render` times (results/gpu/).

Run on a GPU machine with PyTorch and gsplat (its CUDA code is compiled on first use), on a
PLY written by `stereosplat render` from the same seeded generator and camera flags:

    stereosplat render --scene random --gaussians 1000000 --width 1920 --height 1080 --out S
    python3 scripts/gsplat_bench.py --ply S/scene.ply --width 1920 --height 1080

The camera is ours: at the origin looking down +z, square pixels, the given horizontal field
of view, principal point at the image centre. gsplat puts pixel centres at +0.5 where we put
them at integers, so its principal point is ours plus half a pixel. Colours are the PLY's
degree-0 coefficients evaluated once (`0.5 + C0 * f_dc`), so both sides blend plain RGB.

Two figures, median over the timed runs, printed as JSON:
- `forward`: `gsplat.rasterization(..., render_mode="RGB+D")` with every input already on
  the GPU, timed with CUDA events (projection, tile intersection and CUB sort, blending);
- `whole_call`: the same with the Gaussians copied from host memory first and the RGB, depth
  and alpha images copied back after, what `GpuRasterizer::render`'s whole call includes.
"""

import argparse
import json
import math
import statistics
import time

import numpy as np

from ply import load_ply

SH_C0 = 0.28209479177387814


def gaussians(ply):
    """Means, (w, x, y, z) quaternions, standard deviations, opacities and RGB as arrays."""
    col = lambda *names: np.stack([ply[n] for n in names], axis=1)
    return {
        "means": col("x", "y", "z"),
        "quats": col("rot_0", "rot_1", "rot_2", "rot_3"),
        "scales": np.exp(col("scale_0", "scale_1", "scale_2")),
        "opacities": 1.0 / (1.0 + np.exp(-ply["opacity"])),
        "colors": 0.5 + SH_C0 * col("f_dc_0", "f_dc_1", "f_dc_2"),
    }


def intrinsics(width, height, hfov):
    """Our camera's matrix in gsplat's pixel convention (centres at +0.5)."""
    f = 0.5 * width / math.tan(math.radians(hfov) / 2)
    cx, cy = (width - 1) / 2 + 0.5, (height - 1) / 2 + 0.5
    return np.array([[f, 0, cx], [0, f, cy], [0, 0, 1]], dtype=np.float32)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ply", required=True)
    ap.add_argument("--width", type=int, default=544)
    ap.add_argument("--height", type=int, default=112)
    ap.add_argument("--hfov", type=float, default=90.0)
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--warmup", type=int, default=5)
    args = ap.parse_args()

    import torch
    import gsplat

    host = {k: torch.from_numpy(np.ascontiguousarray(v, dtype=np.float32))
            for k, v in gaussians(load_ply(args.ply)).items()}
    host = {k: v.pin_memory() for k, v in host.items()}
    dev = torch.device("cuda")
    view = torch.eye(4, device=dev)[None]
    ks = torch.from_numpy(intrinsics(args.width, args.height, args.hfov)).to(dev)[None]

    def forward(g):
        return gsplat.rasterization(
            g["means"], g["quats"], g["scales"], g["opacities"], g["colors"], view, ks,
            args.width, args.height, render_mode="RGB+D")

    on_gpu = {k: v.to(dev) for k, v in host.items()}

    def time_forward():
        start, end = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
        start.record()
        forward(on_gpu)
        end.record()
        end.synchronize()
        return start.elapsed_time(end)

    def time_whole():
        torch.cuda.synchronize()
        t0 = time.perf_counter()
        g = {k: v.to(dev, non_blocking=True) for k, v in host.items()}
        image, alpha, _ = forward(g)
        image.cpu(), alpha.cpu()
        return (time.perf_counter() - t0) * 1e3

    report = {"gsplat": gsplat.__version__, "torch": torch.__version__,
              "device": torch.cuda.get_device_name(), "gaussians": len(host["means"]),
              "width": args.width, "height": args.height}
    for name, fn in [("forward", time_forward), ("whole_call", time_whole)]:
        for _ in range(args.warmup):
            fn()
        times = [fn() for _ in range(args.runs)]
        report[name] = {"median_ms": statistics.median(times), "min_ms": min(times),
                        "runs": args.runs}
    _, _, meta = forward(on_gpu)
    ids = meta.get("isect_ids")
    report["tile_intersections"] = None if ids is None else int(ids.numel())
    report["tile_size"] = meta.get("tile_size")
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
