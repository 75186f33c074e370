"""Content-addressed columnar cache of recordings (``$CROWD_CACHE_DIR/replay``, default ``~/.cache/crowd/replay``;
issue 47, item 2 in part).

A recording is read through PedPy once: its sorted columns (:class:`sim.replay.recording.Recording`: person ids,
row starts, frames, positions and the search keys of :meth:`Recording.at`) are stored as ``.npy`` files in a folder
named by the SHA-256 of the file's bytes and of how it was read (format, unit, frame rate, :data:`FORMAT`). The
folder is written under a temporary name and renamed into place, so a reader sees a whole entry or none. Later
runs memory-map the columns (``numpy.load(mmap_mode="r")``): no parse, and only the pages a frame touches are read.
An entry that cannot be read (a missing column, shapes that disagree) is ignored and written again; a cache that
cannot be written is skipped (the recording stays in memory).
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

CACHE_ENV = "CROWD_CACHE_DIR"
#: bump when what an entry holds changes
FORMAT = 1
#: the columns of an entry
COLUMNS = ("ids", "start", "frames", "xy", "keys")
#: bytes read at a time while hashing a file
CHUNK = 1 << 22


def cache_dir() -> Path:
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "crowd") / "replay"


def key(path: Path, fmt: str, unit, frame_rate) -> str:
    """The SHA-256 of the file's bytes and of how it is read (module docstring)."""
    h = hashlib.sha256(repr((FORMAT, fmt, unit, frame_rate, Path(path).suffix.lower())).encode())
    with open(path, "rb") as f:
        while True:
            b = f.read(CHUNK)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def load(k: str):
    """``(columns dict, meta dict)`` of entry ``k``, memory-mapped, or None when there is no whole entry."""
    folder = cache_dir() / k
    try:
        meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
        cols = {c: np.load(folder / f"{c}.npy", mmap_mode="r", allow_pickle=False) for c in COLUMNS}
    except (OSError, ValueError, json.JSONDecodeError):
        return None
    rows, persons = cols["frames"].shape[0], cols["ids"].shape[0]
    if (cols["xy"].shape != (rows, 2) or cols["keys"].shape != (rows,) or cols["start"].shape != (persons + 1,)
            or not isinstance(meta, dict) or "frame_rate" not in meta):
        return None
    return cols, meta


def save(k: str, cols: dict, meta: dict) -> None:
    """Store an entry: the columns and ``meta`` into a temporary folder, renamed into place (module docstring)."""
    root = cache_dir()
    tmp = root / f".{k}.tmp-{os.getpid()}"
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp.mkdir(exist_ok=True)
        for c in COLUMNS:
            np.save(tmp / f"{c}.npy", np.ascontiguousarray(cols[c]), allow_pickle=False)
        (tmp / "meta.json").write_text(json.dumps(meta), encoding="utf-8")
        try:
            os.rename(tmp, root / k)
        except OSError:  # another run stored it first (or an unreadable entry is in the way: replace it)
            old = root / f".{k}.old-{os.getpid()}"
            os.rename(root / k, old)
            os.rename(tmp, root / k)
            shutil.rmtree(old, ignore_errors=True)
    except OSError:
        pass
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
