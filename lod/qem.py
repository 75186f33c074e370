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
from numba import njit, prange

from lod.clusters_config import CLUSTERS_FLIP_DOT

#: Normal-compatible Hausdorff distance (:func:`cluster_hausdorff`): an original
#: vertex is only approximated by simplified triangles whose normal makes a
#: cosine above this with its own (80 degrees). A closed tube simplified down to
#: a triangular prism (worst normal deviation 60 degrees) still counts; a tube or
#: a foot flattened into a two-sided sheet (90 degrees) does not -- seen edge-on
#: such a sheet covers no pixel, so its rendered silhouette loses the feature
#: although the plain surface distance is small. 65 degrees kept the same
#: silhouette bound (humanoid, quadruped: scripts/bench_clusters.md) with 11 %
#: more triangles on exhibition at PoE 0.5 (7.97 vs 7.16 M).
HAUSDORFF_NORMAL_COS = 0.1736


# ------------------------------------------------------------------------------------------ quadrics
def plane_quadrics_numpy(positions_per_pose: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Per-pose vertex quadrics, numpy reference of :func:`plane_quadrics`.

    Parameters
    ----------
    positions_per_pose : (P, V, 3) float64
    indices : (T, 3) int

    Returns
    -------
    (P, V, 10) float64 coefficients (a², ab, ac, ad, b², bc, bd, c², cd, d²) of
    the sum of the unit-normal plane quadrics of each vertex's triangles;
    degenerate triangles add nothing.
    """
    X = np.asarray(positions_per_pose, np.float64)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    P, V = X.shape[0], X.shape[1]
    Q = np.zeros((P, V, 10))
    if t.shape[0] == 0:
        return Q
    p0, p1, p2 = X[:, t[:, 0]], X[:, t[:, 1]], X[:, t[:, 2]]
    n = np.cross(p1 - p0, p2 - p0)
    ln = np.linalg.norm(n, axis=-1, keepdims=True)
    ok = ln[..., 0] > 0.0
    n = np.where(ok[..., None], n / np.where(ln > 0, ln, 1.0), 0.0)
    d = -np.sum(n * p0, axis=-1)
    a, b, c = n[..., 0], n[..., 1], n[..., 2]
    coef = np.stack([a * a, a * b, a * c, a * d, b * b, b * c, b * d, c * c, c * d, d * d], axis=-1)
    coef[~ok] = 0.0
    for k in range(3):
        for p in range(P):
            np.add.at(Q[p], t[:, k], coef[p])
    return Q


@njit(cache=True)
def _plane_quadrics(X, t, Q):  # pragma: no cover - compiled
    P = X.shape[0]
    for p in range(P):
        for f in range(t.shape[0]):
            i0, i1, i2 = t[f, 0], t[f, 1], t[f, 2]
            ux = X[p, i1, 0] - X[p, i0, 0]
            uy = X[p, i1, 1] - X[p, i0, 1]
            uz = X[p, i1, 2] - X[p, i0, 2]
            vx = X[p, i2, 0] - X[p, i0, 0]
            vy = X[p, i2, 1] - X[p, i0, 1]
            vz = X[p, i2, 2] - X[p, i0, 2]
            a = uy * vz - uz * vy
            b = uz * vx - ux * vz
            c = ux * vy - uy * vx
            ln = np.sqrt(a * a + b * b + c * c)
            if not (ln > 0.0):
                continue
            a /= ln
            b /= ln
            c /= ln
            d = -(a * X[p, i0, 0] + b * X[p, i0, 1] + c * X[p, i0, 2])
            for k in range(3):
                v = t[f, k]
                Q[p, v, 0] += a * a
                Q[p, v, 1] += a * b
                Q[p, v, 2] += a * c
                Q[p, v, 3] += a * d
                Q[p, v, 4] += b * b
                Q[p, v, 5] += b * c
                Q[p, v, 6] += b * d
                Q[p, v, 7] += c * c
                Q[p, v, 8] += c * d
                Q[p, v, 9] += d * d


def plane_quadrics(positions_per_pose: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Per-pose vertex quadrics (P, V, 10) float64 (see :func:`plane_quadrics_numpy`)."""
    X = np.ascontiguousarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    t = np.ascontiguousarray(np.asarray(indices, np.int64).reshape(-1, 3))
    if t.size and (t.min() < 0 or t.max() >= X.shape[1]):
        raise ValueError(f"plane_quadrics: indices must lie in 0..{X.shape[1] - 1}, got {t.min()}..{t.max()}")
    Q = np.zeros((X.shape[0], X.shape[1], 10))
    _plane_quadrics(X, t, Q)
    return Q


def quadric_eval_numpy(Q: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Evaluate quadrics (..., 10) at points (..., 3): (...,) float64."""
    a2, ab, ac, ad, b2, bc, bd, c2, cd, d2 = np.moveaxis(np.asarray(Q, np.float64), -1, 0)
    X, Y, Z = np.moveaxis(np.asarray(x, np.float64), -1, 0)
    return (a2 * X * X + 2 * ab * X * Y + 2 * ac * X * Z + 2 * ad * X + b2 * Y * Y + 2 * bc * Y * Z
            + 2 * bd * Y + c2 * Z * Z + 2 * cd * Z + d2)


# ------------------------------------------------------------------------------------------ kernel
@njit(cache=True, inline="always")
def _qe(Q, p, u, v, x, y, z):  # pragma: no cover - compiled
    """(Q[p,u] + Q[p,v]) evaluated at (x, y, z)."""
    a2 = Q[p, u, 0] + Q[p, v, 0]
    ab = Q[p, u, 1] + Q[p, v, 1]
    ac = Q[p, u, 2] + Q[p, v, 2]
    ad = Q[p, u, 3] + Q[p, v, 3]
    b2 = Q[p, u, 4] + Q[p, v, 4]
    bc = Q[p, u, 5] + Q[p, v, 5]
    bd = Q[p, u, 6] + Q[p, v, 6]
    c2 = Q[p, u, 7] + Q[p, v, 7]
    cd = Q[p, u, 8] + Q[p, v, 8]
    d2 = Q[p, u, 9] + Q[p, v, 9]
    r = (a2 * x * x + 2.0 * ab * x * y + 2.0 * ac * x * z + 2.0 * ad * x + b2 * y * y + 2.0 * bc * y * z
         + 2.0 * bd * y + c2 * z * z + 2.0 * cd * z + d2)
    return max(r, 0.0)


@njit(cache=True)
def _cost(Q, X, u, v):  # pragma: no cover - compiled
    """(sum over poses, max over poses) of the cost of collapsing u onto v."""
    s = 0.0
    m = 0.0
    for p in range(X.shape[0]):
        e = _qe(Q, p, u, v, X[p, v, 0], X[p, v, 1], X[p, v, 2])
        s += e
        if e > m:
            m = e
    return s, m


@njit(cache=True)
def _push(hc, hi, size, c, a, b, sa, sb):  # pragma: no cover - compiled
    """Push onto the binary min-heap (hc costs, hi (cap, 4) payload); returns new arrays and size."""
    if size >= hc.shape[0]:
        nc = np.empty(hc.shape[0] * 2, np.float64)
        ni = np.empty((hc.shape[0] * 2, 4), np.int64)
        nc[:size] = hc[:size]
        ni[:size] = hi[:size]
        hc = nc
        hi = ni
    i = size
    hc[i] = c
    hi[i, 0] = a
    hi[i, 1] = b
    hi[i, 2] = sa
    hi[i, 3] = sb
    while i > 0:
        par = (i - 1) // 2
        if hc[par] <= hc[i]:
            break
        hc[par], hc[i] = hc[i], hc[par]
        for k in range(4):
            hi[par, k], hi[i, k] = hi[i, k], hi[par, k]
        i = par
    return hc, hi, size + 1


@njit(cache=True)
def _pop(hc, hi, size):  # pragma: no cover - compiled
    """Remove the heap top into hc[size-1]/hi[size-1] (read it there); returns new size."""
    last = size - 1
    hc[0], hc[last] = hc[last], hc[0]
    for k in range(4):
        hi[0, k], hi[last, k] = hi[last, k], hi[0, k]
    n = last
    i = 0
    while True:
        l = 2 * i + 1
        if l >= n:
            break
        m = l
        if l + 1 < n and hc[l + 1] < hc[l]:
            m = l + 1
        if hc[i] <= hc[m]:
            break
        hc[m], hc[i] = hc[i], hc[m]
        for k in range(4):
            hi[m, k], hi[i, k] = hi[i, k], hi[m, k]
        i = m
    return n


@njit(cache=True)
def _push_edge(hc, hi, size, Q, X, locked, ver, a, b):  # pragma: no cover - compiled
    best = np.inf
    fa = -1
    if not locked[a]:
        s, _m = _cost(Q, X, a, b)
        best = s
        fa = a
    if not locked[b]:
        s, _m = _cost(Q, X, b, a)
        if s < best:
            best = s
            fa = b
    if fa < 0:
        return hc, hi, size
    fb = b if fa == a else a
    return _push(hc, hi, size, best, fa, fb, ver[fa], ver[fb])


@njit(cache=True)
def _tri_ok(X, t, tris, u, v, flip_dot):  # pragma: no cover - compiled
    """Would replacing u by v in triangle t keep its normal within the flip bound in every pose?"""
    for p in range(X.shape[0]):
        ax = X[p, tris[t, 0], 0]
        ay = X[p, tris[t, 0], 1]
        az = X[p, tris[t, 0], 2]
        bx = X[p, tris[t, 1], 0]
        by = X[p, tris[t, 1], 1]
        bz = X[p, tris[t, 1], 2]
        cx = X[p, tris[t, 2], 0]
        cy = X[p, tris[t, 2], 1]
        cz = X[p, tris[t, 2], 2]
        n0x = (by - ay) * (cz - az) - (bz - az) * (cy - ay)
        n0y = (bz - az) * (cx - ax) - (bx - ax) * (cz - az)
        n0z = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if tris[t, 0] == u:
            ax, ay, az = X[p, v, 0], X[p, v, 1], X[p, v, 2]
        elif tris[t, 1] == u:
            bx, by, bz = X[p, v, 0], X[p, v, 1], X[p, v, 2]
        else:
            cx, cy, cz = X[p, v, 0], X[p, v, 1], X[p, v, 2]
        n1x = (by - ay) * (cz - az) - (bz - az) * (cy - ay)
        n1y = (bz - az) * (cx - ax) - (bx - ax) * (cz - az)
        n1z = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        l1 = np.sqrt(n1x * n1x + n1y * n1y + n1z * n1z)
        if not (l1 > 0.0):
            return False
        l0 = np.sqrt(n0x * n0x + n0y * n0y + n0z * n0z)
        if l0 > 0.0 and (n0x * n1x + n0y * n1y + n0z * n1z) <= flip_dot * l0 * l1:
            return False
    return True


@njit(cache=True)
def _simplify_kernel(X, tris, locked, Q, target, flip_dot):  # pragma: no cover - compiled
    """Greedy multi-pose QEM edge collapse in place.

    X (P, n, 3) f64 positions; tris (m, 3) int64 rewritten in place; locked (n,)
    bool; Q (P, n, 10) f64 accumulated in place; target triangles. Returns
    (alive (m,) bool, remap (n,) int64 vertex -> surviving vertex, max error²
    over the worst pose, live triangle count).
    """
    n = X.shape[1]
    m = tris.shape[0]
    P = X.shape[0]
    head = np.full(n, -1, np.int64)
    tail = np.full(n, -1, np.int64)
    nxt = np.full(3 * m, -1, np.int64)
    for f in range(m):
        for k in range(3):
            node = 3 * f + k
            v = tris[f, k]
            if head[v] < 0:
                head[v] = node
            else:
                nxt[tail[v]] = node
            tail[v] = node
    alive_t = np.ones(m, np.bool_)
    alive_v = np.ones(n, np.bool_)
    remap = np.arange(n)
    ver = np.zeros(n, np.int64)
    mark = np.full(n, -1, np.int64)
    live = m
    hc = np.empty(max(16, 4 * m), np.float64)
    hi = np.empty((max(16, 4 * m), 4), np.int64)
    size = 0
    for f in range(m):
        for k in range(3):
            a = tris[f, k]
            b = tris[f, (k + 1) % 3]
            if a != b:  # an interior edge is queued from both its triangles; the twin goes stale
                hc, hi, size = _push_edge(hc, hi, size, Q, X, locked, ver, a, b)
    maxerr = 0.0
    stamp = 0
    while live > target and size > 0:
        size = _pop(hc, hi, size)
        u = hi[size, 0]
        v = hi[size, 1]
        if not alive_v[u] or not alive_v[v] or ver[u] != hi[size, 2] or ver[v] != hi[size, 3]:
            continue
        # link condition: common neighbours of u and v == third vertices of the triangles on (u, v)
        stamp += 1
        node = head[v]
        while node >= 0:
            f = node // 3
            if alive_t[f]:
                for k in range(3):
                    mark[tris[f, k]] = stamp
            node = nxt[node]
        shared = 0
        common = 0
        stamp2 = stamp + 1
        stamp += 1
        node = head[u]
        ok = True
        while node >= 0:
            f = node // 3
            if alive_t[f]:
                hasv = tris[f, 0] == v or tris[f, 1] == v or tris[f, 2] == v
                if hasv:
                    shared += 1
                else:
                    if not _tri_ok(X, f, tris, u, v, flip_dot):
                        ok = False
                        break
                for k in range(3):
                    w = tris[f, k]
                    if w != u and w != v and mark[w] == stamp2 - 1:
                        mark[w] = stamp2  # count each common neighbour once
                        common += 1
            node = nxt[node]
        if not ok or shared == 0 or common != shared:
            continue
        # collapse u -> v
        node = head[u]
        while node >= 0:
            f = node // 3
            if alive_t[f]:
                if tris[f, 0] == v or tris[f, 1] == v or tris[f, 2] == v:
                    alive_t[f] = False
                    live -= 1
                else:
                    for k in range(3):
                        if tris[f, k] == u:
                            tris[f, k] = v
            node = nxt[node]
        if head[u] >= 0:
            if head[v] < 0:
                head[v] = head[u]
            else:
                nxt[tail[v]] = head[u]
            tail[v] = tail[u]
        head[u] = -1
        for p in range(P):
            for c in range(10):
                Q[p, v, c] += Q[p, u, c]
        alive_v[u] = False
        remap[u] = v
        ver[v] += 1
        e = 0.0
        for p in range(P):
            q = _qe(Q, p, v, v, X[p, v, 0], X[p, v, 1], X[p, v, 2]) * 0.5
            if q > e:
                e = q
        if e > maxerr:
            maxerr = e
        # re-queue the edges around v with their new costs
        stamp += 1
        node = head[v]
        while node >= 0:
            f = node // 3
            if alive_t[f]:
                for k in range(3):
                    w = tris[f, k]
                    if w != v and mark[w] != stamp:
                        mark[w] = stamp
                        hc, hi, size = _push_edge(hc, hi, size, Q, X, locked, ver, v, w)
            node = nxt[node]
    for i in range(n):
        r = i
        while remap[r] != r:
            r = remap[r]
        j = i
        while remap[j] != r:
            k = remap[j]
            remap[j] = r
            j = k
    return alive_t, remap, maxerr, live


def simplify_reference(positions_per_pose: np.ndarray, indices: np.ndarray, target_triangles: int,
                       locked_vertices: np.ndarray, quadrics: np.ndarray, flip_dot: float = CLUSTERS_FLIP_DOT):
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
             flip_dot: float = CLUSTERS_FLIP_DOT):
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
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 2] != t[:, 0])]
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


# ------------------------------------------------------------------------------------------ measurement
@njit(cache=True)
def _point_tri_d2(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):  # pragma: no cover - compiled
    """Squared distance from a point to a triangle (Ericson, Real-Time Collision Detection 5.1.5)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return apx * apx + apy * apy + apz * apz
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bpx * bpx + bpy * bpy + bpz * bpz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        if not (d1 - d3 > 0.0):  # a == b (zero-length edge): the nearest point is the vertex
            return apx * apx + apy * apy + apz * apz
        v = d1 / (d1 - d3)
        qx, qy, qz = ax + v * abx - px, ay + v * aby - py, az + v * abz - pz
        return qx * qx + qy * qy + qz * qz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cpx * cpx + cpy * cpy + cpz * cpz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        if not (d2 - d6 > 0.0):  # a == c
            return apx * apx + apy * apy + apz * apz
        w = d2 / (d2 - d6)
        qx, qy, qz = ax + w * acx - px, ay + w * acy - py, az + w * acz - pz
        return qx * qx + qy * qy + qz * qz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        if not ((d4 - d3) + (d5 - d6) > 0.0):  # b == c
            return bpx * bpx + bpy * bpy + bpz * bpz
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx = bx + w * (cx - bx) - px
        qy = by + w * (cy - by) - py
        qz = bz + w * (cz - bz) - pz
        return qx * qx + qy * qy + qz * qz
    den = va + vb + vc
    if not (den != 0.0):
        return apx * apx + apy * apy + apz * apz
    v = vb / den
    w = vc / den
    qx = ax + abx * v + acx * w - px
    qy = ay + aby * v + acy * w - py
    qz = az + abz * v + acz * w - pz
    return qx * qx + qy * qy + qz * qz


@njit(cache=True, inline="always")
def _face_normal(X, p, tris, f):  # pragma: no cover - compiled
    """Area-weighted (unnormalised) normal of triangle f in pose p."""
    a, b, c = tris[f, 0], tris[f, 1], tris[f, 2]
    ux, uy, uz = X[p, b, 0] - X[p, a, 0], X[p, b, 1] - X[p, a, 1], X[p, b, 2] - X[p, a, 2]
    wx, wy, wz = X[p, c, 0] - X[p, a, 0], X[p, c, 1] - X[p, a, 1], X[p, c, 2] - X[p, a, 2]
    return uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx


@njit(cache=True)
def _vertex_normals(X, tris, out):  # pragma: no cover - compiled
    for p in range(X.shape[0]):
        for f in range(tris.shape[0]):
            a, b, c = tris[f, 0], tris[f, 1], tris[f, 2]
            nx, ny, nz = _face_normal(X, p, tris, f)
            for v in (a, b, c):
                out[p, v, 0] += nx
                out[p, v, 1] += ny
                out[p, v, 2] += nz
        for v in range(X.shape[1]):
            ln = np.sqrt(out[p, v, 0] ** 2 + out[p, v, 1] ** 2 + out[p, v, 2] ** 2)
            if ln > 0.0:
                out[p, v, 0] /= ln
                out[p, v, 1] /= ln
                out[p, v, 2] /= ln


def vertex_normals(positions_per_pose: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(P, V, 3) float64 unit area-weighted vertex normals of a mesh in every pose (0 for unused vertices)."""
    X = np.ascontiguousarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    t = np.ascontiguousarray(np.asarray(indices, np.int64).reshape(-1, 3))
    out = np.zeros(X.shape)
    if t.size:
        _vertex_normals(X, t, out)
    return out


@njit(cache=True, parallel=True)
def _vertex_surface_d2(X, verts, tris, out):  # pragma: no cover - compiled
    P = X.shape[0]
    nv = verts.shape[0]
    for k in prange(P * nv):
        p = k // nv
        i = verts[k % nv]
        best = np.inf
        px, py, pz = X[p, i, 0], X[p, i, 1], X[p, i, 2]
        for f in range(tris.shape[0]):
            a, b, c = tris[f, 0], tris[f, 1], tris[f, 2]
            d = _point_tri_d2(px, py, pz, X[p, a, 0], X[p, a, 1], X[p, a, 2], X[p, b, 0], X[p, b, 1], X[p, b, 2],
                              X[p, c, 0], X[p, c, 1], X[p, c, 2])
            if d < best:
                best = d
        out[p, k % nv] = best


def vertex_surface_distance(positions_per_pose: np.ndarray, original: np.ndarray, simplified: np.ndarray) -> np.ndarray:
    """Distance of every original vertex to the simplified surface, in every pose.

    A metro-like measure (Cignoni et al., sampling at the original vertices)
    used to compare simplifications (VDR-AM §6 reports the RMS of it): brute
    force over triangles, meant for meshes of a few thousand triangles.

    Parameters
    ----------
    positions_per_pose : (P, V, 3) float64 original vertex positions per pose
    original : (T, 3) int original triangles (their vertices are sampled)
    simplified : (T', 3) int simplified triangles over the same vertices

    Returns
    -------
    (P, n) float64 distances (n = vertices used by ``original``); inf where the
    simplified mesh is empty.
    """
    X = np.ascontiguousarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    verts = np.unique(np.asarray(original, np.int64).reshape(-1))
    tris = np.ascontiguousarray(np.asarray(simplified, np.int64).reshape(-1, 3))
    for name, a in (("original", verts), ("simplified", tris)):
        if a.size and (a.min() < 0 or a.max() >= X.shape[1]):
            raise ValueError(f"vertex_surface_distance: {name} indices must lie in 0..{X.shape[1] - 1}")
    out = np.empty((X.shape[0], verts.shape[0]))
    if verts.size:
        _vertex_surface_d2(X, verts, tris, out)
    return np.sqrt(out)


@njit(cache=True)
def _collapse_distance(X, tris, local, n_local, verts_orig, rep):  # pragma: no cover - compiled
    """Largest (over poses and original vertices) distance from an original vertex
    to the triangles around the vertex it collapsed into; see :func:`collapse_distance`."""
    m = tris.shape[0]
    cnt = np.zeros(n_local + 1, np.int64)
    for f in range(m):
        for k in range(3):
            cnt[local[tris[f, k]] + 1] += 1
    for i in range(n_local):
        cnt[i + 1] += cnt[i]
    fill = cnt[:-1].copy()
    lst = np.empty(3 * m, np.int64)
    for f in range(m):
        for k in range(3):
            li = local[tris[f, k]]
            lst[fill[li]] = f
            fill[li] += 1
    worst = 0.0
    for j in range(verts_orig.shape[0]):
        v = verts_orig[j]
        r = rep[v]
        if r == v:
            continue
        li = local[r]
        for p in range(X.shape[0]):
            best = (X[p, v, 0] - X[p, r, 0]) ** 2 + (X[p, v, 1] - X[p, r, 1]) ** 2 + (X[p, v, 2] - X[p, r, 2]) ** 2
            if li >= 0:
                for q in range(cnt[li], cnt[li + 1]):
                    f = lst[q]
                    a, b, c = tris[f, 0], tris[f, 1], tris[f, 2]
                    d = _point_tri_d2(X[p, v, 0], X[p, v, 1], X[p, v, 2], X[p, a, 0], X[p, a, 1], X[p, a, 2],
                                      X[p, b, 0], X[p, b, 1], X[p, b, 2], X[p, c, 0], X[p, c, 1], X[p, c, 2])
                    if d < best:
                        best = d
            if best > worst:
                worst = best
    return np.sqrt(worst)


def collapse_distance(positions_per_pose: np.ndarray, simplified: np.ndarray, original_vertices: np.ndarray,
                      representative: np.ndarray) -> float:
    """A measured, conservative one-sided error of a subset-placement simplification.

    For every original vertex v whose representative r = ``representative[v]``
    is another vertex, the distance from v to the simplified triangles around r
    (or to r itself when none is left), in every pose; returns the largest, in
    metres. The true vertex-to-surface distance is never larger, so this bounds
    the vertex-sampled Hausdorff distance from above while staying local (a few
    triangles per vertex).

    Parameters
    ----------
    positions_per_pose : (P, V, 3) float64
    simplified : (T', 3) int triangles (global vertex ids)
    original_vertices : (k,) int vertices of the original region
    representative : (V,) int vertex each original vertex ended in
    """
    X = np.ascontiguousarray(positions_per_pose, np.float64)
    t = np.ascontiguousarray(np.asarray(simplified, np.int64).reshape(-1, 3))
    V = X.shape[1]
    verts = np.unique(t)
    local = np.full(V, -1, np.int64)
    local[verts] = np.arange(verts.shape[0])
    return float(_collapse_distance(X, t, local, verts.shape[0], np.asarray(original_vertices, np.int64),
                                    np.asarray(representative, np.int64)))


# ------------------------------------------------------------------------------------------ cluster Hausdorff
@njit(cache=True)
def _vertex_lists(keys, n_keys):  # pragma: no cover - compiled
    """CSR of the positions j grouped by ``keys[j]`` in 0..n_keys-1 (negative keys skipped)."""
    ptr = np.zeros(n_keys + 1, np.int64)
    for j in range(keys.shape[0]):
        if keys[j] >= 0:
            ptr[keys[j] + 1] += 1
    for i in range(n_keys):
        ptr[i + 1] += ptr[i]
    fill = ptr[:-1].copy()
    out = np.empty(ptr[n_keys], np.int64)
    for j in range(keys.shape[0]):
        k = keys[j]
        if k >= 0:
            out[fill[k]] = j
            fill[k] += 1
    return ptr, out


@njit(cache=True)
def _tri_d2(X, p, px, py, pz, tris, f):  # pragma: no cover - compiled
    a, b, c = tris[f, 0], tris[f, 1], tris[f, 2]
    return _point_tri_d2(px, py, pz, X[p, a, 0], X[p, a, 1], X[p, a, 2], X[p, b, 0], X[p, b, 1], X[p, b, 2],
                         X[p, c, 0], X[p, c, 1], X[p, c, 2])


@njit(cache=True)
def _cluster_hausdorff(X, tris, region_verts, rep, vt_ptr, vt_idx, orig_tris, tri_owner, node, vnorm,
                       cos_min):  # pragma: no cover
    """(forward, backward) squared distances, max over poses; see :func:`cluster_hausdorff`.

    ``vnorm`` (P, V, 3) unit vertex normals per pose switch the forward pass to
    the normal-compatible distance (only simplified triangles whose normal makes
    a cosine above ``cos_min`` with the vertex normal count); (0, 0, 3) for the
    plain distance."""
    P = X.shape[0]
    V = X.shape[1]
    m = tris.shape[0]
    local = np.full(V, -1, np.int64)
    n_local = 0
    for f in range(m):
        for k in range(3):
            v = tris[f, k]
            if local[v] < 0:
                local[v] = n_local
                n_local += 1
    # simplified triangles around each simplified vertex (first pass of the forward search)
    key = np.empty(3 * m, np.int64)
    for f in range(m):
        for k in range(3):
            key[3 * f + k] = local[tris[f, k]]
    fan_ptr, fan = _vertex_lists(key, n_local)
    # bounding spheres of the simplified triangles in every pose (culling of the exhaustive pass)
    cen = np.empty((P, m, 3))
    rad = np.empty((P, m))
    for p in range(P):
        for f in range(m):
            for d in range(3):
                cen[p, f, d] = (X[p, tris[f, 0], d] + X[p, tris[f, 1], d] + X[p, tris[f, 2], d]) / 3.0
            r = 0.0
            for k in range(3):
                v = tris[f, k]
                r = max(r, np.sqrt((X[p, v, 0] - cen[p, f, 0]) ** 2 + (X[p, v, 1] - cen[p, f, 1]) ** 2
                                   + (X[p, v, 2] - cen[p, f, 2]) ** 2))
            rad[p, f] = r
    use_n = vnorm.shape[0] == P and P > 0
    fnrm = np.zeros((P if use_n else 0, m, 3))
    if use_n:
        for p in range(P):
            for f in range(m):
                nx, ny, nz = _face_normal(X, p, tris, f)
                ln = np.sqrt(nx * nx + ny * ny + nz * nz)
                if ln > 0.0:  # a degenerate triangle covers no pixel: compatible with nothing
                    fnrm[p, f, 0], fnrm[p, f, 1], fnrm[p, f, 2] = nx / ln, ny / ln, nz / ln
    fwd = 0.0
    for j in range(region_verts.shape[0]):
        v = region_verts[j]
        if local[v] >= 0:
            if not use_n:
                continue  # a vertex of the simplified surface: distance 0
            lr = local[v]  # on the surface; distance 0 only where an incident triangle faces its way
        else:
            r = rep[v]
            lr = local[r] if r >= 0 else -1
        for p in range(P):
            px, py, pz = X[p, v, 0], X[p, v, 1], X[p, v, 2]
            if use_n:
                nx, ny, nz = vnorm[p, v, 0], vnorm[p, v, 1], vnorm[p, v, 2]
            best = np.inf
            if lr >= 0:
                for q in range(fan_ptr[lr], fan_ptr[lr + 1]):
                    f = fan[q] // 3
                    if use_n and fnrm[p, f, 0] * nx + fnrm[p, f, 1] * ny + fnrm[p, f, 2] * nz <= cos_min:
                        continue
                    d = _tri_d2(X, p, px, py, pz, tris, f)
                    if d < best:
                        best = d
            if best <= fwd:
                continue  # cannot raise the maximum
            sb = np.sqrt(best) if best < np.inf else np.inf
            for f in range(m):
                if use_n and fnrm[p, f, 0] * nx + fnrm[p, f, 1] * ny + fnrm[p, f, 2] * nz <= cos_min:
                    continue
                # skip a triangle whose bounding sphere lies farther than the best distance so far
                rr = rad[p, f] + sb
                c2 = (px - cen[p, f, 0]) ** 2 + (py - cen[p, f, 1]) ** 2 + (pz - cen[p, f, 2]) ** 2
                if c2 >= rr * rr:
                    continue
                d = _tri_d2(X, p, px, py, pz, tris, f)
                if d < best:
                    best = d
                    if best <= fwd:
                        break
                    sb = np.sqrt(best)
            if best == np.inf and use_n:
                # no triangle of the cluster faces this way: the feature is lost from the image; bound it by
                # the farthest point of the cluster's simplified surface
                for f in range(m):
                    c2 = np.sqrt((px - cen[p, f, 0]) ** 2 + (py - cen[p, f, 1]) ** 2 + (pz - cen[p, f, 2]) ** 2)
                    d = (c2 + rad[p, f]) ** 2
                    if best == np.inf or d > best:
                        best = d
            if best > fwd:
                fwd = best
    # backward: centroid and edge midpoints of every simplified triangle to the original triangles of the
    # region around the original vertices collapsed into the triangle's corners
    keyv = np.full(region_verts.shape[0], -1, np.int64)
    for j in range(region_verts.shape[0]):
        r = rep[region_verts[j]]
        if r >= 0:
            keyv[j] = local[r]
    col_ptr, col = _vertex_lists(keyv, n_local)
    bwd = 0.0
    for f in range(m):
        for p in range(P):
            for s in range(4):
                if s == 3:
                    px = cen[p, f, 0]
                    py = cen[p, f, 1]
                    pz = cen[p, f, 2]
                else:
                    a, b = tris[f, s], tris[f, (s + 1) % 3]
                    px = 0.5 * (X[p, a, 0] + X[p, b, 0])
                    py = 0.5 * (X[p, a, 1] + X[p, b, 1])
                    pz = 0.5 * (X[p, a, 2] + X[p, b, 2])
                # the corners are original vertices of the region (on its surface): an upper bound to start
                best = np.inf
                for k in range(3):
                    c = tris[f, k]
                    d = (px - X[p, c, 0]) ** 2 + (py - X[p, c, 1]) ** 2 + (pz - X[p, c, 2]) ** 2
                    if d < best:
                        best = d
                if best <= bwd:
                    continue  # cannot raise the maximum
                for k in range(3):
                    lv = local[tris[f, k]]
                    for q in range(col_ptr[lv], col_ptr[lv + 1]):
                        v = region_verts[col[q]]
                        for e in range(vt_ptr[v], vt_ptr[v + 1]):
                            t = vt_idx[e]
                            if tri_owner[t] != node:
                                continue
                            d = _tri_d2(X, p, px, py, pz, orig_tris, t)
                            if d < best:
                                best = d
                        if best <= bwd:
                            break
                    if best <= bwd:
                        break
                if best > bwd:
                    bwd = best
    return fwd, bwd


def cluster_hausdorff(positions_per_pose: np.ndarray, simplified: np.ndarray, region_vertices: np.ndarray,
                      representative: np.ndarray, original: np.ndarray, region_mask: np.ndarray,
                      normal_cos: float | None = None) -> tuple:
    """Measured two-sided Hausdorff distance of a simplified cluster to the ORIGINAL surface it replaces.

    VDR-AM §4.3/§5.1 store with each cluster its Hausdorff distance to the
    original model, over the representative poses. Rather than accumulating
    per-level estimates (which compounds with the depth of the hierarchy), it
    is measured directly against the leaf triangles of the cluster's region:

    - forward (exact, vertex-sampled): the largest distance from an original
      vertex of the region to the simplified triangles, in any pose (a metro
      sampling at the original vertices, Cignoni et al.);
    - backward (sampled, conservative): the largest distance from the centroid
      and edge midpoints of each simplified triangle to the original triangles
      incident to the vertices that collapsed into its corners (a subset of the
      region's surface, so never smaller than the distance to the whole region).

    With ``normal_cos`` (the build passes :data:`HAUSDORFF_NORMAL_COS`) the
    forward pass is normal-compatible: in each pose an original vertex (kept
    vertices included) only measures its distance to simplified triangles whose
    normal makes a cosine above ``normal_cos`` with the vertex's area-weighted
    normal, and a vertex no triangle of the cluster faces is charged the
    distance to the farthest point of the simplified surface (the feature is
    gone from the image). This is what bounds the *rendered* silhouette: the
    plain distance is small for a limb flattened into a two-sided sheet, which
    rasterises to nothing seen edge-on (VDR-AM §4.3 "Hausdorff distance"; the
    orientation test is our addition, measured in ``scripts/bench_clusters.md``).

    Parameters
    ----------
    positions_per_pose : (P, V, 3) float64 original vertex positions per pose
    simplified : (T', 3) int simplified triangles (original vertex ids)
    region_vertices : (k,) int original vertices of the region
    representative : (V,) int the simplified vertex each original vertex collapsed into
        (only entries of ``region_vertices`` are read)
    original : (T, 3) int all original triangles
    region_mask : (T,) bool original triangles that belong to the region
    normal_cos : None (plain distance) or float in [-1, 1), see above

    Returns
    -------
    (forward, backward) : two floats, metres, max over the poses
    """
    X = np.ascontiguousarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    V = X.shape[1]
    t = np.ascontiguousarray(np.asarray(simplified, np.int64).reshape(-1, 3))
    o = np.ascontiguousarray(np.asarray(original, np.int64).reshape(-1, 3))
    rv = np.ascontiguousarray(np.asarray(region_vertices, np.int64).reshape(-1))
    rep = np.ascontiguousarray(np.asarray(representative, np.int64).reshape(-1))
    for name, a in (("simplified", t), ("original", o), ("region_vertices", rv)):
        if a.size and (a.min() < 0 or a.max() >= V):
            raise ValueError(f"cluster_hausdorff: {name} indices must lie in 0..{V - 1}")
    if rep.shape[0] != V:
        raise ValueError(f"cluster_hausdorff: representative must have {V} entries, got {rep.shape[0]}")
    mask = np.asarray(region_mask, bool).reshape(-1)
    if mask.shape[0] != o.shape[0]:
        raise ValueError(f"cluster_hausdorff: region_mask must have {o.shape[0]} entries, got {mask.shape[0]}")
    if t.shape[0] == 0:
        return (np.inf if rv.size else 0.0), 0.0
    flat = o.reshape(-1)
    order = np.argsort(flat, kind="stable")
    vt_ptr = np.zeros(V + 1, np.int64)
    np.add.at(vt_ptr, flat + 1, 1)
    vt_ptr = np.cumsum(vt_ptr)
    owner = np.where(mask, 0, -1).astype(np.int64)
    vn = None if normal_cos is None else vertex_normals(X, o[mask])
    return _cluster_hausdorff_sq(X, t, rv, rep, vt_ptr, (order // 3).astype(np.int64), o, owner, 0, vn,
                                 normal_cos)


def _cluster_hausdorff_sq(X, t, rv, rep, vt_ptr, vt_idx, o, owner, node, vnorm=None, cos_min=0.0):
    vn = np.zeros((0, 0, 3)) if vnorm is None else vnorm
    f2, b2 = _cluster_hausdorff(X, t, rv, rep, vt_ptr, vt_idx, o, owner, node, vn, float(0.0 if cos_min is None else cos_min))
    return float(np.sqrt(max(f2, 0.0))), float(np.sqrt(max(b2, 0.0)))


def cluster_hausdorff_numpy(positions_per_pose: np.ndarray, simplified: np.ndarray, region_vertices: np.ndarray,
                            original: np.ndarray, region_mask: np.ndarray) -> tuple:
    """Brute-force reference of :func:`cluster_hausdorff` (small meshes only).

    forward: every region vertex against every simplified triangle; backward:
    the same sample points (centroid, edge midpoints) against EVERY original
    triangle of the region, so the compiled backward value is >= this one.
    """
    X = np.asarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    t = np.asarray(simplified, np.int64).reshape(-1, 3)
    o = np.asarray(original, np.int64).reshape(-1, 3)[np.asarray(region_mask, bool)]
    used = np.unique(t)
    rv = np.setdiff1d(np.asarray(region_vertices, np.int64), used)

    def d2(pts, tri):  # (P, n, 3) points against (P, m) triangles -> (P, n) min squared distance
        out = np.full(pts.shape[:2], np.inf)
        for p in range(pts.shape[0]):
            for j in range(pts.shape[1]):
                for f in tri:
                    a, b, c = X[p, f[0]], X[p, f[1]], X[p, f[2]]
                    out[p, j] = min(out[p, j], _point_tri_d2_py(pts[p, j], a, b, c))
        return out

    fwd = float(np.sqrt(d2(X[:, rv], t).max())) if rv.size and t.size else 0.0
    if t.shape[0] == 0 or o.shape[0] == 0:
        return fwd, 0.0
    A, B, C = X[:, t[:, 0]], X[:, t[:, 1]], X[:, t[:, 2]]
    samples = np.concatenate([(A + B) / 2, (B + C) / 2, (C + A) / 2, (A + B + C) / 3], axis=1)
    return fwd, float(np.sqrt(d2(samples, o).max()))


def _point_tri_d2_py(p, a, b, c):
    """Squared point-triangle distance by minimising over the triangle (plain numpy, barycentric projection
    clamped to the edges)."""
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    nn = float(n @ n)
    if nn > 0.0:
        # projection inside the triangle?
        w = p - a
        s = float(np.cross(w, ac) @ n) / nn
        u = float(np.cross(ab, w) @ n) / nn
        if s >= 0 and u >= 0 and s + u <= 1:
            q = a + s * ab + u * ac
            return float((p - q) @ (p - q))

    def seg(x, y):
        d = y - x
        dd = float(d @ d)
        s = 0.0 if dd == 0 else min(max(float((p - x) @ d) / dd, 0.0), 1.0)
        q = x + s * d
        return float((p - q) @ (p - q))
    return min(seg(a, b), seg(b, c), seg(c, a))
