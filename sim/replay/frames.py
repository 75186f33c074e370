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
any length holds the per-person segments (48 bytes a person and cursor) and the slices between the slowest and the
fastest cursor (read once for the three, up to :data:`KEEP_BYTES`). The next slice is read ahead a share per frame
over the frames before the leading cursor needs it, so no frame pays a whole slice's read (a million people at
1 fps: 44 MB a slice, 1.5 MB a frame at 30 fps); the buffers of a dropped slice are read into again.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numba import njit, prange

from sim.params import ParamError

#: the table's files in a cache entry, by array name
FILES = {"values": "f_values.npy", "offsets": "f_offsets.npy", "person": "f_person.npy", "seg": "f_seg.npy"}
#: columns of ``seg``
SEG_COLUMNS = 5
#: bytes of a row of a slice (person int32, seg float64 x 5)
ROW_BYTES = 4 + 8 * SEG_COLUMNS
#: bytes of read slices a file-backed table keeps: those between the slowest and the fastest cursor (each slice
#: read once for the three) and the next one, read ahead; a slice beyond it is read, used and dropped
KEEP_BYTES = 128 << 20
#: fewest rows read ahead at a time
AHEAD_MIN_ROWS = 1 << 15


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
        self._kept: dict = {}  # slice -> (person, seg, buffers) read (a file-backed table; KEEP_BYTES)
        self._ahead = None  # [slice, person buffer, seg buffer, rows read] of the slice being read ahead
        self._spare = None  # the buffers of a dropped slice, read into again (no fresh pages to fault in)

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
        """``(person (n,) int32, seg (n, 5) float64)`` of slice ``j``; an opened table's from the slices it keeps,
        the one read ahead (its rest read now) or its files (kept while :data:`KEEP_BYTES` allows)."""
        a, b = int(self.offsets[j]), int(self.offsets[j + 1])
        if self.person is not None:
            return self.person[a:b], self.seg[a:b]
        got = self._kept.get(j)
        if got is None:
            if self._ahead is not None and self._ahead[0] == j:
                self.read_ahead(j, 1.0)
                bufs = (self._ahead[1], self._ahead[2])
                self._ahead = None
            else:
                bufs = self._buffers(b - a)
                self._read_rows(j, 0, b - a, bufs)
            got = (bufs[0][:b - a], bufs[1][:b - a], bufs)
            if self._kept_bytes() + self._bytes(j) <= KEEP_BYTES:
                self._kept[j] = got
        return got[0], got[1]

    def _bytes(self, j: int) -> int:
        return int(self.offsets[j + 1] - self.offsets[j]) * ROW_BYTES

    def _kept_bytes(self) -> int:
        return sum(self._bytes(j) for j in self._kept) + (0 if self._ahead is None else self._bytes(self._ahead[0]))

    def _buffers(self, n: int) -> tuple:
        """A (person, seg) buffer pair of at least ``n`` rows: the spare one when it is large enough."""
        if self._spare is not None and self._spare[0].shape[0] >= n:
            got, self._spare = self._spare, None
            return got
        return np.empty(n, np.int32), np.empty((n, SEG_COLUMNS), np.float64)

    def _read_rows(self, j: int, first: int, count: int, bufs: tuple) -> None:
        """Rows ``first .. first + count`` of slice ``j`` read into the same rows of ``bufs``."""
        a = int(self.offsets[j]) + first
        try:
            _read(*self.files["person"], a, bufs[0][first:first + count])
            _read(*self.files["seg"], a, bufs[1][first:first + count])
        except OSError as e:  # the entry changed under the run (checked whole when opened)
            raise ParamError("file", f"the replay cache entry {Path(self.files['seg'][0]).parent} cannot be read "
                                     f"({e}); delete it and run again") from None

    def read_ahead(self, j: int, share: float) -> None:
        """An opened table: read ``share`` (0 .. 1) of slice ``j``'s rows not read yet (at least
        :data:`AHEAD_MIN_ROWS`), so a slice arrives over the frames before a cursor needs it, not in one frame;
        nothing when ``j`` is kept, out of range, or would pass :data:`KEEP_BYTES`."""
        if self.person is not None or not 0 <= j < self.slices or j in self._kept:
            return
        n = int(self.offsets[j + 1] - self.offsets[j])
        if self._ahead is None or self._ahead[0] != j:
            self._ahead = None  # (a seek back may have left another slice half read: dropped)
            if self._kept_bytes() + self._bytes(j) > KEEP_BYTES:
                return
            self._ahead = [j, *self._buffers(n), 0]
        done = self._ahead[3]
        count = n - done if share >= 1.0 else min(n - done, max(AHEAD_MIN_ROWS, int(np.ceil(share * n))))
        if count > 0:
            self._read_rows(j, done, count, (self._ahead[1], self._ahead[2]))
            self._ahead[3] = done + count

    def release(self, first: int) -> None:
        """An opened table: drop the kept slices before ``first`` (no cursor needs them again); one's buffers are
        kept for the next read."""
        for j in [j for j in self._kept if j < first]:
            bufs = self._kept.pop(j)[2]
            if self._spare is None or self._spare[0].shape[0] < bufs[0].shape[0]:
                self._spare = bufs

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
        if rows and (int(offsets[0]) != 0 or (np.diff(offsets) < 0).any() or (np.diff(values) <= 0).any()):
            return None
        files = {"person": (str(folder / FILES["person"]), int(p.offset)),
                 "seg": (str(folder / FILES["seg"]), int(s.offset))}
        del maps, p, s  # (nothing of the maps was read: their pages stay out of the process)
        return cls(values, offsets, files=files)


def _read(path: str, offset: int, first: int, out: np.ndarray) -> None:
    """Rows ``first ..`` of a C-ordered ``.npy`` array whose data starts at byte ``offset`` into ``out`` (as many
    rows as it holds, of the same row length): one plain read (module docstring). OSError when the file is shorter
    than its header says."""
    if not out.shape[0]:
        return
    row = out.nbytes // out.shape[0]
    with open(path, "rb", buffering=0) as f:
        f.seek(offset + first * row)
        got = f.readinto(memoryview(out).cast("B"))
    if got != out.nbytes:
        raise OSError(f"{os.path.basename(path)}: truncated (read {got} of {out.nbytes} bytes)")


class Cursor:
    """Per person, the segment around time ``t`` (module docstring): ``state`` (P, 6) float64 rows (frame, x, y,
    next frame, next x, next y), valid for the persons whose first recorded frame is at or before ``t``."""

    def __init__(self, table: FrameTable, persons: int):
        self.table = table
        self.state = np.full((persons, 6), 0.0)  # (written now: its pages are not faulted in mid-replay)
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
        self.first_xy = np.asarray(first_xy, np.float64)  # (a view of the recording's ends: not copied)
        n = self.first.shape[0]
        self.cursors = [Cursor(table, n) for _ in range(3)]
        self._lead = None  # the leading cursor's time at the last seek (how fast the stream moves)

    def seek(self, frame: float, w: float) -> tuple:
        """Move the cursors to ``frame - w``, ``frame``, ``frame + w`` and return what :func:`kinematics` reads:
        ``(first, last, first_xy, state at frame - w, at frame, at frame + w)``."""
        frame = float(frame)
        for c, t in zip(self.cursors, (frame - w, frame, frame + w)):
            c.seek(t)
        self._read_ahead(frame + w)
        return (self.first, self.last, self.first_xy) + tuple(c.state for c in self.cursors)

    def _read_ahead(self, lead: float) -> None:
        """Drop the slices every cursor has passed and read a share of the next one the leading cursor (at
        ``lead``) will need: one over the frames left until it does, at the pace of the last seek."""
        table = self.cursors[0].table
        table.release(min(c.applied for c in self.cursors))
        j = max(c.applied for c in self.cursors)
        if j < table.slices:
            step = lead - self._lead if self._lead is not None and lead > self._lead else 0.0
            left = (table.values[j] - lead) / step if step > 0 else 1.0
            table.read_ahead(j, 1.0 / max(left, 1.0))
        self._lead = lead

    def rows(self, persons: np.ndarray, frame: float, w: float, rate: float) -> np.ndarray:
        """(k, 4) float64 (x, y, vx, vy) of ``persons`` at ``frame``: the position linear between the recorded
        frames around it and the velocity over ``frame`` -+ ``w`` frames, each clamped to the person's recorded
        span (``rate``: recorded frames per second; :func:`kinematics`)."""
        arrays = self.seek(frame, w)
        p = np.ascontiguousarray(persons, np.int64)
        out = np.empty((p.shape[0], 4), np.float64)
        if p.shape[0]:
            _rows_kernel(p, *arrays, float(frame), float(w), float(rate), out)
        return out


@njit(cache=True, parallel=True)
def _apply(person, seg, frame, state):  # pragma: no cover - compiled
    """Slice rows into the persons' segments (:meth:`Cursor.seek`; a slice holds a person once; a row naming no
    person of ``state``, from a damaged file, is skipped)."""
    for r in prange(person.shape[0]):
        p = person[r]
        if p < 0 or p >= state.shape[0]:
            continue
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


@njit(cache=True, inline="always")
def kinematics(p, first, last, first_xy, sa, s, sb, frame, w, rate):  # pragma: no cover - compiled
    """``(x, y, vx, vy)`` of person ``p``: the position at ``frame`` (cursor ``s``) and the velocity between
    ``frame`` - ``w`` (``sa``) and ``frame`` + ``w`` (``sb``), the span clamped to the person's frames; the arrays
    are :meth:`Stream.seek`'s (for kernels that place agents as they read, ``sim.replay.effect``)."""
    lo, hi = first[p], last[p]
    x, y = _at(s, p, frame, lo, hi, first_xy)
    xa, ya = _at(sa, p, frame - w, lo, hi, first_xy)
    xb, yb = _at(sb, p, frame + w, lo, hi, first_xy)
    qa = min(max(frame - w, lo), hi)
    qb = min(max(frame + w, lo), hi)
    span = (qb - qa) / rate
    if span > 0:
        return x, y, (xb - xa) / span, (yb - ya) / span
    return x, y, 0.0, 0.0


@njit(cache=True, parallel=True)
def _rows_kernel(persons, first, last, first_xy, sa, s, sb, frame, w, rate, out):  # pragma: no cover - compiled
    """:func:`kinematics` of every person of ``persons`` into ``out`` rows (:meth:`Stream.rows`)."""
    for a in prange(persons.shape[0]):
        out[a, 0], out[a, 1], out[a, 2], out[a, 3] = kinematics(persons[a], first, last, first_xy, sa, s, sb,
                                                                frame, w, rate)


__all__ = ["Cursor", "FrameTable", "Stream", "kinematics"]
