#!/usr/bin/env python3
"""The same-call A/B of `gpu_bench.sh ab` as a markdown table: per preset and round, the
median ms of `bench model` for the baseline build and the current one, and their ratio.
  python3 scripts/ab_table.py DIR [DIR...]   (each DIR holds ab_<preset>_<build>_<round>.json)"""
import json
import sys
from pathlib import Path


def field(path: Path, key: str = "median_ms") -> float:
    """One number of a `bench model` JSON."""
    return json.loads(path.read_text())[key]


def main() -> None:
    print("| call | preset | round | baseline ms | this build ms | ratio | cost-volume branch, baseline / this |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for d in map(Path, sys.argv[1:]):
        for preset in ("tiny", "small", "paper"):
            for rnd in (1, 2):
                base = d / f"ab_{preset}_baseline_{rnd}.json"
                this = d / f"ab_{preset}_stereosplat_{rnd}.json"
                if not (base.exists() and this.exists()):
                    continue
                b, t = field(base), field(this)
                cb, ct = field(base, "cost_volume_median_ms"), field(this, "cost_volume_median_ms")
                print(f"| {d.name} | {preset} | {rnd} | {b:.1f} | {t:.1f} | {b / t:.2f}x | {cb:.1f} / {ct:.1f} |")


if __name__ == "__main__":
    main()
