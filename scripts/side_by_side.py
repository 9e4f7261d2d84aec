#!/usr/bin/env python3
"""Pictures of the same bins from several `stereosplat research eval` runs, side by side.

Each eval picture (model/src/eval/pictures.rs) stacks four panels of one frame top to bottom:
recorded image, render, rendered depth, error. For every picture name the first run has
(`<sequence>_bin<first>_<role>.png`), this writes one PNG with, top to bottom: the bin's input
(the first frame's recorded image), each run's render of that frame, and its recorded image,
each strip labelled.

    python3 scripts/side_by_side.py OUT_DIR LABEL=EVAL_DIR [LABEL=EVAL_DIR ...]
"""

import sys
from pathlib import Path

from PIL import Image, ImageDraw

PANELS = 4  # recorded, render, depth, error


def panel(path: Path, index: int) -> Image.Image:
    """Panel `index` (0 recorded, 1 render) of an eval picture."""
    sheet = Image.open(path).convert("RGB")
    h = sheet.height // PANELS
    return sheet.crop((0, index * h, sheet.width, (index + 1) * h))


def labelled(image: Image.Image, label: str) -> Image.Image:
    """The image with a label strip on its left."""
    width = 110
    out = Image.new("RGB", (image.width + width, image.height), (255, 255, 255))
    out.paste(image, (width, 0))
    ImageDraw.Draw(out).text((4, image.height // 2 - 6), label, fill=(0, 0, 0))
    return out


def main() -> None:
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = Path(sys.argv[1])
    runs = [arg.split("=", 1) for arg in sys.argv[2:]]
    if any(len(r) != 2 for r in runs):
        sys.exit("each run is LABEL=EVAL_DIR")
    out.mkdir(parents=True, exist_ok=True)
    first_dir = Path(runs[0][1]) / "pictures"
    names = sorted(p.name for p in first_dir.glob("*.png"))
    for name in names:
        if not all((Path(d) / "pictures" / name).exists() for _, d in runs):
            print(f"skipped {name}: not in every run")
            continue
        bin_name = name.rsplit("_", 1)[0]
        strips = [labelled(panel(first_dir / f"{bin_name}_first.png", 0), "input (first)")]
        for label, d in runs:
            strips.append(labelled(panel(Path(d) / "pictures" / name, 1), label))
        strips.append(labelled(panel(first_dir / name, 0), "ground truth"))
        sheet = Image.new("RGB", (strips[0].width, sum(s.height for s in strips)))
        y = 0
        for s in strips:
            sheet.paste(s, (0, y))
            y += s.height
        sheet.save(out / name)
    print(f"wrote {len(names)} pictures to {out}")


if __name__ == "__main__":
    main()
