"""Image output: PNG files written atomically."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def write_png(path, pixels: np.ndarray) -> Path:
    """Write ``pixels`` (h, w, 3|4) uint8, top row first, as a PNG.

    The file appears complete or not at all: it is written to a temporary file
    in the same folder and moved into place with ``os.replace``.
    """
    from PIL import Image

    path = Path(path)
    px = np.asarray(pixels)
    if px.dtype != np.uint8 or px.ndim != 3 or px.shape[2] not in (3, 4):
        raise ValueError(f"write_png {path}: expected (h, w, 3|4) uint8 pixels, got {px.shape} {px.dtype}")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            Image.fromarray(np.ascontiguousarray(px)).save(fh, format="PNG")
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def read_png(path) -> np.ndarray:
    """(h, w, 3) uint8 pixels of a PNG (top row first)."""
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))
