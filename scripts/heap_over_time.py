#!/usr/bin/env python3
"""The live heap of a process over time, from a heaptrack recording: per window of seconds,
the smallest, median and largest heap heaptrack saw (every malloc'd byte not yet freed, C
libraries' included), so a run's resident memory can be read against what it holds.

    heaptrack -o out/heap/drive stereosplat bench drive --out out/bench_drive
    python3 scripts/heap_over_time.py out/heap/drive.zst [--window 30]

Needs heaptrack_print (Debian's heaptrack). Prints a Markdown table.
"""
import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def samples(recording: Path):
    """(seconds, live heap bytes) pairs of the recording, in time order."""
    with tempfile.TemporaryDirectory() as tmp:
        massif = Path(tmp) / "massif.out"
        subprocess.run(
            ["heaptrack_print", "-f", str(recording), "--print-peaks", "0",
             "--print-allocators", "0", "--print-temporary", "0", "--print-leaks", "0",
             "--print-massif", str(massif), "--massif-threshold", "100"],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t = None
        out = []
        for line in massif.read_text().splitlines():
            if line.startswith("time="):
                t = float(line[5:])
            elif line.startswith("mem_heap_B=") and t is not None:
                out.append((t, int(line[11:])))
        return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("recording", type=Path)
    p.add_argument("--window", type=float, default=30.0, help="seconds per row")
    a = p.parse_args()
    points = samples(a.recording)
    if not points:
        print("no heap samples in the recording", file=sys.stderr)
        return 1
    mib = lambda b: b / 2**20
    print("| from s | min MiB | median MiB | max MiB |")
    print("| ---: | ---: | ---: | ---: |")
    end = points[-1][0]
    start = 0.0
    while start <= end:
        w = [m for t, m in points if start <= t < start + a.window]
        if w:
            print(f"| {start:.0f} | {mib(min(w)):.1f} | {mib(statistics.median(w)):.1f} "
                  f"| {mib(max(w)):.1f} |")
        start += a.window
    return 0


if __name__ == "__main__":
    sys.exit(main())
