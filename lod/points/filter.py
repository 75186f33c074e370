"""Attribute prefiltering of representative samples (Wand & Straßer 2002, §3.5).

The stratified points R of a node stand for all the surface around them, so
their colour and normal should be an average of that surface rather than the
value at one random spot (which would flicker as the level of detail changes).

Notes
-----
Wand & Straßer, *Multi-Resolution Rendering of Complex Animated Scenes*,
Eurographics 2002, §3.5: a denser, unstratified sample set F is drawn on the
same triangles; a radial 3-D Gaussian around each point of R weights the
attributes of the neighbouring points of F (found with a spatial grid); the
filtered attributes are computed at the start and at the end of the keyframe
pair and blended linearly in time (the blend happens at render time, like the
positions).

Departures:

* F is drawn with the triangles' *maximum* areas (the candidate sampler), so
  its density at time u is not uniform; each F point is weighted by
  ``area(u) / max_area`` of its triangle, which makes the weighted set uniform
  per unit area at the filtered time.
* The size of F is ``POINTS_FILTER_FACTOR * n`` (n the number of
  coupon-collector bins of the node, default 10 n, about 25x the kept points)
  instead of ten times the candidate count (10 * safety * n ln n), which would
  dominate the build time; with sigma = r/4 cut at 2 sigma a kernel still sees
  about 90 points of F on a flat surface.
* The filtered normal is the principal axis of the normals' weighted second
  moment ``M = sum w n n^T / sum w`` (its eigenvector of the largest
  eigenvalue), turned towards their weighted mean, not the renormalised mean.
  The renderer lights both sides of a surface alike (``|n . l|``, ``|n . v|``:
  render/shaders/world/light.glsl), so the light a set of normals receives is
  ``E|n . x| <= sqrt(x^T M x)``, which the principal axis keeps where the
  normals are (near) one axis, while the mean of opposite normals (a thin
  sheet, the front and back of a body in one coarse node) cancels and its
  renormalised remnant points anywhere (lit as if seen edge-on). Measured on
  the shipped scenes the change is small (stadium frame 0 within 0.01 dB of
  the renormalised mean): their coarse nodes rarely span both sides.
* A point with no point of F inside its kernel keeps its own interpolated
  attributes; a degenerate moment (no weight, zero normals) falls back to the
  point's own normal, then to +Y, so no NaN is produced.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from lod.points.stratify import _grid


@njit(cache=True, nogil=True)
def _bary_kernel(a, tri, bary, out):  # pragma: no cover - compiled
    for i in range(tri.shape[0]):
        k = tri[i]
        b1 = bary[i, 0]
        b2 = bary[i, 1]
        b0 = 1.0 - b1 - b2
        for c in range(a.shape[2]):
            out[i, c] = b0 * a[k, 0, c] + b1 * a[k, 1, c] + b2 * a[k, 2, c]
    return out


def barycentric_attribute(corner_attr: np.ndarray, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(N, C) float64 attribute of barycentric samples (numba).

    corner_attr : (T, 3, C) per-corner attribute; tri : (N,) int; bary : (N, 2).
    Equals ``(1 - b1 - b2) a[tri, 0] + b1 a[tri, 1] + b2 a[tri, 2]``.
    """
    a = np.ascontiguousarray(corner_attr, np.float64)
    out = np.empty((tri.shape[0], a.shape[2]))
    if tri.shape[0]:
        _bary_kernel(a, np.ascontiguousarray(tri, np.int64), np.ascontiguousarray(bary, np.float64), out)
    return out


def _unit(n, fb):
    """Rows of ``n`` made unit length; rows too short take ``fb``'s row (then +Y)."""
    ln = np.linalg.norm(n, axis=1)
    good = ln > 1e-12
    n = np.where(good[:, None], n / np.where(good, ln, 1.0)[:, None], fb)
    ln = np.linalg.norm(n, axis=1)
    good = ln > 1e-12
    return np.where(good[:, None], n / np.where(good, ln, 1.0)[:, None], np.array([0.0, 1.0, 0.0]))


#: index pairs of the 6 second-moment components (xx, xy, xz, yy, yz, zz)
_MOMENT = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def principal_normal(mom, mean, fb) -> np.ndarray:
    """(R, 3) unit principal axes of normal second moments ``mom`` (R, 6: xx, xy, xz, yy, yz, zz), signed
    towards ``mean`` (R, 3; where the axis is perpendicular to it, towards ``fb``); rows whose moment has no
    largest direction (all zero) take ``fb`` (then +Y)."""
    mom = np.asarray(mom, np.float64).reshape(-1, 6)
    R = mom.shape[0]
    M = np.zeros((R, 3, 3))
    for k, (i, j) in enumerate(_MOMENT):
        M[:, i, j] = M[:, j, i] = mom[:, k]
    fb = _unit(np.asarray(fb, np.float64).reshape(-1, 3), np.array([0.0, 1.0, 0.0]))
    if R == 0:
        return fb
    ok = np.isfinite(M).all(axis=(1, 2)) & (np.abs(M).sum(axis=(1, 2)) > 1e-30)
    axis = fb.copy()
    if ok.any():
        _, vec = np.linalg.eigh(M[ok])  # ascending eigenvalues: the last column is the principal axis
        axis[ok] = vec[:, :, 2]
    m = np.asarray(mean, np.float64).reshape(-1, 3)
    d = (axis * m).sum(1)
    d = np.where(np.abs(d) > 1e-9 * np.maximum(np.linalg.norm(m, axis=1), 1e-300), d, (axis * fb).sum(1))
    return _unit(np.where((d < 0.0)[:, None], -axis, axis), fb)


def _finish(col_sum, nrm_sum, mom_sum, wsum, fb_col, fb_nrm):
    """Normalise weighted sums with the documented fallbacks (numpy)."""
    ok = wsum > 0.0
    col = np.where(ok[:, None], col_sum / np.where(ok, wsum, 1.0)[:, None], fb_col)
    fb = _unit(np.asarray(fb_nrm, np.float64), np.array([0.0, 1.0, 0.0]))
    n = principal_normal(np.where(ok[:, None], mom_sum, 0.0), np.where(ok[:, None], nrm_sum, 0.0), fb)
    return col, n


def gaussian_filter_numpy(rep_pos, f_pos, f_col, f_nrm, f_w, sigma, fb_col, fb_nrm):
    """Reference Gaussian filter at one time (dense distances, small inputs).

    Parameters
    ----------
    rep_pos : (R, 3) float64 representative positions
    f_pos : (F, 3) float64 filter-set positions; f_col : (F, C) colours;
    f_nrm : (F, 3) normals; f_w : (F,) density weights >= 0
    sigma : float > 0; the kernel is cut off at 2 sigma
    fb_col : (R, C), fb_nrm : (R, 3) fallbacks

    Returns
    -------
    col : (R, C) float64, nrm : (R, 3) float64 unit.
    """
    d2 = ((np.asarray(rep_pos)[:, None, :] - np.asarray(f_pos)[None, :, :]) ** 2).sum(-1)
    cut2 = (2.0 * sigma) ** 2
    w = np.where(d2 <= cut2, np.exp(-d2 / (2.0 * sigma * sigma)), 0.0) * np.asarray(f_w)[None, :]
    f_nrm = np.asarray(f_nrm, np.float64)
    mom = np.stack([f_nrm[:, i] * f_nrm[:, j] for i, j in _MOMENT], 1)
    return _finish(w @ f_col, w @ f_nrm, w @ mom, w.sum(1), fb_col, fb_nrm)


@njit(cache=True, nogil=True)
def _filter_kernel(rep_pos, f_pos, f_col, f_nrm, f_w, sigma, col_sum, nrm_sum, mom_sum, wsum):  # pragma: no cover
    cut = 2.0 * sigma
    cut2 = cut * cut
    inv = 1.0 / (2.0 * sigma * sigma)
    lo, dims, start, ids, cell, _ = _grid(f_pos, cut)
    C = f_col.shape[1]
    near = np.empty(f_pos.shape[0] + 1, np.int64)  # + 1: the slot written after the last hit
    dist = np.empty(f_pos.shape[0] + 1)
    for i in range(rep_pos.shape[0]):
        px = rep_pos[i, 0]
        py = rep_pos[i, 1]
        pz = rep_pos[i, 2]
        fx = (px - lo[0]) / cell
        fy = (py - lo[1]) / cell
        fz = (pz - lo[2]) / cell
        if fx < -1.0 or fy < -1.0 or fz < -1.0 or fx > dims[0] + 1.0 or fy > dims[1] + 1.0 or fz > dims[2] + 1.0:
            continue
        ix = int(math.floor(fx))
        iy = int(math.floor(fy))
        iz = int(math.floor(fz))
        # the F points within the cut-off, in scan order (branch-free: the
        # test outcome is unpredictable), then their weighted sums in that order
        cnt = 0
        for x in range(max(ix - 1, 0), min(ix + 2, dims[0])):
            for y in range(max(iy - 1, 0), min(iy + 2, dims[1])):
                for z in range(max(iz - 1, 0), min(iz + 2, dims[2])):
                    cc = (x * dims[1] + y) * dims[2] + z
                    for s in range(start[cc], start[cc + 1]):
                        j = ids[s]
                        d0 = px - f_pos[j, 0]
                        d1 = py - f_pos[j, 1]
                        d2 = pz - f_pos[j, 2]
                        dd = d0 * d0 + d1 * d1 + d2 * d2
                        near[cnt] = j
                        dist[cnt] = dd
                        cnt += dd <= cut2
        for q in range(cnt):
            j = near[q]
            w = math.exp(-dist[q] * inv) * f_w[j]
            if w <= 0.0:
                continue
            for c in range(C):
                col_sum[i, c] += w * f_col[j, c]
            nx = f_nrm[j, 0]
            ny = f_nrm[j, 1]
            nz = f_nrm[j, 2]
            nrm_sum[i, 0] += w * nx
            nrm_sum[i, 1] += w * ny
            nrm_sum[i, 2] += w * nz
            mom_sum[i, 0] += w * nx * nx
            mom_sum[i, 1] += w * nx * ny
            mom_sum[i, 2] += w * nx * nz
            mom_sum[i, 3] += w * ny * ny
            mom_sum[i, 4] += w * ny * nz
            mom_sum[i, 5] += w * nz * nz
            wsum[i] += w


def gaussian_filter(rep_pos, f_pos, f_col, f_nrm, f_w, sigma, fb_col, fb_nrm):
    """Gaussian-weighted colour and (principal-axis) normal of representative points (§3.5, numba).

    Same parameters and results as :func:`gaussian_filter_numpy`; the neighbour
    query uses a grid with cell 2 sigma over F.
    """
    rep_pos = np.ascontiguousarray(rep_pos, np.float64).reshape(-1, 3)
    f_pos = np.ascontiguousarray(f_pos, np.float64).reshape(-1, 3)
    f_col = np.ascontiguousarray(f_col, np.float64)
    f_nrm = np.ascontiguousarray(f_nrm, np.float64).reshape(-1, 3)
    f_w = np.ascontiguousarray(f_w, np.float64).reshape(-1)
    R = rep_pos.shape[0]
    C = f_col.shape[1] if f_col.ndim == 2 else np.asarray(fb_col).shape[1]
    col_sum = np.zeros((R, C))
    nrm_sum = np.zeros((R, 3))
    mom_sum = np.zeros((R, 6))
    wsum = np.zeros(R)
    if R and f_pos.shape[0] and sigma > 0.0:
        _filter_kernel(rep_pos, f_pos, f_col, f_nrm, f_w, float(sigma), col_sum, nrm_sum, mom_sum, wsum)
    return _finish(col_sum, nrm_sum, mom_sum, wsum, np.asarray(fb_col, np.float64),
                   np.asarray(fb_nrm, np.float64))


def filter_set(areas: np.ndarray, filter_count: int, rng: np.random.Generator):
    """The filter set F of a node: ``filter_count`` samples by maximum area
    (``lod.points.sampling.sample_triangles``), (tri, bary)."""
    from lod.points.sampling import sample_triangles

    return sample_triangles(areas, int(filter_count), rng)


def filter_points(v0, v1, col0, col1, nrm0, nrm1, areas, rep_tri, rep_bary, spacing, rng,
                  filter_count: int, sigma_fraction: float, gaussian=gaussian_filter, f_set=None):
    """Filtered start and end attributes of a node's kept points (§3.5).

    Parameters
    ----------
    v0, v1 : (T, 3, 3) float64 triangle corners at u = 0 and 1
    col0, col1 : (T, 3, C) float64 corner colours at u = 0 and 1
    nrm0, nrm1 : (T, 3, 3) float64 corner normals at u = 0 and 1
    areas : (T,) float64 maximum areas (sampling weights of F)
    rep_tri : (R,) int, rep_bary : (R, 2) float64 the kept points
    spacing : float, node spacing r; sigma = ``sigma_fraction * r``
    rng : numpy Generator (draws F; unused when ``f_set`` is given)
    filter_count : int, size of F
    gaussian : the filter implementation (numba default; tests pass the
        numpy reference)
    f_set : None or F drawn beforehand by :func:`filter_set` (the octree
        draws every node's randomness in one thread, then filters in
        parallel; the kernels release the GIL)

    Returns
    -------
    (col_start (R, C), col_end (R, C), nrm_start (R, 3), nrm_end (R, 3)),
    float64, normals unit length.
    """
    from lod.points.sampling import triangle_area_at

    f_tri, f_bary = filter_set(areas, filter_count, rng) if f_set is None else f_set
    sigma = float(sigma_fraction) * float(spacing)
    out = []
    safe = np.where(areas > 0.0, areas, 1.0)
    for u, v, col, nrm in ((0.0, v0, col0, nrm0), (1.0, v1, col1, nrm1)):
        rp = barycentric_attribute(v, rep_tri, rep_bary)
        fb_c = barycentric_attribute(col, rep_tri, rep_bary)
        fb_n = barycentric_attribute(nrm, rep_tri, rep_bary)
        fp = barycentric_attribute(v, f_tri, f_bary)
        fc = barycentric_attribute(col, f_tri, f_bary)
        fn = barycentric_attribute(nrm, f_tri, f_bary)
        w = (triangle_area_at(v0, v1, u) / safe)[f_tri]
        out.append(gaussian(rp, fp, fc, fn, w, sigma, fb_c, fb_n))
    (c0, n0), (c1, n1) = out
    return c0, c1, n0, n1
