"""Per-frame CPU helpers of the points drawer (``render/points.py``, which re-exports them):
the windows that keep every storage-buffer binding within the GL limit, and the resolve
rectangles of the filled anchor tiles.

Storage-buffer limit: a GL implementation may refuse to address more than
``GL_MAX_SHADER_STORAGE_BLOCK_SIZE`` bytes through one binding (llvmpipe: 128 MB, i.e. the
instance data of 2 M instances, the job table of 8 M jobs, 16 M triangle-vertex items). A
frame above it is drawn in windows (:func:`instance_windows`): the jobs whose instances lie in
one range of instance rows, that range bound at its offset and the jobs' instance indices made
relative to it, at most ``max_jobs`` jobs a piece. The splat passes' atomics do not depend on
the order or grouping of the points, so a windowed frame has the same pixels (tested with a
small injected limit).
"""
from __future__ import annotations

import numpy as np


def instance_windows(jobs: np.ndarray, rows: int, window: int, max_jobs: int) -> list:
    """Cut a job table (J, >=3: column 2 the instance row, in ``0 .. rows - 1``) into pieces.

    Returns a list of (first row, piece): each piece holds the jobs of instance rows
    ``first .. first + window - 1`` (at most ``max_jobs``, in table order), their column 2 made
    relative to ``first``. One window (the table itself, first row 0) when ``rows <= window``
    and ``J <= max_jobs``.
    """
    j = np.asarray(jobs)
    window, max_jobs = max(1, int(window)), max(1, int(max_jobs))
    if rows <= window and j.shape[0] <= max_jobs:
        return [(0, j)] if j.shape[0] else []
    out = []
    w = j[:, 2].astype(np.int64) // window
    order = np.argsort(w, kind="stable")
    cuts = np.flatnonzero(np.diff(w[order])) + 1
    for part in np.split(order, cuts):
        if not part.shape[0]:
            continue
        first = int(w[part[0]]) * window
        piece = j[part].copy()
        piece[:, 2] -= first
        for a in range(0, piece.shape[0], max_jobs):
            out.append((first, piece[a:a + max_jobs]))
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
