"""Per-frame packing of the point drawer (:mod:`render.points.draw`) in numba: the instance rows with each
representation's sample box folded in (:func:`render.points.draw.fold_box`), the colour words of every instance
row (:func:`render.tint.batch_words`) and the job tables with their exclusive prefix
(:func:`render.points.draw.job_table`), written once into preallocated arrays instead of per-batch numpy
temporaries and concatenations (a million far agents: a million rows and a million jobs a frame). Each is
tested equal to the numpy function it stands for (tests/render/test_points_pack.py).

``fold_box`` computes ``m @ lo`` with numpy's matrix product, which on this platform is a fused
multiply-add chain (BLAS); :func:`_dot3` is compiled with contraction so that it rounds the same way, and
a test pins that equivalence.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from render.tint import TINT_WORDS, debug_word, takes_variation


@njit(cache=True, fastmath={"contract"})
def _dot3(a0, a1, a2, b0, b1, b2):  # pragma: no cover - compiled
    """a . b rounded as numpy's ``(k, 3) @ (3,)`` product (a fused multiply-add chain)."""
    return a0 * b0 + a1 * b1 + a2 * b2


@njit(cache=True, parallel=True)
def _fold_kernel(data, lo, scale, out, base, bad):  # pragma: no cover - compiled
    """Rows ``base ..`` of ``out``: :func:`render.points.draw.fold_box` of ``data`` (k, 16); ``bad[0]`` set
    when a folded value is not finite."""
    for k in prange(data.shape[0]):
        r = base + k
        for i in range(3):
            m0 = np.float64(data[k, 4 * i])
            m1 = np.float64(data[k, 4 * i + 1])
            m2 = np.float64(data[k, 4 * i + 2])
            t = np.float64(data[k, 4 * i + 3]) + _dot3(m0, m1, m2, lo[0], lo[1], lo[2])
            out[r, 4 * i] = np.float32(m0 * scale)
            out[r, 4 * i + 1] = np.float32(m1 * scale)
            out[r, 4 * i + 2] = np.float32(m2 * scale)
            out[r, 4 * i + 3] = np.float32(t)
        for c in range(12, 16):
            out[r, c] = np.float32(data[k, c])
        for c in range(16):
            if not np.isfinite(out[r, c]):
                bad[0] = True


def fold_rows(batches, boxes) -> tuple[np.ndarray, bool]:
    """((sum k, 16) float32 instance rows of ``batches`` in order, each folded with its box
    ``boxes[i]`` = (lo, scale); whether every value is finite)."""
    rows = sum(b.n_instances for b in batches)
    out = np.empty((rows, 16), np.float32)
    bad = np.zeros(1, np.bool_)
    at = 0
    for b, (lo, scale) in zip(batches, boxes):
        d = np.asarray(b.instance_data)
        if d.dtype not in (np.float32, np.float64):
            d = d.astype(np.float64)
        d = np.ascontiguousarray(d).reshape(-1, 16)
        _fold_kernel(d, np.asarray(lo, np.float64), float(scale), out, at, bad)
        at += d.shape[0]
    return out, not bool(bad[0])


@njit(cache=True, parallel=True)
def _words_kernel(ids, table, use_table, debug, out, base):  # pragma: no cover - compiled
    n = table.shape[0]
    for k in prange(ids.shape[0]):
        a = ids[k]
        out[base + k, 0] = table[a] if use_table and a >= 0 and a < n else np.uint32(0)
        out[base + k, 1] = debug


def batch_words(batches, table) -> np.ndarray:
    """:func:`render.tint.batch_words` (same words) in numba."""
    rows = sum(b.n_instances for b in batches)
    out = np.empty((rows, TINT_WORDS), np.uint32)
    t = np.zeros(1, np.uint32) if table is None else np.ascontiguousarray(table, np.uint32)
    at = 0
    for b in batches:
        ids = np.asarray(b.instance_ids).reshape(-1)
        if ids.dtype.kind not in "iu":
            ids = ids.astype(np.int64)
        use = table is not None and takes_variation(b.rep)
        _words_kernel(ids, t, use, np.uint32(debug_word(getattr(b, "tint", None))), out, at)
        at += ids.shape[0]
    return out


@njit(cache=True)
def _count_kept(jobs):  # pragma: no cover - compiled
    n = 0
    for q in range(jobs.shape[0]):
        if jobs[q, 2] > 0:
            n += 1
    return n


@njit(cache=True)
def _jobs_kernel(jobs, first, inst, out, at, total):  # pragma: no cover - compiled
    """Append the jobs with points (count > 0) as (first + start, count, inst + row, prefix)."""
    for q in range(jobs.shape[0]):
        c = jobs[q, 2]
        if c <= 0:
            continue
        out[at, 0] = first + jobs[q, 1]
        out[at, 1] = c
        out[at, 2] = inst + jobs[q, 0]
        out[at, 3] = total
        total += c
        at += 1
    return at, total


def job_table(batches, key: str, bases: np.ndarray, which: str, inst_offsets: dict) -> np.ndarray:
    """:func:`render.points.draw.job_table` (same (J, 4) uint32 table) in numba."""
    parts = []
    n = 0
    for b in batches:
        if b.rep != key:
            continue
        j = np.asarray(getattr(b, which), np.int64).reshape(-1, 3)
        if j.shape[0]:
            parts.append((b, np.ascontiguousarray(j)))
            n += _count_kept(parts[-1][1])
    out64 = np.empty((n, 4), np.int64)
    at, total = 0, 0
    for b, j in parts:
        at, total = _jobs_kernel(j, int(bases[b.part]), int(inst_offsets[id(b)]), out64, at, total)
    if n and total >= 2 ** 32:
        raise ValueError(f"points drawer: {total} work items in one frame exceed 2**32")
    return out64.astype(np.uint32)


__all__ = ["batch_words", "fold_rows", "job_table"]
