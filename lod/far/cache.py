"""The far footprints' on-disk cache: a measured ``FarTable`` (``lod.far.footprint``) under the SHA-256 of what it
was measured from (the posed surfaces, the measurement's grids and format), written atomically, read back with
its shapes and values checked; an entry that cannot be read is measured again and replaced."""
from __future__ import annotations

import hashlib
import io
import os
import zipfile
from pathlib import Path

import numpy as np

from lod.far import footprint as fp
from sim.atomic_io import write_atomic

#: environment variable naming the cache folder (shared with the other caches)
CACHE_ENV = "CROWD_CACHE_DIR"
FIELDS = ("area", "ambient", "head", "direct", "radius", "centre", "ground", "floor", "extent", "varied", "varied_base")


def cache_dir() -> Path:
    """``$CROWD_CACHE_DIR/far`` or ``~/.cache/crowd/far``."""
    d = os.environ.get(CACHE_ENV, "")
    return (Path(d).expanduser() if d else Path.home() / ".cache" / "crowd") / "far"


def key(surfaces, rest=None) -> str:
    """SHA-256 hex of the measurement's format and grids, every array of ``surfaces`` and the rest pose (shape,
    dtype, bytes)."""
    h = hashlib.sha256(repr((fp.FOOTPRINT_FORMAT, fp.VIEW_AZIMUTHS, fp.VIEW_ELEVATIONS, fp.LIGHT_AZIMUTHS,
                             fp.LIGHT_ELEVATIONS, fp.RESOLUTION, fp.RINGS, fp.RING_EXTENT, fp.RING_POINTS,
                             len(surfaces))).encode())
    for s in list(surfaces) + ([(rest,)] if rest is not None else []):
        for a in s:
            a = np.ascontiguousarray(a)
            h.update(repr((a.shape, a.dtype.str)).encode())
            h.update(a.tobytes())
    return h.hexdigest()


def _shapes() -> dict:
    ve, va, le, la = fp.VIEW_ELEVATIONS, fp.VIEW_AZIMUTHS, fp.LIGHT_ELEVATIONS, fp.LIGHT_AZIMUTHS
    return {"area": (ve, va), "ambient": (ve, va, 3), "head": (ve, va, 3), "direct": (ve, va, le, la, 3),
            "radius": (), "centre": (3,), "ground": (ve, va, fp.RINGS), "floor": (3,), "extent": (3,),
            "varied": (ve, va, 2 + le * la), "varied_base": (ve, va, 3)}


def load(path: Path) -> fp.FarTable | None:
    """The table stored at ``path``, or None when it is missing, unreadable, of other shapes or not finite."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: np.asarray(z[k], np.float64) for k in FIELDS}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    if any(arrays[k].shape != s for k, s in _shapes().items()) or not all(np.isfinite(a).all() for a in arrays.values()):
        return None
    return fp.FarTable(arrays["area"], arrays["ambient"], arrays["head"], arrays["direct"], float(arrays["radius"]),
                       arrays["centre"], arrays["ground"], arrays["floor"], arrays["extent"], arrays["varied"],
                       arrays["varied_base"])


def save(path: Path, table: fp.FarTable) -> None:
    buf = io.BytesIO()
    np.savez(buf, **{k: np.asarray(getattr(table, k), np.float64) for k in FIELDS})
    write_atomic(path, buf.getvalue())


def measured(surfaces, use_cache: bool = True, rest=None) -> fp.FarTable:
    """The far table of ``surfaces`` with the rest pose ``rest`` (``lod.far.footprint.measure``), from the cache
    when it holds it."""
    if not use_cache or not surfaces:
        return fp.measure(surfaces, rest=rest)
    path = cache_dir() / f"{key(surfaces, rest)}.npz"
    table = load(path)
    if table is None:
        table = fp.measure(surfaces, rest=rest)
        try:
            save(path, table)
        except OSError:  # a read-only cache folder: measured every time, still right
            pass
    return table
