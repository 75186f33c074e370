"""The compiled greedy collapse loop of :mod:`lod.simplify.collapse`: collapse
costs summed over poses, a binary heap of candidate edges with version
stamps, the link and normal-flip tests, and :func:`_simplify_kernel` itself.
"""
from __future__ import annotations

import numpy as np
from numba import njit


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
