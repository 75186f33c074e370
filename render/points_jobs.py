"""CPU-side job helpers of the point drawer (``render.points``): the indexed
form of triangle jobs, the per-item expansion of point jobs (GL_POINTS path)
and the pixel rectangles the splat resolve draws. Plain numpy; moved out of
``render/points.py`` unchanged (that module re-exports them)."""
from __future__ import annotations

import numpy as np

#: triangle ranges whose (unique vertices, local corners) a rep keeps (render/points.py
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


def resolve_rects(flags: np.ndarray, size, tile: int, margin: int, splat: int) -> np.ndarray:
    """(R, 4) int64 pixel rectangles (x0, y0, x1, y1), half-open, that hold
    every pixel a filled anchor can cover.

    flags : (ty, tx) bool, the anchor-slot tiles the depth pass filled (slot
        (sx, sy) = pixel anchor + margin, tile (sy // tile, sx // tile))
    size : (width, height) pixels; splat : footprint side s (1..3 <= margin + 1)

    Pixel p reads the slots p + margin - d for 0 <= d < s, so a block of
    tile x tile pixels is needed when a flagged tile meets its slot range; the
    blocks of a row are merged into runs (few, wide rectangles).
    """
    w, h = int(size[0]), int(size[1])
    f = np.asarray(flags, bool)
    ty, tx = f.shape
    s = int(splat)
    # summed-area table of the flags: any flag in a tile range in O(1)
    sat = np.zeros((ty + 1, tx + 1), np.int64)
    sat[1:, 1:] = f.astype(np.int64).cumsum(0).cumsum(1)

    def ranges(n_px, n_tiles):
        p0 = np.arange(0, n_px, tile)
        p1 = np.minimum(p0 + tile, n_px)
        lo = np.clip((p0 + margin - s + 1) // tile, 0, n_tiles - 1)
        hi = np.clip((p1 - 1 + margin) // tile, 0, n_tiles - 1)
        return p0, p1, lo, hi + 1

    x0, x1, lx, hx = ranges(w, tx)
    y0, y1, ly, hy = ranges(h, ty)
    cnt = sat[np.ix_(hy, hx)] - sat[np.ix_(ly, hx)] - sat[np.ix_(hy, lx)] + sat[np.ix_(ly, lx)]
    need = cnt > 0  # (pixel tile rows, pixel tile columns)
    pad = np.zeros((need.shape[0], need.shape[1] + 2), np.int8)
    pad[:, 1:-1] = need
    d = np.diff(pad, axis=1)
    rows, starts = np.nonzero(d == 1)
    _, ends = np.nonzero(d == -1)  # same row order: each run's start then end
    if not rows.shape[0]:
        return np.zeros((0, 4), np.int64)
    return np.stack([x0[starts], y0[rows], x1[ends - 1], y1[rows]], axis=1).astype(np.int64)


def rect_vertices(rects: np.ndarray, size) -> np.ndarray:
    """(6 R, 2) float32 NDC corners of two triangles per pixel rectangle."""
    r = np.asarray(rects, np.float64).reshape(-1, 4)
    w, h = float(size[0]), float(size[1])
    xa, ya, xb, yb = (2.0 * r[:, 0] / w - 1.0, 2.0 * r[:, 1] / h - 1.0, 2.0 * r[:, 2] / w - 1.0,
                      2.0 * r[:, 3] / h - 1.0)
    v = np.stack([np.stack([xa, ya], 1), np.stack([xb, ya], 1), np.stack([xa, yb], 1),
                  np.stack([xb, yb], 1), np.stack([xa, yb], 1), np.stack([xb, ya], 1)], axis=1)
    return v.reshape(-1, 2).astype(np.float32)
