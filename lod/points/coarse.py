"""Representations coarser than a point hierarchy's root: prefixes of the root's
points in farthest-point order, each with the spacing it stands for.

Wand & Straßer 2002 (§3.1, §3.2) stop refining at the root: an instance a pixel
or two tall still draws every point of the root (about 50-70 for a 5,000-triangle
humanoid), although a handful of splats, or one, would cover its footprint. This
module extends the hierarchy upwards without new data:

* Order: the points of the root's time interval ``j`` are reordered (in place,
  within the interval's range, so every draw of the whole range is unchanged)
  by farthest-point sampling (Gonzalez 1985; Eldar et al. 1997) under the
  distance ``max(|a0 - b0|, |a1 - b1|)`` of the two keyframe positions. The
  distance of two linearly moving points is convex in time (as for the
  stratification, ``lod.points.stratify``), so the bounds below hold at every
  u of the segment. The first point is the one nearest the points' centroid.
* Error: after ``m`` points, every root point is within ``c_m`` of one of them
  (``c_m`` is the farthest-point distance of the ``m + 1``-th pick; ``c_n = 0``),
  and the root's points cover the surface within ``r / 2`` (``r`` = the root's
  spacing, §3.4.2). The prefix therefore covers the surface within
  ``c_m + r / 2``, the same coverage as a node of spacing ``s_m = 2 c_m + r``.
  It is drawn under the traversal's own rule (§3.2): the smallest prefix whose
  projected spacing ``s_m * scale / depth * viewport_scale`` is at most the
  splat size, i.e. within the same pixels of error as any node drawn as points
  (``lod.view``'s projected error; auto's point candidate prices its error as
  the splat size, so it chooses the coarse prefix exactly when a node would be
  allowed). ``m = 1`` is one splat standing for the whole agent: its spacing
  ``2 c_1 + r`` is about the agent's size, so it is drawn only when the whole
  agent projects within the splat (an impostor splat sized by its error).
* Table: prefixes of ``1, 2, 4, ...`` points and the whole root
  (``COARSE_LEVELS`` at most), ``coarse_count`` (m, J x L int64) and
  ``coarse_spacing`` (s_m, J x L float64), padded with the whole root.

``farthest_order`` (numba) and ``farthest_order_numpy`` (reference) compute the
order and covering radii; :func:`add_coarse` applies them to a hierarchy.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: most prefix sizes per interval (1, 2, 4, ..., 2**(L-2), then the whole root)
COARSE_LEVELS = 12


@njit(cache=True)
def _farthest_kernel(P, first, order, radius):  # pragma: no cover - compiled
    # P (K, n, 3): the points at K times; the distance is the largest over them
    n = P.shape[1]
    dist = np.empty(n)
    used = np.zeros(n, np.bool_)
    cur = first
    for m in range(n):
        order[m] = cur
        used[cur] = True
        best = -1.0
        arg = 0
        for i in range(n):
            if used[i]:
                continue
            dd = 0.0
            for q in range(P.shape[0]):
                e = 0.0
                for k in range(3):
                    a = P[q, i, k] - P[q, cur, k]
                    e += a * a
                if e > dd:
                    dd = e
            d = np.sqrt(dd)
            if m == 0 or d < dist[i]:
                dist[i] = d
            if dist[i] > best:
                best = dist[i]
                arg = i
        radius[m] = best if best >= 0.0 else 0.0
        cur = arg


def _first(P) -> int:
    mid = P.mean(axis=0)
    return int(np.argmin(((mid - mid.mean(axis=0)) ** 2).sum(axis=1)))


def farthest_order(p0, p1=None, poses=None) -> tuple[np.ndarray, np.ndarray]:
    """Farthest-point order of points moving from ``p0`` to ``p1`` (n, 3), or of points at K times
    (``poses`` (K, n, 3); ``lod.points.follow``: the stratification poses).

    Returns order (n,) int64 and radius (n,) float64: after the first ``m + 1``
    points of ``order`` every point is within ``radius[m]`` (distance: the largest
    over the times); ``radius[n - 1] = 0``."""
    if poses is None:
        P = np.stack([np.asarray(p0, np.float64).reshape(-1, 3), np.asarray(p1, np.float64).reshape(-1, 3)])
    else:
        P = np.asarray(poses, np.float64).reshape(len(poses), -1, 3)
    P = np.ascontiguousarray(P)
    n = P.shape[1]
    order, radius = np.zeros(n, np.int64), np.zeros(n, np.float64)
    if n:
        _farthest_kernel(P, _first(P), order, radius)
    return order, radius


def farthest_order_numpy(p0, p1) -> tuple[np.ndarray, np.ndarray]:
    """Reference of :func:`farthest_order` (numpy, O(n^2) memory)."""
    p0 = np.asarray(p0, np.float64).reshape(-1, 3)
    p1 = np.asarray(p1, np.float64).reshape(-1, 3)
    n = p0.shape[0]
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    d = np.sqrt(np.maximum(((p0[:, None] - p0[None]) ** 2).sum(-1), ((p1[:, None] - p1[None]) ** 2).sum(-1)))
    order, radius = [_first(np.stack([p0, p1]))], []
    near = d[order[0]].copy()
    for _ in range(1, n):
        cand = np.where(np.isin(np.arange(n), order), -1.0, near)
        nxt = int(np.argmax(cand))
        radius.append(float(near[nxt]))
        order.append(nxt)
        near = np.minimum(near, d[nxt])
    radius.append(0.0)
    return np.array(order, np.int64), np.array(radius)


#: the point arrays of a PointHierarchy permuted together
_POINT_ARRAYS = ("pos0", "pos1", "nrm0", "nrm1", "col0", "col1", "tri", "bary", "node")


def prefix_table(radius: np.ndarray, root_spacing: float, levels: int = COARSE_LEVELS):
    """(counts, spacings) of the prefixes 1, 2, 4, ... and the whole root (see module doc)."""
    n = int(radius.shape[0])
    counts = []
    m = 1
    while m < n and len(counts) < levels - 1:
        counts.append(m)
        m *= 2
    counts.append(n)
    counts = np.array(counts, np.int64)
    spacing = 2.0 * radius[counts - 1] + float(root_spacing)
    spacing[-1] = float(root_spacing)
    return counts, spacing


def add_coarse(h, poses=None) -> None:
    """Reorder the root's points of every time interval in farthest-point order and set
    ``h.coarse_count`` and ``h.coarse_spacing`` (J, COARSE_LEVELS). Idempotent; a
    hierarchy whose root draws no points gets tables of width 0 (no coarse prefixes).
    ``poses`` (K, n, 3): the root's points (one interval) at K times to order them by
    (``lod.points.follow``), in place of its two keyframes."""
    if getattr(h, "coarse_count", None) is not None:
        return
    J = int(h.point_count.shape[1]) if h.n_nodes else 0
    cnt = np.zeros((J, COARSE_LEVELS), np.int64)
    spc = np.zeros((J, COARSE_LEVELS), np.float64)
    r = float(h.spacing[0]) if h.n_nodes else 0.0
    if not h.n_nodes or h.child_count[0] == 0 or r <= 0.0 or not (h.point_count[0] > 0).all():
        h.coarse_count, h.coarse_spacing = cnt[:, :0], spc[:, :0]
        return
    for j in range(J):
        s, n = int(h.point_start[0, j]), int(h.point_count[0, j])
        if poses is not None:
            order, radius = farthest_order(None, poses=poses)
        else:
            order, radius = farthest_order(h.pos0[s:s + n], h.pos1[s:s + n])
        for name in _POINT_ARRAYS:
            a = getattr(h, name, None)
            if a is not None and a.shape[0] == h.pos0.shape[0]:  # (a super-hierarchy keeps no tri / bary)
                a[s:s + n] = a[s:s + n][order]
        c, sp = prefix_table(radius, r)
        cnt[j, :] = c[-1]
        spc[j, :] = sp[-1]
        cnt[j, :c.shape[0]] = c
        spc[j, :c.shape[0]] = sp
    h.coarse_count, h.coarse_spacing = cnt, spc


def coarse_arrays(h) -> tuple[np.ndarray, np.ndarray]:
    """(coarse_count, coarse_spacing) of ``h`` for the traversal kernels; (J, 0) when none."""
    c = getattr(h, "coarse_count", None)
    if c is None:
        J = int(h.point_count.shape[1]) if h.point_count.ndim == 2 else 1
        return np.zeros((J, 0), np.int64), np.zeros((J, 0), np.float64)
    return c, h.coarse_spacing
