"""Content-addressed disk cache of goal fields (``$CROWD_CACHE_DIR/routing``, default ``~/.cache/crowd/routing``).

A goal's field, vias and corner distances depend only on the walkable area, the clearance, the grid, the build
constants and the goal's shape: their SHA-256 (:func:`field_key`) names an ``.npz`` file. A field of an office
floor (28 goals, 63 K nodes, 830 corners) takes 0.2-0.4 s to build and 1 ms to load. Files are written to a
temporary name in the cache folder and moved into place (:func:`sim.atomic_io.atomic_open`: a reader sees a whole
file or none); an unreadable or mismatched file is rebuilt.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from sim.atomic_io import atomic_open

CACHE_ENV = "CROWD_CACHE_DIR"
#: bump when the build changes what a key's arrays hold
FORMAT = 1


def cache_dir() -> Path:
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "crowd") / "routing"


def field_key(router, shape) -> str:
    """The SHA-256 of everything a goal's arrays depend on (module docstring)."""
    import shapely

    from sim.routing import corners, field

    g = router.grid
    h = hashlib.sha256()
    h.update(repr((FORMAT, g.x0, g.z0, g.h, g.nx, g.nz, router.clearance, router.order, router.steering,
                   field.SEED_CELLS, field.BAND_SLOWNESS, field.RIM_CELLS, corners.ARC_SEGMENTS, shape)).encode())
    h.update(shapely.to_wkb(shapely.normalize(router.walkable.area), byte_order=1))
    return h.hexdigest()


def load(key: str, expect: dict) -> dict | None:
    """The arrays stored under ``key`` when they have the ``expect``-ed shapes ({name: shape}), else None."""
    path = cache_dir() / f"{key}.npz"
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: z[k] for k in expect}
    except (OSError, ValueError, KeyError, EOFError):
        return None
    if any(out[k].shape != tuple(s) for k, s in expect.items()):
        return None
    return out


def save(key: str, arrays: dict) -> None:
    """Store ``arrays`` under ``key``, atomically; a cache that cannot be written is skipped (the field stays
    in memory)."""
    try:
        with atomic_open(cache_dir() / f"{key}.npz") as f:
            np.savez(f, **arrays)
    except OSError:
        return
