"""Multi-pose quadric error simplification (VDR-AM §4.3 after DeCoro & Rusinkiewicz).

Garland & Heckbert's quadric error metric drives greedy edge collapses; for an
articulated model the quadrics come from several poses (DeCoro & Rusinkiewicz,
*Pose-independent simplification of articulated meshes*, I3D 2005), so a
collapse is cheap only if it is cheap in every pose. VDR-AM §4.3 uses this with
the representative poses of §4.1 to halve every cluster of its hierarchy.

Design (reusable by triangle LOD chains as well as cluster hierarchies):

- Subset placement: an edge (u, v) collapses onto one of its endpoints. The
  surviving vertex keeps its skin weights, so a simplified mesh indexes the
  original vertex buffer and skins exactly like it (no new vertices, no weight
  fitting). The candidate's position in every pose is known, which is why we
  keep one quadric per pose and per vertex, (P, V, 10), and evaluate each in
  its own pose. Departure from DR05, which transforms every pose's quadric into
  the rest pose through the vertex's blended skinning matrix and sums them into
  one 4x4: that is exact only where neighbouring vertices share a transform;
  ours is exact for subset placement, at P times the memory (P is the handful of
  representative poses). The "accumulated in the rest pose" view is the same
  sum: cost(u->v) = sum_p (Q_u^p + Q_v^p)(x_v^p).
- Quadrics are unweighted plane quadrics, so a quadric value is a sum of
  squared distances (m^2) and sqrt(max over collapses of the worst pose's value)
  is the §5.1 Hausdorff estimate returned as ``error``.
- Locked vertices never move (they may absorb others). Vertices on open or
  non-manifold edges are locked automatically. With the link condition checked
  before each collapse, every edge between two locked vertices that borders the
  region survives unchanged, which is what keeps a cluster cut crack-free.
- A collapse that turns a triangle normal by more than 90 degrees in any pose,
  or makes it degenerate, is refused.

:func:`plane_quadrics_numpy` is the numpy reference of the compiled quadric
accumulation; the collapse loop itself is checked by behaviour tests (locked
vertices fixed, closed meshes stay closed, planar meshes simplify at zero error).
"""
from __future__ import annotations

import numpy as np

from lod.simplify.kernels import _simplify_kernel
from lod.simplify.quadrics import plane_quadrics, quadric_eval_numpy

#: a collapse is refused when a triangle normal turns by more than 90 degrees
#: (its cosine drops below this) in any pose
FLIP_DOT = 0.0


def simplify_reference(positions_per_pose: np.ndarray, indices: np.ndarray, target_triangles: int,
                       locked_vertices: np.ndarray, quadrics: np.ndarray, flip_dot: float = FLIP_DOT):
    """Plain-Python reference of the compiled collapse loop (``_simplify_kernel``).

    Same algorithm (lazy-deletion heap of directed collapses, link condition,
    normal-flip test in every pose, quadrics summed onto the survivor) written
    with ``heapq``, sets and numpy, for small meshes in tests. ``locked_vertices``
    must already include the open-edge vertices and ``quadrics`` (P, V, 10) is
    updated in place. Returns (alive (T,) bool, remap (V,) int64, max error², live).
    With distinct collapse costs it makes the same choices as the kernel.
    """
    import heapq

    X = np.asarray(positions_per_pose, np.float64)
    tris = np.array(indices, np.int64).reshape(-1, 3)
    lock = np.asarray(locked_vertices, bool)
    Q = quadrics
    V, m = X.shape[1], tris.shape[0]
    inc = [set() for _ in range(V)]
    for f in range(m):
        for v in tris[f]:
            inc[v].add(f)
    alive_t = np.ones(m, bool)
    alive_v = np.ones(V, bool)
    remap = np.arange(V)
    ver = np.zeros(V, np.int64)
    live = m

    def qe(u, v):  # per-pose (Q_u + Q_v)(x_v)
        return np.maximum(quadric_eval_numpy(Q[:, u] + Q[:, v], X[:, v]), 0.0)

    heap: list = []

    def push(a, b):
        best, fa = np.inf, -1
        if not lock[a]:
            best, fa = float(qe(a, b).sum()), a
        if not lock[b]:
            c = float(qe(b, a).sum())
            if c < best:
                best, fa = c, b
        if fa >= 0:
            fb = b if fa == a else a
            heapq.heappush(heap, (best, fa, fb, int(ver[fa]), int(ver[fb])))

    def normal(p, a, b, c):
        return np.cross(X[p, b] - X[p, a], X[p, c] - X[p, a])

    for f in range(m):
        for k in range(3):
            a, b = int(tris[f, k]), int(tris[f, (k + 1) % 3])
            if a != b:
                push(a, b)
    maxerr = 0.0
    while live > target_triangles and heap:
        _c, u, v, su, sv = heapq.heappop(heap)
        if not alive_v[u] or not alive_v[v] or ver[u] != su or ver[v] != sv:
            continue
        tu = [f for f in inc[u] if alive_t[f]]
        shared = [f for f in tu if v in tris[f]]
        nv = {int(w) for f in inc[v] if alive_t[f] for w in tris[f]}
        nu = {int(w) for f in tu for w in tris[f]} - {u, v}
        ok = len(shared) > 0 and len(nu & nv) == len(shared)
        for f in tu:
            if not ok:
                break
            if v in tris[f]:
                continue
            new = [v if w == u else int(w) for w in tris[f]]
            for p in range(X.shape[0]):
                n0, n1 = normal(p, *tris[f]), normal(p, *new)
                l0, l1 = np.linalg.norm(n0), np.linalg.norm(n1)
                if not l1 > 0.0 or (l0 > 0.0 and float(n0 @ n1) <= flip_dot * l0 * l1):
                    ok = False
                    break
        if not ok:
            continue
        for f in tu:
            if v in tris[f]:
                alive_t[f] = False
                live -= 1
            else:
                tris[f][tris[f] == u] = v
        inc[v] |= inc[u]
        inc[u] = set()
        Q[:, v] += Q[:, u]
        alive_v[u] = False
        remap[u] = v
        ver[v] += 1
        maxerr = max(maxerr, float((np.maximum(quadric_eval_numpy(2.0 * Q[:, v], X[:, v]), 0.0) * 0.5).max()))
        for w in sorted({int(w) for f in inc[v] if alive_t[f] for w in tris[f]} - {v}):
            push(v, w)
    for i in range(V):
        r = i
        while remap[r] != r:
            r = remap[r]
        remap[i] = r
    return alive_t, remap, maxerr, live


def drawable_triangles(indices: np.ndarray) -> np.ndarray:
    """(T', 3) int64: the triangles of ``indices`` (T, 3) without a repeated vertex index.

    A triangle such as (u, u, v) has zero area in every pose, so it covers no pixel and holds no surface;
    :func:`simplify` drops such triangles from its output, and a vertex used only by them has no collapse
    target. Whoever tracks where every vertex of its input went (the cluster hierarchy's collapse tracking,
    :mod:`lod.clusters.dag`) must start from these triangles. Zero-area triangles on distinct (coincident or
    collinear) vertices stay: they are real topology (they link vertices) and a collapse may remove them.
    """
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    return t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 2] != t[:, 0])]


def open_edge_vertices(indices: np.ndarray, n_vertices: int) -> np.ndarray:
    """(V,) bool: vertices on an edge used by one triangle or by more than two."""
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    out = np.zeros(int(n_vertices), bool)
    if t.shape[0] == 0:
        return out
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    e.sort(axis=1)
    u, cnt = np.unique(e, axis=0, return_counts=True)
    bad = u[cnt != 2]
    out[bad.reshape(-1)] = True
    return out


def simplify(positions_per_pose: np.ndarray, indices: np.ndarray, target_triangles: int,
             locked_vertices: np.ndarray | None = None, quadrics: np.ndarray | None = None,
             flip_dot: float = FLIP_DOT):
    """Simplify a mesh with multi-pose quadric error edge collapses.

    Parameters
    ----------
    positions_per_pose : (P, V, 3) float (or (V, 3) for one pose), the mesh in
        each pose whose error counts (VDR-AM: the representative poses).
    indices : (T, 3) int triangles into the V vertices
    target_triangles : int >= 0; collapses stop at or below it, or earlier when
        no valid collapse is left (locked borders, tiny closed parts).
    locked_vertices : (V,) bool or None; True vertices never move. Vertices on
        open or non-manifold edges are locked in addition.
    quadrics : (P, V, 10) float64 or None; initial quadrics, updated in place
        (a hierarchy passes the quadrics carried from its children so the error
        stays measured against the original surface). None: plane quadrics of
        ``indices`` (:func:`plane_quadrics`).
    flip_dot : collapses that turn a normal beyond this cosine are refused

    Returns
    -------
    indices : (T', 3) int64, T' <= T, referring to the original vertex numbering
        (subset placement: no vertex moves, every vertex keeps its skin weights)
    remap : (V,) int64, the vertex each input vertex collapsed into (itself when kept)
    error : float >= 0, metres: sqrt of the largest quadric value of any
        collapse in its worst pose (0 when nothing collapsed), the VDR-AM §5.1
        Hausdorff estimate.
    """
    X = np.asarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    if X.ndim != 3 or X.shape[-1] != 3:
        raise ValueError(f"simplify: positions_per_pose must be (P, V, 3), got shape {np.shape(positions_per_pose)}")
    if not np.all(np.isfinite(X)):
        raise ValueError("simplify: positions_per_pose contains NaN or Inf")
    V = X.shape[1]
    t = np.array(indices, np.int64).reshape(-1, 3)
    if t.size and (t.min() < 0 or t.max() >= V):
        raise ValueError(f"simplify: indices must lie in 0..{V - 1}, got {t.min()}..{t.max()}")
    target = int(target_triangles)
    if target < 0:
        raise ValueError(f"simplify: target_triangles must be >= 0, got {target_triangles}")
    t = drawable_triangles(t)
    lock = open_edge_vertices(t, V)
    if locked_vertices is not None:
        lv = np.asarray(locked_vertices, bool).reshape(-1)
        if lv.shape[0] != V:
            raise ValueError(f"simplify: locked_vertices must have {V} entries, got {lv.shape[0]}")
        lock |= lv
    if quadrics is None:
        Q = plane_quadrics(X, t)
    else:
        Q = quadrics
        if Q.shape != (X.shape[0], V, 10) or Q.dtype != np.float64 or not Q.flags.c_contiguous:
            raise ValueError(f"simplify: quadrics must be C-contiguous float64 {(X.shape[0], V, 10)}, got "
                             f"{Q.dtype} {Q.shape}")
    if t.shape[0] <= target:
        return t, np.arange(V, dtype=np.int64), 0.0
    X = np.ascontiguousarray(X)
    alive, remap, err2, _live = _simplify_kernel(X, t, lock, Q, target, float(flip_dot))
    return t[alive], remap, float(np.sqrt(max(err2, 0.0)))
