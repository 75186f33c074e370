"""Geomorphs between two cluster cuts of one VDR-AM hierarchy (Friedrich, Polthier & Schmies §3).

Friedrich, Polthier, Schmies, *Smooth View-Dependent Rendering in Animations*,
§3: the view-dependent selection runs every n-th frame only, and every frame in
between draws the *union* of the two keyframe selections with vertex positions
interpolated by the frame's weight ``t``, so the representation never pops. The
paper does this for bisection hierarchies, whose finer triangles carry the
coarser ones' vertices; a VDR-AM cluster hierarchy (Claudio et al. §4.3,
:mod:`lod.clusters.dag`) offers the same structure:

- every internal cluster is its children's triangles simplified by half-edge
  collapses onto kept vertices (subset placement), so each vertex a cluster
  removed has a *collapse target* in that cluster (``morph_vertex`` /
  ``morph_target`` of :class:`lod.clusters.dag.ClusterHierarchy`), and a vertex
  is removed by at most one cluster;
- following the targets from a vertex of a fine cluster ``f`` up to an
  ancestor ``a`` (while the cluster that removed the current vertex lies in
  ``a``'s subtree, i.e. its height is at most ``a``'s: both lie on ``f``'s path
  to the root) gives the vertex of ``a`` the original vertex has collapsed into.
  Drawing ``f``'s triangles with every vertex moved to that target draws
  exactly ``a``'s triangles over ``f``'s region, plus degenerate ones.

So the union of two cuts A (keyframe i) and B (keyframe i+1) is drawn as the
*finer* of the two clusters over every part of the mesh, with each vertex
blended from its own skinned position towards its target in the coarser
cluster: weight ``t`` where A is the finer (A coarsens into B) and ``1 - t``
where B is the finer (A's coarse cluster refines into B's). At ``t = 0`` the
image is cut A, at ``t = 1`` cut B, and in between no vertex jumps. Vertices on
a coarse cluster's border are locked in it (:mod:`lod.clusters.dag`'s crack
rule), so their chain ends at themselves: two neighbouring regions blending
towards different ancestors, or one blending and one not, share an unmoved
border, and the morph is crack-free at every ``t``.

Departures: the cuts are clipped to the view frustum (:func:`lod.clusters.mode.cull_clusters`),
so one cut may lack part of a region the other draws coarse; such an instance
is reported as not morphable and the caller falls back to the screen-door fade
(:mod:`lod.temporal.selection`). A cluster only one cut draws (the other culled
its whole region) is drawn unmoved.

:func:`collapse_table` turns the hierarchy's per-cluster lists into per-vertex
arrays (the GPU follows them in ``render/shaders/clusters/clusters_morph.vert``);
:func:`chain_targets` is the CPU form of that walk, :func:`morph_union` builds
the union per instance (numba kernel beside :func:`morph_union_numpy`), and
:func:`morphed_triangle_positions` evaluates a morphed union on the CPU (tests,
``scripts/bench_temporal.py``).
"""
from __future__ import annotations

import copy

import numpy as np
from numba import njit

#: removal height of a vertex no cluster removes (it survives to the root)
NEVER_REMOVED = np.int32(2 ** 30)
#: morph height of a union entry drawn unmoved
NO_MORPH = -1
#: side of a union entry: the finer cluster comes from cut A (blend weight t) or from cut B (weight 1 - t)
SIDE_A, SIDE_B = 0, 1
#: longest collapse chain the shader follows (``render/shaders/clusters/clusters_morph.vert`` MAX_CHAIN); a chain
#: climbs strictly in height, so hierarchies up to this height morph (taller ones are faded)
MAX_CHAIN = 64


def collapse_table(h) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex collapse arrays of a :class:`lod.clusters.dag.ClusterHierarchy` (cached on it).

    Returns
    -------
    nxt : (V,) int32, the vertex each vertex collapses onto in the cluster that
        removes it; the vertex itself when no cluster removes it
    removed_at : (V,) int32, the height of that cluster; :data:`NEVER_REMOVED` when none

    Raises ValueError when a vertex is removed by two clusters or its target is
    out of range (a corrupt hierarchy: the chain could then loop).
    """
    c = h.__dict__.get("_collapse_table")
    if c is not None and c[0] is h.morph_target:
        return c[1], c[2]
    V = int(h.n_vertices)
    nxt = np.arange(V, dtype=np.int32)
    removed_at = np.full(V, NEVER_REMOVED, np.int32)
    ptr = np.asarray(h.morph_ptr, np.int64)
    mv = np.asarray(h.morph_vertex, np.int64)
    mt = np.asarray(h.morph_target, np.int64)
    if mv.size:
        if mv.max() >= V or mt.max() >= V:
            raise ValueError("cluster hierarchy: a geomorph vertex or target lies past the vertex buffer")
        owner = np.repeat(np.arange(ptr.shape[0] - 1), np.diff(ptr))
        if np.unique(mv).shape[0] != mv.shape[0]:
            raise ValueError("cluster hierarchy: a vertex is removed by two clusters")
        hgt = np.asarray(h.height, np.int32)[owner]
        nxt[mv] = mt.astype(np.int32)
        removed_at[mv] = hgt
        # a target is kept by the cluster that removes its source, so it is removed (if ever) strictly higher
        tgt_h = removed_at[mt]
        if np.any(tgt_h <= hgt):
            raise ValueError("cluster hierarchy: a geomorph target is removed no higher than its source")
    h.__dict__["_collapse_table"] = (h.morph_target, nxt, removed_at)
    return nxt, removed_at


def chain_targets(nxt: np.ndarray, removed_at: np.ndarray, vertices: np.ndarray, heights) -> np.ndarray:
    """The vertex each of ``vertices`` has collapsed into by a cluster of height ``heights``.

    Follows ``nxt`` while the cluster that removed the current vertex has a
    height <= the given one (numpy; the shader runs the same loop per vertex).

    Parameters
    ----------
    nxt, removed_at : :func:`collapse_table`
    vertices : (m,) int vertex ids; heights : (m,) int or a scalar (negative: no morph)

    Returns
    -------
    (m,) int64 target vertices (the vertex itself where nothing collapsed it)
    """
    x = np.asarray(vertices, np.int64).copy()
    hh = np.broadcast_to(np.asarray(heights, np.int64), x.shape)
    for _ in range(MAX_CHAIN):
        go = removed_at[x] <= hh
        if not go.any():
            return x
        x[go] = nxt[x[go]]
    raise ValueError(f"cluster geomorph: collapse chain longer than {MAX_CHAIN} steps (corrupt hierarchy)")


# ---------------------------------------------------------------------------- union of two cuts
def _sorted_by_leaf(cl: np.ndarray, leaf_lo: np.ndarray) -> np.ndarray:
    return cl[np.argsort(leaf_lo[cl], kind="stable")]


def morph_union_numpy(h, off_a, cl_a, off_b, cl_b):
    """Reference of :func:`morph_union` (plain Python, per instance)."""
    lo = np.asarray(h.leaf_lo, np.int64)
    hi = np.asarray(h.leaf_hi, np.int64)
    ht = np.asarray(h.height, np.int64)
    k = off_a.shape[0] - 1
    out_off = [0]
    out_cl, out_h, out_s = [], [], []
    ok = np.ones(k, bool)
    for i in range(k):
        A = list(_sorted_by_leaf(np.asarray(cl_a[off_a[i]:off_a[i + 1]], np.int64), lo))
        B = list(_sorted_by_leaf(np.asarray(cl_b[off_b[i]:off_b[i + 1]], np.int64), lo))
        ent = []
        ia = ib = 0
        while ia < len(A) or ib < len(B):
            if ib >= len(B) or (ia < len(A) and hi[A[ia]] <= lo[B[ib]]):
                ent.append((A[ia], NO_MORPH, SIDE_A))
                ia += 1
                continue
            if ia >= len(A) or hi[B[ib]] <= lo[A[ia]]:
                ent.append((B[ib], NO_MORPH, SIDE_B))
                ib += 1
                continue
            a, b = A[ia], B[ib]
            if a == b:
                ent.append((a, NO_MORPH, SIDE_A))
                ia += 1
                ib += 1
                continue
            a_coarse = lo[a] <= lo[b] and hi[b] <= hi[a] and ht[a] >= ht[b]
            if a_coarse:
                c, fine, j, side = a, B, ib, SIDE_B
            else:
                c, fine, j, side = b, A, ia, SIDE_A
            covered = 0
            while j < len(fine) and lo[fine[j]] < hi[c]:
                ent.append((fine[j], int(ht[c]), side))
                covered += hi[fine[j]] - lo[fine[j]]
                j += 1
            if covered != hi[c] - lo[c]:
                ok[i] = False
            if a_coarse:
                ia, ib = ia + 1, j
            else:
                ia, ib = j, ib + 1
        out_cl += [e[0] for e in ent]
        out_h += [e[1] for e in ent]
        out_s += [e[2] for e in ent]
        out_off.append(len(out_cl))
    return (np.asarray(out_off, np.int64), np.asarray(out_cl, np.int32), np.asarray(out_h, np.int32),
            np.asarray(out_s, np.int8), ok)


@njit(cache=True)
def _insertion_sort_by(keys, vals, n):  # pragma: no cover - compiled
    for i in range(1, n):
        kv, vv = keys[i], vals[i]
        j = i - 1
        while j >= 0 and keys[j] > kv:
            keys[j + 1] = keys[j]
            vals[j + 1] = vals[j]
            j -= 1
        keys[j + 1] = kv
        vals[j + 1] = vv


@njit(cache=True)
def _union_kernel(lo, hi, ht, off_a, cl_a, off_b, cl_b, out_off, out_cl, out_h, out_s, ok,
                  ka, va, kb, vb):  # pragma: no cover - compiled
    n = 0
    for i in range(off_a.shape[0] - 1):
        na = off_a[i + 1] - off_a[i]
        nb = off_b[i + 1] - off_b[i]
        for j in range(na):
            c = cl_a[off_a[i] + j]
            ka[j] = lo[c]
            va[j] = c
        for j in range(nb):
            c = cl_b[off_b[i] + j]
            kb[j] = lo[c]
            vb[j] = c
        _insertion_sort_by(ka, va, na)  # cuts come in leaf order already: linear
        _insertion_sort_by(kb, vb, nb)
        ia = 0
        ib = 0
        while ia < na or ib < nb:
            # a cluster only one cut draws here (the other's next one lies beyond it), or both the same: unmoved
            only_a = ib >= nb or (ia < na and hi[va[ia]] <= lo[vb[ib]])
            only_b = not only_a and (ia >= na or hi[vb[ib]] <= lo[va[ia]])
            if only_a or only_b or va[ia] == vb[ib]:
                out_cl[n] = vb[ib] if only_b else va[ia]
                out_h[n] = -1
                out_s[n] = 1 if only_b else 0
                n += 1
                if not only_b:
                    ia += 1
                if not only_a:
                    ib += 1
                continue
            a = va[ia]
            b = vb[ib]
            a_coarse = lo[a] <= lo[b] and hi[b] <= hi[a] and ht[a] >= ht[b]
            # the finer side's clusters inside the coarse one morph towards it
            if a_coarse:
                c, fv, fn, j, side = a, vb, nb, ib, 1
            else:
                c, fv, fn, j, side = b, va, na, ia, 0
            covered = 0
            while j < fn and lo[fv[j]] < hi[c]:
                out_cl[n] = fv[j]
                out_h[n] = ht[c]
                out_s[n] = side
                n += 1
                covered += hi[fv[j]] - lo[fv[j]]
                j += 1
            if a_coarse:
                ia += 1
                ib = j
            else:
                ib += 1
                ia = j
            if covered != hi[c] - lo[c]:
                ok[i] = False
        out_off[i + 1] = n


def morph_union(h, off_a, cl_a, off_b, cl_b):
    """Union of two CSR cuts of the same instances, per part of the mesh the finer cluster
    with its morph target (module docstring).

    Parameters
    ----------
    h : lod.clusters.dag.ClusterHierarchy
    off_a, cl_a : (k+1,) int64, int32 cut A (keyframe i) per instance
    off_b, cl_b : the same instances' cut B (keyframe i+1)

    Returns
    -------
    offsets : (k+1,) int64; clusters : (E,) int32 the union per instance, in leaf order
    heights : (E,) int32 height of the coarse cluster each entry morphs towards,
        :data:`NO_MORPH` (-1) for an entry both cuts draw or only one draws
    sides : (E,) int8 :data:`SIDE_A` (the entry is A's; blend weight t) or
        :data:`SIDE_B` (B's; blend weight 1 - t)
    ok : (k,) bool, False where a coarse cluster's region is only partly drawn by
        the other cut (frustum-culled clusters): that instance cannot morph
    """
    off_a = np.asarray(off_a, np.int64)
    off_b = np.asarray(off_b, np.int64)
    if off_a.shape != off_b.shape:
        raise ValueError(f"morph_union: cuts of {off_a.shape[0] - 1} and {off_b.shape[0] - 1} instances")
    k = off_a.shape[0] - 1
    cl_a = np.asarray(cl_a, np.int32)
    cl_b = np.asarray(cl_b, np.int32)
    n_max = int(cl_a.shape[0] + cl_b.shape[0])
    out_off = np.zeros(k + 1, np.int64)
    out_cl = np.empty(n_max, np.int32)
    out_h = np.empty(n_max, np.int32)
    out_s = np.empty(n_max, np.int8)
    ok = np.ones(k, np.bool_)
    wa = max(int(np.diff(off_a).max()) if k else 0, 1)
    wb = max(int(np.diff(off_b).max()) if k else 0, 1)
    if k:
        _union_kernel(np.asarray(h.leaf_lo, np.int64), np.asarray(h.leaf_hi, np.int64),
                      np.asarray(h.height, np.int64), off_a, cl_a, off_b, cl_b, out_off, out_cl, out_h, out_s, ok,
                      np.empty(wa, np.int64), np.empty(wa, np.int32), np.empty(wb, np.int64), np.empty(wb, np.int32))
    n = int(out_off[-1])
    return out_off, out_cl[:n].copy(), out_h[:n].copy(), out_s[:n].copy(), ok


def entry_weights(sides: np.ndarray, heights: np.ndarray, t: float) -> np.ndarray:
    """(E,) float32 blend weight of each union entry at the frame weight ``t``: t for A's
    entries, 1 - t for B's, 0 for entries drawn unmoved."""
    t = float(min(1.0, max(0.0, t)))
    w = np.where(np.asarray(sides) == SIDE_A, t, 1.0 - t).astype(np.float32)
    w[np.asarray(heights) < 0] = 0.0
    return w


def _rows_csr(offsets: np.ndarray, rows: np.ndarray):
    """(offsets, entry index) of the CSR rows ``rows``."""
    lens = offsets[rows + 1] - offsets[rows]
    out = np.zeros(rows.shape[0] + 1, np.int64)
    np.cumsum(lens, out=out[1:])
    src = np.repeat(offsets[rows] - out[:-1], lens) + np.arange(int(out[-1]))
    return out, src


def morph_batch(h, a, b, t: float):
    """The geomorphed batch of two cluster-cut batches of the same instances (module docstring).

    Parameters
    ----------
    h : the hierarchy both cuts belong to
    a, b : ``lod.clusters.mode.ClusterDrawBatch`` (or any batch with CSR ``offsets`` /
        ``clusters``) drawing the same instance rows, in the same order, with cut A
        (keyframe i) and cut B (keyframe i+1); ``a`` gives the instance data
    t : the frame's weight in [0, 1] (0 = A, 1 = B)

    Returns
    -------
    batch : a shallow copy of ``a`` restricted to the morphable rows, its cuts replaced by
        the unions, with ``morph_height`` / ``morph_weight`` per entry and the union's
        triangle count; None when no row can morph
    ok : (k,) bool the rows ``batch`` holds (the others need a fade; all of them for a hierarchy
        taller than :data:`MAX_CHAIN` - 1)
    """
    if h.height.size and int(h.height.max()) >= MAX_CHAIN:  # chains the shader could not follow to the end
        return None, np.zeros(a.n_instances, bool)
    off, cl, hs, sd, ok = morph_union(h, a.offsets, a.clusters, b.offsets, b.clusters)
    if not ok.any():
        return None, ok
    w = entry_weights(sd, hs, t)
    if not ok.all():
        rows = np.flatnonzero(ok)
        off, src = _rows_csr(off, rows)
        cl, hs, w = cl[src], hs[src], w[src]
    else:
        rows = None
    out = copy.copy(a)
    if rows is not None:
        out.instance_ids = np.asarray(a.instance_ids)[rows]
        out.instance_data = np.asarray(a.instance_data)[rows]
    out.offsets, out.clusters = off, cl
    out.morph_height, out.morph_weight = hs, w
    out.fade = None
    out.triangles = int(np.diff(np.asarray(h.tri_start, np.int64))[cl].sum()) if cl.size else 0
    out.points = 0
    return out, ok


def morphed_triangle_positions(h, positions: np.ndarray, clusters, heights, weights) -> np.ndarray:
    """(T, 3, 3) float64 corners of the triangles of union entries as the morph draws them.

    Parameters
    ----------
    h : the hierarchy; positions : (V, 3) skinned vertex positions of one pose
    clusters, heights, weights : one instance's union entries (:func:`morph_union`,
        :func:`entry_weights`)
    """
    nxt, removed_at = collapse_table(h)
    X = np.asarray(positions, np.float64)
    parts = []
    for c, hh, w in zip(np.asarray(clusters), np.asarray(heights), np.asarray(weights)):
        tri = np.asarray(h.cluster_triangles(int(c)), np.int64)
        if tri.size == 0:
            continue
        v = tri.reshape(-1)
        x = chain_targets(nxt, removed_at, v, int(hh)) if hh >= 0 else v
        p = (1.0 - float(w)) * X[v] + float(w) * X[x]
        parts.append(p.reshape(-1, 3, 3))
    return np.concatenate(parts) if parts else np.zeros((0, 3, 3))


__all__ = ["NEVER_REMOVED", "NO_MORPH", "SIDE_A", "SIDE_B", "collapse_table", "chain_targets", "morph_union",
           "morph_union_numpy", "entry_weights", "morph_batch", "morphed_triangle_positions"]
