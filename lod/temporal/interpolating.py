"""Interpolating triangle hierarchies: keyframes refined independently, blended without remeshing.

Keyframe hierarchies meet the interpolation constraints of Definition 2 when
they share the root complex and the root refinement edges and are refined by
Rivara/Bänsch bisection (:class:`lod.temporal.bisection.BisectionForest`). Each is then
a sub-hierarchy of one infinite hierarchy, so their *union hierarchy* (every
node refined in any keyframe is refined) is again a conforming bisection
hierarchy (Theorem 1). A union vertex missing from keyframe ``k`` takes the
value of ``k``'s piecewise-linear surface at that vertex: the mean of the two
endpoints of the refinement edge it bisects, evaluated coarse to fine. The
in-between hierarchy is then ``H(b) = sum_k b_k H_k`` on the union mesh, with
linear weights between two keyframes or the Bernstein weights of eq. (1).

Notes
-----
Friedrich, Polthier & Schmies, §2.2: Definition 2, Theorem 1, eq. (1). With
Bernstein weights the interpolant passes through the first and the last
keyframe; the inner keyframes act as Bézier control hierarchies (eq. (1) is a
Bézier curve of hierarchies), and the scheme has linear precision.
"""
from __future__ import annotations

import math

import numpy as np

from lod.temporal.bisection import BisectionForest, _ekey


def check_interpolation_constraints(forests) -> None:
    """Raise ValueError unless all forests share root vertices, root triangles
    and root refinement edges (Definition 2, conditions 1 and 2)."""
    if not forests:
        raise ValueError("keyframe hierarchies: expected at least one hierarchy, got none")
    f0 = forests[0]
    for j, f in enumerate(forests[1:], 1):
        if f.n_roots != f0.n_roots or f.n_root_verts != f0.n_root_verts:
            raise ValueError(f"keyframe hierarchy {j}: root complex differs from hierarchy 0 "
                             f"({f.n_roots} vs {f0.n_roots} root triangles)")
        if not np.array_equal(f.tri[: f.n_roots], f0.tri[: f0.n_roots]):
            raise ValueError(f"keyframe hierarchy {j}: root triangles or refinement edges differ from hierarchy 0")
        if not np.allclose(f.verts[: f.n_root_verts], f0.verts[: f0.n_root_verts]):
            raise ValueError(f"keyframe hierarchy {j}: root vertex domain positions differ from hierarchy 0")


def union_hierarchy(forests) -> tuple[BisectionForest, list]:
    """The union hierarchy of Theorem 1.

    Parameters
    ----------
    forests : list of BisectionForest meeting Definition 2

    Returns
    -------
    union : BisectionForest, a node is bisected iff it is bisected in any forest
    ident : list of (Vu,) int64 per forest: the forest's id of each union vertex
        if that vertex is part of the forest's current mesh, else -1
    """
    check_interpolation_constraints(forests)
    f0 = forests[0]
    u = BisectionForest(f0.verts[: f0.n_root_verts], f0.tri[: f0.n_roots], np.zeros(f0.n_roots, np.int64))
    stack = [(r, [r] * len(forests)) for r in range(f0.n_roots)]
    while stack:
        node, ks = stack.pop()
        split = [k >= 0 and f.active[k] and not f.leaf[k] for k, f in zip(ks, forests)]
        if not any(split):
            continue
        ch = u.bisect(node) if u.leaf[node] else int(u.child[node])
        for j in (0, 1):
            stack.append((ch + j, [int(f.child[k]) + j if s else -1 for k, f, s in zip(ks, forests, split)]))
    ident = []
    for f in forests:
        idm = np.full(u.n_verts, -1, np.int64)
        idm[: u.n_root_verts] = np.arange(u.n_root_verts)
        for v in range(u.n_root_verts, u.n_verts):
            a, b = u.vparents[v]
            if idm[a] >= 0 and idm[b] >= 0:
                idm[v] = f.mid.get(_ekey(int(idm[a]), int(idm[b])), -1)
        used = np.zeros(u.n_verts, bool)
        ok = idm >= 0
        used[ok] = f.vuse[idm[ok]] > 0
        idm[~used] = -1
        ident.append(idm)
    return u, ident


def values_on_union(union: BisectionForest, ident: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(Vu, D) float64 values of keyframe ``values`` ((Vk, D), indexed by the
    keyframe forest's vertex ids) at every union vertex: own value where the
    keyframe has the vertex, else its piecewise-linear surface (edge midpoint,
    coarse to fine, which is exact because the union refines every keyframe)."""
    vals = np.asarray(values, np.float64)
    out = np.zeros((union.n_verts, vals.shape[1]))
    have = ident >= 0
    out[have] = vals[ident[have]]
    for v in np.flatnonzero(~have):  # ids grow coarse to fine: parents come first
        a, b = union.vparents[v]
        out[v] = 0.5 * (out[a] + out[b])
    return out


def bernstein_weights(n: int, t: float) -> np.ndarray:
    """(n + 1,) float64 Bernstein polynomials ``B_{i,n}(t)`` (eq. 1), t clamped to [0, 1]."""
    if n < 0:
        raise ValueError(f"bernstein_weights: expected degree n >= 0, got {n}")
    t = min(max(float(t), 0.0), 1.0)
    return np.array([math.comb(n, i) * t ** i * (1.0 - t) ** (n - i) for i in range(n + 1)])


def linear_weights(n_keys: int, t: float) -> np.ndarray:
    """(n_keys,) float64 piecewise-linear weights: t in [0, 1] spans the keys evenly."""
    if n_keys < 1:
        raise ValueError("linear_weights: expected at least one key")
    w = np.zeros(n_keys)
    if n_keys == 1:
        w[0] = 1.0
        return w
    s = min(max(float(t), 0.0), 1.0) * (n_keys - 1)
    i = min(int(s), n_keys - 2)
    w[i], w[i + 1] = 1.0 - (s - i), s - i
    return w


def interpolate(forests, values, t: float, scheme: str = "linear"):
    """Interpolated hierarchy ``H(t)`` of keyframes (Theorem 1 / eq. 1).

    Parameters
    ----------
    forests : list of BisectionForest (Definition 2)
    values : list of (Vk, D) float64 per-vertex values (e.g. 3-D positions) of each keyframe
    t : float in [0, 1] over the whole key sequence
    scheme : "linear" (piecewise linear between neighbouring keys) or
        "bernstein" (degree ``len(forests) - 1``, eq. 1)

    Returns
    -------
    triangles : (L, 3) int64 union leaves (conforming)
    positions : (Vu, D) float64 interpolated values of the union vertices
    union : BisectionForest
    """
    if len(values) != len(forests):
        raise ValueError(f"interpolate: {len(forests)} hierarchies but {len(values)} value arrays")
    if scheme == "linear":
        w = linear_weights(len(forests), t)
    elif scheme == "bernstein":
        w = bernstein_weights(len(forests) - 1, t)
    else:
        raise ValueError(f"interpolate: scheme {scheme!r}; expected 'linear' or 'bernstein'")
    union, ident = union_hierarchy(forests)
    pos = sum(wk * values_on_union(union, idk, vk) for wk, idk, vk in zip(w, ident, values))
    return union.leaf_triangles(), pos, union
