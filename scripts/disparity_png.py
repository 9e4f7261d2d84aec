"""Writes a float disparity map (.npy or the first array of an .npz; inf, NaN or <= 0 =
unknown) as a 16-bit grey PNG of disparity x 256, 0 = unknown (the KITTI disparity
convention; `stereosplat reconstruct --truth-scale 0.00390625` reads it back).
Only numpy and the standard library (zlib), so setup needs no imaging package.

    python3 scripts/disparity_png.py IN.npz OUT.png
"""
import struct
import sys
import zlib

import numpy as np


def chunk(kind: bytes, data: bytes) -> bytes:
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))


def main(src: str, dst: str) -> None:
    loaded = np.load(src)
    disp = loaded[loaded.files[0]] if hasattr(loaded, "files") else loaded
    disp = np.asarray(disp, dtype=np.float64)
    known = np.isfinite(disp) & (disp > 0)
    values = np.where(known, np.clip(np.round(disp * 256.0), 1, 65535), 0).astype(">u2")
    height, width = values.shape
    rows = b"".join(b"\x00" + values[y].tobytes() for y in range(height))
    header = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 9))
    with open(dst, "wb") as f:
        f.write(png + chunk(b"IEND", b""))
    print(f"{dst}: {width}x{height}, {int(known.sum())} known disparities")


if __name__ == "__main__":
    main(*sys.argv[1:3])
