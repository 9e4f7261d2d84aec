"""Builds the generator's photo texture bank, model/textures/photo_bank.png, from the
photographs that ship inside the scikit-image wheel on the Python package index (their
licences, as scikit-image's own docstrings state them, go to model/textures/ATTRIBUTION.md).

The bank is an atlas of 128x128 tiles cut at seeded random places and scales from each
photograph; the generator (model::synth::photos) maps tiles onto surfaces. No stereo pair is
used, and no photograph whose terms the docstring does not state (the wheel's Middlebury motorcycle pair is left out on purpose: it is evaluation data).

    python3 scripts/texture_bank.py [WHEEL_DIR]

WHEEL_DIR holds an unpacked scikit-image wheel; without it the script runs
`pip download scikit-image==0.26.0 --no-deps` into a temporary folder and unpacks it.
"""

import inspect
import pathlib
import re
import subprocess
import sys
import tempfile
import zipfile

import numpy as np
from PIL import Image

TILE = 128
COLUMNS = 8
# (file in skimage/data, fetcher function whose docstring states the licence, tiles)
PHOTOS = [
    ("astronaut.png", "astronaut", 5),
    ("brick.png", "brick", 4),
    ("camera.png", "camera", 4),
    ("chelsea.png", "chelsea", 4),
    ("coffee.png", "coffee", 4),
    ("coins.png", "coins", 4),
    ("grass.png", "grass", 4),
    ("gravel.png", "gravel", 4),
    ("rocket.jpg", "rocket", 4),
    ("retina.jpg", "retina", 2),
    ("hubble_deep_field.jpg", "hubble_deep_field", 3),
    ("text.png", "text", 2),
    ("cell.png", "cell", 2),
    ("ihc.png", "immunohistochemistry", 2),
]


def wheel_dir() -> pathlib.Path:
    if len(sys.argv) > 1:
        return pathlib.Path(sys.argv[1])
    tmp = pathlib.Path(tempfile.mkdtemp())
    subprocess.run(
        [sys.executable, "-m", "pip", "download", "scikit-image==0.26.0", "--no-deps",
         "-d", str(tmp), "-q"],
        check=True,
    )
    wheel = next(tmp.glob("scikit_image-*.whl"))
    with zipfile.ZipFile(wheel) as z:
        z.extractall(tmp, [n for n in z.namelist() if n.startswith("skimage/data/")])
    return tmp


def licence(fetchers: str, function: str) -> str:
    """The sentences of a fetcher's docstring that state where the image comes from and
    under which terms."""
    match = re.search(rf"def {function}\(.*?\"\"\"(.*?)\"\"\"", fetchers, re.S)
    if not match:
        return "see scikit-image's documentation"
    text = " ".join(match.group(1).split())
    text = re.sub(r"\b(Notes|Returns|References) -+ ", "", text)
    keep = [s for s in re.split(r"(?<=\.)\s", text)
            if re.search(r"licen|copyright|public domain|CC0|CC-0|CC BY", s, re.I)
            and "ndarray" not in s and "versionchanged" not in s]
    return " ".join(keep) or "see scikit-image's documentation"


def main() -> None:
    root = wheel_dir()
    data = root / "skimage" / "data"
    fetchers = (data / "_fetchers.py").read_text()
    rng = np.random.default_rng(20261125)
    tiles, notes = [], []
    for name, function, count in PHOTOS:
        image = Image.open(data / name).convert("RGB")
        for _ in range(count):
            scale = rng.uniform(0.5, 1.0)
            side = int(min(image.size) * scale)
            x = int(rng.integers(0, image.size[0] - side + 1))
            y = int(rng.integers(0, image.size[1] - side + 1))
            crop = image.crop((x, y, x + side, y + side)).resize((TILE, TILE), Image.LANCZOS)
            tiles.append(np.asarray(crop))
        notes.append(f"- `{name}` ({count} tiles): {licence(fetchers, function)}")
    rows = (len(tiles) + COLUMNS - 1) // COLUMNS
    atlas = np.zeros((rows * TILE, COLUMNS * TILE, 3), np.uint8)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, COLUMNS)
        atlas[r * TILE:(r + 1) * TILE, c * TILE:(c + 1) * TILE] = tile
    out = pathlib.Path(__file__).resolve().parent.parent / "model" / "textures"
    out.mkdir(parents=True, exist_ok=True)
    Image.fromarray(atlas).save(out / "photo_bank.png", optimize=True)
    (out / "ATTRIBUTION.md").write_text(
        "# Photo texture bank\n\n"
        f"`photo_bank.png`: {len(tiles)} tiles of {TILE}x{TILE} pixels, {COLUMNS} per row, cut"
        " by `python3 scripts/texture_bank.py` from photographs in the scikit-image 0.26.0"
        " wheel (PyPI, `skimage/data/`). The generator's domain randomisation maps them onto"
        " surfaces. Licences as scikit-image's docstrings state them:\n\n"
        + "\n".join(notes) + "\n"
    )
    print(f"{len(tiles)} tiles -> {out / 'photo_bank.png'}")


if __name__ == "__main__":
    main()
