"""Errors of a simplified mesh measured against the original in every pose
(VDR-AM §5.1): vertex-to-surface distances, the distance of a collapse chain,
and the normal-compatible cluster Hausdorff distance, each a numba kernel
beside a numpy reference.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

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


#: a vertex normal shorter than this fraction of the summed lengths of its face normals has no facing (the
#: faces cancel: a sheet drawn from both sides on shared vertices) and is set to 0
NORMAL_CANCEL_FRACTION = 1e-6


@njit(cache=True)
def _vertex_normals(X, tris, out):  # pragma: no cover - compiled
    mag = np.zeros(X.shape[1])
    for p in range(X.shape[0]):
        mag[:] = 0.0
        for f in range(tris.shape[0]):
            a, b, c = tris[f, 0], tris[f, 1], tris[f, 2]
            nx, ny, nz = _face_normal(X, p, tris, f)
            ln = np.sqrt(nx * nx + ny * ny + nz * nz)
            for v in (a, b, c):
                out[p, v, 0] += nx
                out[p, v, 1] += ny
                out[p, v, 2] += nz
                mag[v] += ln
        for v in range(X.shape[1]):
            ln = np.sqrt(out[p, v, 0] ** 2 + out[p, v, 1] ** 2 + out[p, v, 2] ** 2)
            if ln > NORMAL_CANCEL_FRACTION * mag[v] and ln > 0.0:
                out[p, v, 0] /= ln
                out[p, v, 1] /= ln
                out[p, v, 2] /= ln
            else:
                out[p, v, 0] = out[p, v, 1] = out[p, v, 2] = 0.0


def vertex_normals(positions_per_pose: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(P, V, 3) float64 unit area-weighted vertex normals of a mesh in every pose; 0 for unused vertices, for
    vertices whose triangles all have zero area and for vertices whose face normals cancel
    (:data:`NORMAL_CANCEL_FRACTION`): those have no facing (:func:`cluster_hausdorff`)."""
    X = np.ascontiguousarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    t = np.ascontiguousarray(np.asarray(indices, np.int64).reshape(-1, 3))
    out = np.zeros(X.shape)
    if t.size:
        _vertex_normals(X, t, out)
    return out


def vertex_normals_numpy(positions_per_pose: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """numpy reference of :func:`vertex_normals` (same rule for missing and cancelling normals)."""
    X = np.asarray(positions_per_pose, np.float64)
    if X.ndim == 2:
        X = X[None]
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    fn = np.cross(X[:, t[:, 1]] - X[:, t[:, 0]], X[:, t[:, 2]] - X[:, t[:, 0]])  # (P, T, 3)
    out = np.zeros(X.shape)
    mag = np.zeros(X.shape[:2])
    for k in range(3):
        for p in range(X.shape[0]):
            np.add.at(out[p], t[:, k], fn[p])
            np.add.at(mag[p], t[:, k], np.linalg.norm(fn[p], axis=1))
    ln = np.linalg.norm(out, axis=2)
    ok = (ln > NORMAL_CANCEL_FRACTION * mag) & (ln > 0.0)
    return np.where(ok[..., None], out / np.where(ok, ln, 1.0)[..., None], 0.0)


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
            nx, ny, nz = 0.0, 0.0, 0.0
            if use_n:
                nx, ny, nz = vnorm[p, v, 0], vnorm[p, v, 1], vnorm[p, v, 2]
            # a vertex without a facing (only zero-area triangles around it, or a two-sided sheet on shared
            # vertices whose normals cancel) is compatible with every triangle: the plain distance
            un = use_n and nx * nx + ny * ny + nz * nz > 0.0
            if not un and local[v] >= 0:
                continue  # a vertex of the simplified surface: distance 0
            best = np.inf
            if lr >= 0:
                for q in range(fan_ptr[lr], fan_ptr[lr + 1]):
                    f = fan[q] // 3
                    if un and fnrm[p, f, 0] * nx + fnrm[p, f, 1] * ny + fnrm[p, f, 2] * nz <= cos_min:
                        continue
                    d = _tri_d2(X, p, px, py, pz, tris, f)
                    if d < best:
                        best = d
            if best <= fwd:
                continue  # cannot raise the maximum
            sb = np.sqrt(best) if best < np.inf else np.inf
            for f in range(m):
                if un and fnrm[p, f, 0] * nx + fnrm[p, f, 1] * ny + fnrm[p, f, 2] * nz <= cos_min:
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
            if best == np.inf and un:
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
    gone from the image). A vertex without a facing (:func:`vertex_normals` gives
    0: only zero-area triangles around it, or a sheet drawn from both sides on
    shared vertices) measures the plain distance. This is what bounds the *rendered* silhouette: the
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
