"""PNG files of rendered frames: written atomically, read back (the renderer hands over pixels, ``render.renderer.
Renderer.read_pixels``; files are the application's)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.atomic_io import atomic_open


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
    with atomic_open(path, "wb") as fh:
        Image.fromarray(np.ascontiguousarray(px)).save(fh, format="PNG")
    return path


def read_png(path) -> np.ndarray:
    """(h, w, 3) uint8 pixels of a PNG (top row first)."""
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))
