"""Content-addressed columnar cache of recordings (``$CROWD_CACHE_DIR/replay``, default ``~/.cache/crowd/replay``;
issue 47, item 2 in part).

A recording is read through PedPy once: its sorted columns (:class:`sim.replay.recording.Recording`: person ids,
row starts, frames, positions, the search keys of :meth:`Recording.at` and each person's first and last rows) and
its frame-major form (:mod:`sim.replay.frames`) are stored as ``.npy`` files in a folder named by the SHA-256 of the
file's bytes and of how it was read (format, unit, frame rate, :data:`FORMAT`). The folder is written under a
temporary name and renamed into place, so a reader sees a whole entry or none. Later runs memory-map the
person-major columns (``numpy.load(mmap_mode="r")``: only the pages a question touches are read) and stream the
frame-major rows a slice at a time (plain reads: the replay of a long recording holds one slice, not the file).
An entry that cannot be read (a missing column, shapes that disagree) is ignored and written again; a cache that
cannot be written is skipped (the recording stays in memory). The first parse holds the whole recording in memory
(PedPy reads it into one table); replays after it do not.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

from sim.replay.frames import FrameTable

CACHE_ENV = "CROWD_CACHE_DIR"
#: bump when what an entry holds changes
FORMAT = 3
#: the person-major columns of an entry (the frame-major files: ``sim.replay.frames.FILES``)
COLUMNS = ("ids", "start", "frames", "xy", "keys", "ends")
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
    """``(columns dict, meta dict, frame table)`` of entry ``k``: the columns memory-mapped, the table's rows left
    in their files (``FrameTable.open``); None when there is no whole entry."""
    folder = cache_dir() / k
    try:
        meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
        cols = {c: np.load(folder / f"{c}.npy", mmap_mode="r", allow_pickle=False) for c in COLUMNS}
    except (OSError, ValueError, json.JSONDecodeError):
        return None
    rows, persons = cols["frames"].shape[0], cols["ids"].shape[0]
    if (cols["xy"].shape != (rows, 2) or cols["keys"].shape != (rows,) or cols["start"].shape != (persons + 1,)
            or cols["ends"].shape != (6, persons) or not isinstance(meta, dict) or "frame_rate" not in meta):
        return None
    table = FrameTable.open(folder)
    if table is None or table.rows != rows:
        return None
    return cols, meta, table


def save(k: str, rec) -> None:
    """Store recording ``rec``'s entry (its columns, its frame-major table, what it is) into a temporary folder,
    renamed into place (module docstring)."""
    root = cache_dir()
    tmp = root / f".{k}.tmp-{os.getpid()}"
    meta = {"frame_rate": rec.frame_rate, "format": rec.format, "source": Path(rec.source).name, "rows": rec.rows}
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp.mkdir(exist_ok=True)
        for c in COLUMNS:
            np.save(tmp / f"{c}.npy", np.ascontiguousarray(getattr(rec, c)), allow_pickle=False)
        rec.frame_table().save(tmp)
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
