"""A recording in frame-major order, streamed frame by frame (issue 47, item 2).

A :class:`sim.replay.recording.Recording` keeps each person's rows together (person-major): answering "where is
everyone at frame f" then touches every person's rows, all of the recording, every frame. The frame-major form
keeps the rows of one recorded frame together instead, so a frame's answer reads only the slices up to it:

    values  : (J,) float64, the distinct recorded frames, increasing
    offsets : (J + 1,) int64, slice j (the rows recorded at ``values[j]``) is rows ``offsets[j] .. offsets[j + 1]``
    person  : (R,) int32, the row's person (index into the recording's ``ids``), increasing within a slice
    seg     : (R, 5) float64, the row's position and the same person's next row: x, y, next frame, next x, next y
              (the row itself on a person's last row)

A :class:`Cursor` at time ``t`` has applied every slice recorded at or before ``t``: it holds, per person, the
*segment* (last row at or before ``t``, the row after it) that :meth:`Recording.at` would interpolate in, so any
frame between two slices is one linear interpolation per person, with the same arithmetic. Moving forwards applies
only the slices passed since; moving back starts again from the first slice. :class:`Stream` is the three cursors
the replay needs (``t - w``, ``t``, ``t + w``: the position and the smoothed velocity, ``sim.replay.track``).

A table lives in memory (built from a recording's person-major columns, :meth:`FrameTable.from_rows`) or in the
replay cache's ``.npy`` files (:meth:`FrameTable.open`), whose slices are read with plain file reads, never
memory-mapped: the pages a long run reads stay in the page cache, not in the process, so replaying a recording of
any length holds the per-person segments (48 bytes a person and cursor) and one slice at a time.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numba import njit, prange

#: the table's files in a cache entry, by array name
FILES = {"values": "f_values.npy", "offsets": "f_offsets.npy", "person": "f_person.npy", "seg": "f_seg.npy"}
#: columns of ``seg``
SEG_COLUMNS = 5


class FrameTable:
    """The frame-major rows of one recording (module docstring). ``person`` and ``seg`` are arrays (in memory) or,
    for a table opened from files, None with ``files`` = ``{"person": (path, data offset), "seg": (...)}``."""

    def __init__(self, values, offsets, person=None, seg=None, files: dict | None = None):
        self.values = np.asarray(values, np.float64)
        self.offsets = np.asarray(offsets, np.int64)
        self.person = person
        self.seg = seg
        self.files = files
        if (person is None or seg is None) and not files:
            raise ValueError("FrameTable: give the person and seg arrays or their files")

    @property
    def slices(self) -> int:
        return int(self.values.shape[0])

    @property
    def rows(self) -> int:
        return int(self.offsets[-1]) if self.offsets.shape[0] else 0

    @classmethod
    def from_rows(cls, start, frames, xy) -> FrameTable:
        """The table of person-major rows (``Recording``'s ``start``, ``frames``, ``xy``): a stable sort by frame
        keeps each frame's rows in person order."""
        start = np.asarray(start, np.int64)
        frames = np.asarray(frames, np.float64)
        xy = np.asarray(xy, np.float64)
        rows = frames.shape[0]
        nxt = np.arange(1, rows + 1, dtype=np.int64)
        ends = start[1:] - 1
        nxt[ends[ends >= 0]] -= 1  # a person's last row: its own next
        order = np.argsort(frames, kind="stable")
        owner = np.repeat(np.arange(start.shape[0] - 1, dtype=np.int32), np.diff(start))
        person = owner[order]
        del owner
        seg = np.empty((rows, SEG_COLUMNS), np.float64)
        seg[:, 0] = xy[order, 0]
        seg[:, 1] = xy[order, 1]
        nxt = nxt[order]
        seg[:, 2] = frames[nxt]
        seg[:, 3] = xy[nxt, 0]
        seg[:, 4] = xy[nxt, 1]
        fs = frames[order]
        first = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]]) if rows else np.zeros(0, np.int64)
        return cls(fs[first], np.append(first, rows).astype(np.int64), person, seg)

    def slice(self, j: int) -> tuple:
        """``(person (n,) int32, seg (n, 5) float64)`` of slice ``j``; read from the files for an opened table."""
        a, b = int(self.offsets[j]), int(self.offsets[j + 1])
        if self.person is not None:
            return self.person[a:b], self.seg[a:b]
        return (_read(*self.files["person"], np.int32, a, b - a, 1),
                _read(*self.files["seg"], np.float64, a, b - a, SEG_COLUMNS))

    def save(self, folder: Path) -> None:
        """Write the four arrays as ``.npy`` files into ``folder`` (an in-memory table; the cache's temporary
        entry folder, renamed into place by ``sim.replay.cache``)."""
        folder = Path(folder)
        for name in ("values", "offsets", "person", "seg"):
            np.save(folder / FILES[name], np.ascontiguousarray(getattr(self, name)), allow_pickle=False)

    @classmethod
    def open(cls, folder: Path) -> FrameTable | None:
        """The table saved in ``folder``: the slice bounds in memory, the rows left in their files (read a slice
        at a time). None when a file is missing or the shapes disagree."""
        folder = Path(folder)
        try:
            values = np.load(folder / FILES["values"], allow_pickle=False)
            offsets = np.load(folder / FILES["offsets"], allow_pickle=False)
            maps = {n: np.load(folder / FILES[n], mmap_mode="r", allow_pickle=False) for n in ("person", "seg")}
        except (OSError, ValueError):
            return None
        rows = int(offsets[-1]) if offsets.shape[0] else -1
        p, s = maps["person"], maps["seg"]
        if (values.ndim != 1 or offsets.shape != (values.shape[0] + 1,) or p.shape != (rows,)
                or s.shape != (rows, SEG_COLUMNS) or p.dtype != np.int32 or s.dtype != np.float64
                or not isinstance(p, np.memmap) or not isinstance(s, np.memmap)
                or not p.flags.c_contiguous or not s.flags.c_contiguous):
            return None
        if rows and (int(offsets[0]) != 0 or (np.diff(offsets) < 0).any()):
            return None
        files = {"person": (str(folder / FILES["person"]), int(p.offset)),
                 "seg": (str(folder / FILES["seg"]), int(s.offset))}
        del maps, p, s  # (nothing of the maps was read: their pages stay out of the process)
        return cls(values, offsets, files=files)


def _read(path: str, offset: int, dtype, first: int, count: int, cols: int) -> np.ndarray:
    """Rows ``first .. first + count`` of a C-ordered ``.npy`` array of ``cols`` columns whose data starts at byte
    ``offset``: one plain read (module docstring). OSError when the file is shorter than its header says."""
    out = np.empty((count, cols) if cols > 1 else count, dtype)
    if count:
        with open(path, "rb", buffering=0) as f:
            f.seek(offset + first * cols * out.itemsize)
            got = f.readinto(memoryview(out).cast("B"))
        if got != out.nbytes:
            raise OSError(f"{os.path.basename(path)}: truncated (read {got} of {out.nbytes} bytes)")
    return out


class Cursor:
    """Per person, the segment around time ``t`` (module docstring): ``state`` (P, 6) float64 rows (frame, x, y,
    next frame, next x, next y), valid for the persons whose first recorded frame is at or before ``t``."""

    def __init__(self, table: FrameTable, persons: int):
        self.table = table
        self.state = np.zeros((persons, 6), np.float64)
        self.applied = 0  # slices 0 .. applied - 1 are in state

    def seek(self, t: float) -> None:
        """Apply the slices recorded at or before ``t`` (forwards: those since the last seek; back: from the
        first slice again, which leaves each person's last row at or before ``t``)."""
        v = self.table.values
        if self.applied and v[self.applied - 1] > t:
            self.applied = 0
        while self.applied < v.shape[0] and v[self.applied] <= t:
            person, seg = self.table.slice(self.applied)
            _apply(person, seg, float(v[self.applied]), self.state)
            self.applied += 1


class Stream:
    """The three cursors of the replay (module docstring) over ``table``, for a recording whose persons' first and
    last recorded frames are ``first``, ``last`` and whose first rows' positions are ``first_xy`` (P, 2)."""

    def __init__(self, table: FrameTable, first, last, first_xy):
        self.first = np.ascontiguousarray(first, np.float64)
        self.last = np.ascontiguousarray(last, np.float64)
        self.first_xy = np.ascontiguousarray(first_xy, np.float64)
        n = self.first.shape[0]
        self.cursors = [Cursor(table, n) for _ in range(3)]

    def rows(self, persons: np.ndarray, frame: float, w: float, rate: float) -> np.ndarray:
        """(k, 4) float64 (x, y, vx, vy) of ``persons`` at ``frame``: the position linear between the recorded
        frames around it and the velocity over ``frame`` -+ ``w`` frames, each clamped to the person's recorded
        span (``rate``: recorded frames per second)."""
        frame = float(frame)
        for c, t in zip(self.cursors, (frame - w, frame, frame + w)):
            c.seek(t)
        p = np.ascontiguousarray(persons, np.int64)
        out = np.empty((p.shape[0], 4), np.float64)
        if p.shape[0]:
            a, b, c = (cur.state for cur in self.cursors)
            _rows_kernel(p, self.first, self.last, self.first_xy, a, b, c, frame, float(w), float(rate), out)
        return out


@njit(cache=True, parallel=True)
def _apply(person, seg, frame, state):  # pragma: no cover - compiled
    """Slice rows into the persons' segments (:meth:`Cursor.seek`; a slice holds a person once)."""
    for r in prange(person.shape[0]):
        p = person[r]
        state[p, 0] = frame
        state[p, 1] = seg[r, 0]
        state[p, 2] = seg[r, 1]
        state[p, 3] = seg[r, 2]
        state[p, 4] = seg[r, 3]
        state[p, 5] = seg[r, 4]


@njit(cache=True, inline="always")
def _at(state, p, t, lo, hi, first_xy):
    """Person ``p``'s position at ``t`` clamped to ``lo .. hi`` from a cursor at ``t``: linear in its segment
    (``Recording.at``'s arithmetic); before ``lo`` the cursor has no row of it yet: its first position."""
    if t < lo:
        return first_xy[p, 0], first_xy[p, 1]
    q = min(t, hi)
    f0 = state[p, 0]
    df = state[p, 3] - f0
    a = (q - f0) / df if df > 0 else 0.0
    return state[p, 1] * (1.0 - a) + state[p, 4] * a, state[p, 2] * (1.0 - a) + state[p, 5] * a


@njit(cache=True, parallel=True)
def _rows_kernel(persons, first, last, first_xy, sa, s, sb, frame, w, rate, out):  # pragma: no cover - compiled
    """Per person: the position at ``frame`` (cursor ``s``) and the velocity between ``frame`` - ``w`` (``sa``)
    and ``frame`` + ``w`` (``sb``), the span clamped to the person's frames (:meth:`Stream.rows`)."""
    for a in prange(persons.shape[0]):
        p = persons[a]
        lo, hi = first[p], last[p]
        x, y = _at(s, p, frame, lo, hi, first_xy)
        xa, ya = _at(sa, p, frame - w, lo, hi, first_xy)
        xb, yb = _at(sb, p, frame + w, lo, hi, first_xy)
        qa = min(max(frame - w, lo), hi)
        qb = min(max(frame + w, lo), hi)
        span = (qb - qa) / rate
        out[a, 0], out[a, 1] = x, y
        out[a, 2] = (xb - xa) / span if span > 0 else 0.0
        out[a, 3] = (yb - ya) / span if span > 0 else 0.0


__all__ = ["Cursor", "FrameTable", "Stream"]
