"""CPU-side job helpers of the point drawer (``render.points.draw``): the indexed
form of triangle jobs, the per-item expansion of point jobs (GL_POINTS
path) and the job tables of the points that follow the animation
(:func:`posed_job_table`, numba: at a million agents its numpy form took
140 ms a call, twice a frame); the resolve rectangles live in ``render.screen``."""
from __future__ import annotations

import numpy as np
from numba import njit

#: triangle ranges whose (unique vertices, local corners) a rep keeps (render/points/draw.py
#: indexed_triangle_jobs); past it the cache is emptied (ranges are octree nodes: a few thousand)
TRI_RANGE_CACHE = 200_000


def indexed_triangle_jobs(jobs: np.ndarray, corners: np.ndarray, cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """Indexed form of triangle jobs (first triangle, count, instance, prefix).

    Returns (items (V, 2) uint32 (vertex, instance) — each vertex a job's
    triangles use once, in job order — and index (3 T,) uint32 into items,
    the triangles in job order). ``corners`` (T_all, 3) are the rep's
    triangles' global vertex indices; ``cache`` maps a (first, count) range
    to its unique vertices and local corner indices (filled here)."""
    j = np.asarray(jobs, np.int64).reshape(-1, 4)
    if not j.shape[0]:
        return np.zeros((0, 2), np.uint32), np.zeros(0, np.uint32)
    keys = (j[:, 0] << 32) | j[:, 1]
    uk, inv = np.unique(keys, return_inverse=True)
    if len(cache) > TRI_RANGE_CACHE:
        cache.clear()
    verts, local = [], []
    for k in uk.tolist():
        e = cache.get(k)
        if e is None:
            f, c = k >> 32, k & 0xFFFFFFFF
            u, li = np.unique(corners[f:f + c].reshape(-1), return_inverse=True)
            e = cache[k] = (u.astype(np.uint32), li.astype(np.uint32))
        verts.append(e[0])
        local.append(e[1])
    nv = np.array([v.shape[0] for v in verts], np.int64)
    ni = np.array([v.shape[0] for v in local], np.int64)
    pv = np.concatenate(verts)
    pi = np.concatenate(local)
    ov = np.zeros(nv.shape[0], np.int64)
    np.cumsum(nv[:-1], out=ov[1:])
    oi = np.zeros(ni.shape[0], np.int64)
    np.cumsum(ni[:-1], out=oi[1:])

    def gather(off, n):  # the concatenated ranges [off[k], off[k] + n[k]) of every job
        nj = n[inv]
        tot = int(nj.sum())
        start = np.zeros(nj.shape[0], np.int64)
        np.cumsum(nj[:-1], out=start[1:])
        return np.repeat(off[inv] - start, nj) + np.arange(tot), nj, start

    gv, njv, vbase = gather(ov, nv)
    items = np.empty((gv.shape[0], 2), np.uint32)
    items[:, 0] = pv[gv]
    items[:, 1] = np.repeat(j[:, 2], njv)
    gi, nji, _ = gather(oi, ni)
    index = (pi[gi].astype(np.int64) + np.repeat(vbase, nji)).astype(np.uint32)
    return items, index


def expand_jobs(jobs: np.ndarray) -> np.ndarray:
    """(total, 2) uint32 (sample, instance) per work item of a job table
    (the GL_POINTS path draws one vertex per item)."""
    counts = jobs[:, 1].astype(np.int64)
    total = int(counts.sum())
    out = np.empty((total, 2), np.uint32)
    rep_start = np.repeat(jobs[:, 0].astype(np.int64) - jobs[:, 3].astype(np.int64), counts)
    out[:, 0] = rep_start + np.arange(total)
    out[:, 1] = np.repeat(jobs[:, 2], counts)
    return out


@njit(cache=True)
def _fill_posed_jobs(jobs, slot, pose_base, add_base, row0, out, n):  # pragma: no cover - numba
    """Append to ``out`` from row ``n`` the jobs (instance, first, count) of ``jobs`` with a count > 0 whose
    instance's pose (``slot``) is placed this round (``pose_base`` >= 0): (first, plus the pose's base when
    ``add_base``; count; ``row0`` + instance). Returns the rows written so far."""
    for i in range(jobs.shape[0]):
        c = jobs[i, 2]
        if c <= 0:
            continue
        b = pose_base[slot[jobs[i, 0]]]
        if b < 0:
            continue
        out[n, 0] = jobs[i, 1] + (b if add_base else 0)
        out[n, 1] = c
        out[n, 2] = row0 + jobs[i, 0]
        n += 1
    return n


@njit(cache=True)
def _exclusive_prefix(out, n):  # pragma: no cover - numba
    s = 0
    for i in range(n):
        out[i, 3] = s
        s += out[i, 1]
    return s


def posed_job_table(items, add_base: bool) -> np.ndarray:
    """(J, 4) uint32 jobs (first, count, instance row, exclusive prefix of the counts) of the points that follow
    the animation (``render.points.follow.FollowFrame``): ``items`` = [(jobs (k, 3) ints (instance, first,
    count), slot (n,) int64 pose of each instance, pose_base (P,) int64 first placed item of each pose this round,
    -1 when not placed, row0: the batch's first instance row)], in order. A job with count 0, or whose pose is not
    placed this round, is left out; ``add_base``: the first item is the pose's base plus the job's first (point
    jobs), else the job's first (triangle jobs). One pass per batch, no temporaries (numba)."""
    items = [(np.ascontiguousarray(np.asarray(j).reshape(-1, 3)), np.asarray(sl, np.int64), np.asarray(pb, np.int64),
              int(r0)) for j, sl, pb, r0 in items]
    total = sum(j.shape[0] for j, _, _, _ in items)
    out = np.empty((total, 4), np.int64)
    n = 0
    for j, sl, pb, r0 in items:
        if j.shape[0]:
            n = _fill_posed_jobs(j, sl, pb, bool(add_base), r0, out, n)
    if n == 0:
        return np.zeros((0, 4), np.uint32)
    if _exclusive_prefix(out, n) >= 2 ** 32:
        raise ValueError("points drawer: more than 2**32 work items in one frame")
    return out[:n].astype(np.uint32)
