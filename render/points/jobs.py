"""CPU-side job helpers of the point drawer (``render.points.draw``): the indexed
form of triangle jobs and the per-item expansion of point jobs (GL_POINTS
path); the resolve rectangles live in ``render.screen``. Plain numpy;
moved out of ``render/points/draw.py`` unchanged (that module re-exports them)."""
from __future__ import annotations

import numpy as np

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
