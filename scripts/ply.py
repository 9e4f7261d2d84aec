"""Reading the project's 3DGS PLY files (binary little-endian, one vertex element whose
properties are all floats, as `stereosplat` writes them) in the scripts that inspect them."""

import sys

import numpy as np


def load_ply(path):
    """The vertex records of a binary little-endian PLY whose properties are all floats."""
    with open(path, "rb") as f:
        names, count = [], None
        while True:
            line = f.readline()
            if not line:
                sys.exit(f"{path}: no end_header")
            words = line.decode("ascii").split()
            if words[:2] == ["format", "ascii"]:
                sys.exit(f"{path}: ascii PLY, expected binary_little_endian")
            if words[:2] == ["element", "vertex"]:
                count = int(words[2])
            elif words[:1] == ["element"] and count is not None:
                sys.exit(f"{path}: elements after vertex are not read here")
            elif words[:1] == ["property"]:
                if words[1] != "float":
                    sys.exit(f"{path}: property {words[-1]} is {words[1]}, expected float")
                names.append(words[2])
            elif words == ["end_header"]:
                break
        data = np.fromfile(f, dtype="<f4", count=count * len(names))
    if count is None or data.size != count * len(names):
        sys.exit(f"{path}: expected {count} records of {len(names)} floats")
    data = data.reshape(count, len(names))
    return {name: data[:, i] for i, name in enumerate(names)}
