"""Triangle order for llvmpipe's vertex cache: fewer vertex shader runs per drawn instance.

Mesa's draw module (``draw_pt_vsplit.c``, Mesa 22.3) splits an indexed draw into segments of at most 1,024
indices and, inside a segment, reuses a vertex's shaded result through a direct-mapped table of 256 entries keyed
by ``index % 256``; each new segment starts with an empty table. A mesh whose triangles come in long strips
(the procedural tubes go ring after ring around a body part) shades most vertices two or three times per
instance (2.4x the distinct vertices on the 60 K-triangle humanoid), and on llvmpipe the vertex work is most of
a heavy crowd's frame once back faces are culled (scripts/bench_full_detail.md).

:func:`vertex_cache_order` sorts the triangles along a Morton (Z-order) curve of their centroids, so a segment
covers a compact patch whose vertices it shares, and keeps whichever of that order and the original shades
fewer vertices by the cache model (:func:`vsplit_shaded`, numba; :func:`vsplit_shaded_reference`, plain
Python). Only the order of whole triangles changes (each keeps its winding and vertices): the image is the same
up to which of two triangles at exactly equal depth is drawn first. The same order helps any GPU's post-transform
cache (Morton order is a classic cheap approximation of cache-aware orders such as Forsyth's or Tom F.'s).
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: indices per segment of llvmpipe's vertex splitter and entries of its reuse table (draw_pt_vsplit.c)
VSPLIT_SEGMENT = 1024
VSPLIT_MAP = 256


@njit(cache=True)
def _vsplit_shaded(idx, segment, mapsize):
    table = np.full(mapsize, -1, np.int64)
    shaded = 0
    per = segment - segment % 3
    for s in range(0, idx.shape[0], per):
        table[:] = -1
        for i in range(s, min(s + per, idx.shape[0])):
            v = idx[i]
            h = v % mapsize
            if table[h] != v:
                table[h] = v
                shaded += 1
    return shaded


def vsplit_shaded(indices, segment: int = VSPLIT_SEGMENT, mapsize: int = VSPLIT_MAP) -> int:
    """Vertex shader runs llvmpipe's splitter makes for one instance of an indexed triangle list."""
    idx = np.ascontiguousarray(np.asarray(indices).ravel(), np.int64)
    return int(_vsplit_shaded(idx, int(segment), int(mapsize))) if idx.size else 0


def vsplit_shaded_reference(indices, segment: int = VSPLIT_SEGMENT, mapsize: int = VSPLIT_MAP) -> int:
    """Plain-Python reference of :func:`vsplit_shaded`."""
    idx = [int(v) for v in np.asarray(indices).ravel()]
    per = segment - segment % 3
    shaded = 0
    for s in range(0, len(idx), per):
        table = {}
        for v in idx[s:s + per]:
            if table.get(v % mapsize) != v:
                table[v % mapsize] = v
                shaded += 1
    return shaded


def _spread_bits(x: np.ndarray) -> np.ndarray:
    """10-bit integers with two zero bits after every bit (the Morton code of one axis)."""
    x = x.astype(np.uint64) & np.uint64(0x3FF)
    for shift, mask in ((16, 0x30000FF), (8, 0x300F00F), (4, 0x30C30C3), (2, 0x9249249)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def morton_order(positions, triangles) -> np.ndarray:
    """(T,) int64 permutation of the triangles along a Morton curve of their centroids (stable)."""
    tri = np.asarray(triangles, np.int64).reshape(-1, 3)
    if tri.shape[0] == 0:
        return np.zeros(0, np.int64)
    c = np.asarray(positions, np.float64)[tri].mean(axis=1)
    lo, hi = c.min(axis=0), c.max(axis=0)
    q = np.clip(((c - lo) / np.maximum(hi - lo, 1e-300) * 1023.0), 0, 1023).astype(np.int64)
    code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << np.uint64(1)) | (_spread_bits(q[:, 2]) << np.uint64(2))
    return np.argsort(code, kind="stable")


def vertex_cache_order(positions, indices) -> np.ndarray:
    """(T, 3) triangles of ``indices`` in the order that shades fewer vertices: Morton, or the original."""
    tri = np.asarray(indices).reshape(-1, 3)
    if tri.shape[0] < 2 or not np.all(np.isfinite(np.asarray(positions, np.float64))):
        return tri
    cand = tri[morton_order(positions, tri)]
    return cand if vsplit_shaded(cand) < vsplit_shaded(tri) else tri
