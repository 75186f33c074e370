"""Candidate sample sets for moving triangles (Wand & Straßer 2002, §3.4.1).

Between two keyframes every vertex moves on a straight line with constant
speed, ``p(u) = (1 - u) p0 + u p1`` for ``u`` in [0, 1]. A triangle's area then
changes over time; the paper samples each triangle with probability
proportional to its *maximum* area over the interval, so that the
coupon-collector argument ("every bin of area h^2 receives a sample") holds at
every time, whatever the motion.

Notes
-----
Wand & Straßer, *Multi-Resolution Rendering of Complex Animated Scenes*,
Eurographics 2002, §3.4.1 and the correction at the end of the paper: the
*squared* area is a polynomial of degree 4 in u (not the area itself), so the
maximum is found among the interval ends and the real roots of the cubic
derivative of the squared area. This module finds those roots without a
closed-form cubic formula: the stationary points of the cubic split [0, 1] into
pieces where it is monotone, and a sign change in a piece is bisected to
machine precision. That is exact to rounding and robust when the leading
coefficients vanish (pure translation, uniform scaling, degenerate triangles).

Samples are stored as (triangle id, two barycentric coordinates), fixed on the
surface, so they move with it: a sample's position at u is the barycentric
combination of the triangle's interpolated vertices.

Number of candidates: bins are voxels of side ``h = r / (2 sqrt 3)`` (the
paper sets the maximum sample distance r to two voxel diagonals), a piece of
surface covering a voxel has area at least h^2, so there are at most
``n = A_max / h^2`` bins and ``safety * n * ln n`` random samples hit them all
with high probability (§3.4.1, coupon collector).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from lod.points.config import POINTS_BIN_RATIO, POINTS_MAX_CANDIDATES, POINTS_SAFETY_FACTOR

# --------------------------------------------------------------------------- geometry helpers

def triangle_vertices(p: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(T, 3, 3) float64 corner positions ``p[indices]``.

    p : (V, 3) float; indices : (T, 3) int.
    """
    p = np.asarray(p, np.float64).reshape(-1, 3)
    idx = np.asarray(indices, np.int64).reshape(-1, 3)
    return p[idx]


def squared_area_coefficients(v0: np.ndarray, v1: np.ndarray) -> np.ndarray:
    """Coefficients of the squared doubled area ``|e1(u) x e2(u)|^2``.

    Parameters
    ----------
    v0, v1 : (T, 3, 3) float64 triangle corners at u = 0 and u = 1.

    Returns
    -------
    (T, 5) float64 ``c`` with ``|e1 x e2|^2 = sum_k c[:, k] u^k`` (the area is
    half the square root of that).

    Notes
    -----
    With edges ``e(u) = e0 + u de`` the cross product is ``C0 + u C1 + u^2 C2``
    (C0 = e1 x e2, C1 = e1 x de2 + de1 x e2, C2 = de1 x de2), and its squared
    norm is a quartic (paper correction, §3.4.1).
    """
    v0 = np.asarray(v0, np.float64).reshape(-1, 3, 3)
    v1 = np.asarray(v1, np.float64).reshape(-1, 3, 3)
    e1 = v0[:, 1] - v0[:, 0]
    e2 = v0[:, 2] - v0[:, 0]
    d1 = (v1[:, 1] - v1[:, 0]) - e1
    d2 = (v1[:, 2] - v1[:, 0]) - e2
    c0 = np.cross(e1, e2)
    c1 = np.cross(e1, d2) + np.cross(d1, e2)
    c2 = np.cross(d1, d2)
    dot = lambda a, b: np.einsum("ij,ij->i", a, b)  # noqa: E731
    out = np.empty((v0.shape[0], 5))
    out[:, 0] = dot(c0, c0)
    out[:, 1] = 2.0 * dot(c0, c1)
    out[:, 2] = dot(c1, c1) + 2.0 * dot(c0, c2)
    out[:, 3] = 2.0 * dot(c1, c2)
    out[:, 4] = dot(c2, c2)
    return out


def triangle_area_at(v0: np.ndarray, v1: np.ndarray, u: float) -> np.ndarray:
    """(T,) float64 areas of the interpolated triangles at time u in [0, 1]."""
    v0 = np.asarray(v0, np.float64).reshape(-1, 3, 3)
    v1 = np.asarray(v1, np.float64).reshape(-1, 3, 3)
    v = (1.0 - u) * v0 + u * v1
    return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)


# --------------------------------------------------------------------------- maximum area

def max_area_numpy(v0: np.ndarray, v1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference: maximum area over u in [0, 1] via ``np.roots`` per triangle.

    Parameters
    ----------
    v0, v1 : (T, 3, 3) float64 corners at u = 0 and u = 1.

    Returns
    -------
    area : (T,) float64 maximum area; u : (T,) float64 a time where it occurs.
    """
    c = squared_area_coefficients(v0, v1)
    T = c.shape[0]
    area = np.zeros(T)
    when = np.zeros(T)
    for i in range(T):
        q = c[i]
        cand = [0.0, 1.0]
        d = np.array([4 * q[4], 3 * q[3], 2 * q[2], q[1]])  # highest power first
        nz = np.flatnonzero(np.abs(d) > 0)
        if nz.size and nz[0] < 3:
            for rt in np.roots(d[nz[0]:]):
                if abs(rt.imag) < 1e-9 and 0.0 < rt.real < 1.0:
                    cand.append(float(rt.real))
        cand = np.array(cand)
        vals = np.polyval(q[::-1], cand)
        k = int(np.argmax(vals))
        area[i] = 0.5 * math.sqrt(max(vals[k], 0.0))
        when[i] = cand[k]
    return area, when


@njit(cache=True)
def _poly4(c0, c1, c2, c3, c4, u):  # pragma: no cover - compiled
    return (((c4 * u + c3) * u + c2) * u + c1) * u + c0


@njit(cache=True)
def _dpoly4(c1, c2, c3, c4, u):  # pragma: no cover - compiled
    return ((4.0 * c4 * u + 3.0 * c3) * u + 2.0 * c2) * u + c1


@njit(cache=True)
def _max_area_kernel(coef, area, when):  # pragma: no cover - compiled
    T = coef.shape[0]
    br = np.empty(4)
    for i in range(T):
        c0 = coef[i, 0]
        c1 = coef[i, 1]
        c2 = coef[i, 2]
        c3 = coef[i, 3]
        c4 = coef[i, 4]
        # stationary points of the cubic derivative D(u): roots of 12c4 u^2 + 6c3 u + 2c2
        nb = 0
        br[nb] = 0.0
        nb += 1
        A = 12.0 * c4
        B = 6.0 * c3
        C = 2.0 * c2
        r1 = -1.0
        r2 = -1.0
        if A != 0.0:
            disc = B * B - 4.0 * A * C
            if disc >= 0.0:
                s = math.sqrt(disc)
                q = -0.5 * (B + s) if B >= 0.0 else -0.5 * (B - s)
                r1 = q / A
                if q != 0.0:
                    r2 = C / q
        elif B != 0.0:
            r1 = -C / B
        if r1 > r2:
            r1, r2 = r2, r1
        if 0.0 < r1 < 1.0:
            br[nb] = r1
            nb += 1
        if 0.0 < r2 < 1.0 and r2 != r1:
            br[nb] = r2
            nb += 1
        br[nb] = 1.0
        nb += 1
        best_u = 0.0
        best = _poly4(c0, c1, c2, c3, c4, 0.0)
        v = _poly4(c0, c1, c2, c3, c4, 1.0)
        if v > best:
            best = v
            best_u = 1.0
        for k in range(nb - 1):
            a = br[k]
            b = br[k + 1]
            da = _dpoly4(c1, c2, c3, c4, a)
            db = _dpoly4(c1, c2, c3, c4, b)
            # a maximum of Q needs D to go from + to -
            if da > 0.0 and db < 0.0:
                for _ in range(200):
                    m = 0.5 * (a + b)
                    if m <= a or m >= b:
                        break
                    if _dpoly4(c1, c2, c3, c4, m) > 0.0:
                        a = m
                    else:
                        b = m
                m = 0.5 * (a + b)
                v = _poly4(c0, c1, c2, c3, c4, m)
                if v > best:
                    best = v
                    best_u = m
        area[i] = 0.5 * math.sqrt(best) if best > 0.0 else 0.0
        when[i] = best_u
    return area, when


def max_area(v0: np.ndarray, v1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Maximum area of linearly moving triangles over u in [0, 1] (§3.4.1).

    Parameters
    ----------
    v0, v1 : (T, 3, 3) float corners at u = 0 and u = 1 (see
        :func:`triangle_vertices`).

    Returns
    -------
    area : (T,) float64, the exact maximum of the area (to rounding); zero for
        triangles that stay degenerate; never NaN for finite input.
    u : (T,) float64 in [0, 1], a time at which it is reached.

    Raises
    ------
    ValueError if the shapes differ or a coordinate is not finite.
    """
    v0 = np.asarray(v0, np.float64).reshape(-1, 3, 3)
    v1 = np.asarray(v1, np.float64).reshape(-1, 3, 3)
    if v0.shape != v1.shape:
        raise ValueError(f"max_area: start and end corners differ in shape, {v0.shape} vs {v1.shape}")
    if not (np.isfinite(v0).all() and np.isfinite(v1).all()):
        raise ValueError("max_area: triangle corners must be finite, got NaN or Inf")
    coef = squared_area_coefficients(v0, v1)
    area = np.zeros(v0.shape[0])
    when = np.zeros(v0.shape[0])
    if v0.shape[0]:
        _max_area_kernel(coef, area, when)
    return area, when


# --------------------------------------------------------------------------- candidates

def candidate_count(total_area: float, spacing: float, safety: float = POINTS_SAFETY_FACTOR,
                    cap: int = POINTS_MAX_CANDIDATES) -> int:
    """Number of random candidates for a node (coupon collector, §3.4.1).

    Parameters
    ----------
    total_area : float, sum of the maximum areas of the node's triangles (m^2)
    spacing : float, maximum sample distance r of the node (m)
    safety : float > 0, the constant factor (paper: 3 or 5)
    cap : int, upper bound (see ``POINTS_MAX_CANDIDATES``)

    Returns
    -------
    int ``ceil(safety * n * max(ln n, 1))`` with ``n = ceil(A / h^2)`` bins of
    side ``h = r / (2 sqrt 3)``; 0 when the area or spacing is zero.
    """
    if not (total_area > 0.0 and spacing > 0.0) or not math.isfinite(total_area / spacing):
        return 0
    h = spacing * POINTS_BIN_RATIO
    n = math.ceil(total_area / (h * h))
    k = math.ceil(safety * n * max(math.log(n), 1.0))
    return int(min(k, cap))


def interval_areas(v0: np.ndarray, v1: np.ndarray, times) -> np.ndarray:
    """(m, T) float64 maximum area of every triangle within each time interval.

    v0, v1 : (T, 3, 3) corners at u = 0 and 1; times : (m + 1,) increasing
    interval boundaries in [0, 1]. The corners move linearly, so within
    [t_j, t_j+1] the triangle is the linear blend of its corners at the two
    ends and :func:`max_area` of those gives its largest area there.
    """
    t = np.asarray(times, np.float64)
    v0 = np.asarray(v0, np.float64)
    v1 = np.asarray(v1, np.float64)
    out = np.empty((t.shape[0] - 1, v0.shape[0]))
    for j in range(t.shape[0] - 1):
        a = (1.0 - t[j]) * v0 + t[j] * v1
        b = (1.0 - t[j + 1]) * v0 + t[j + 1] * v1
        out[j] = max_area(a, b)[0]
    return out


def interval_thinning(areas: np.ndarray, interval_area: np.ndarray, spacing: float,
                      safety: float = POINTS_SAFETY_FACTOR) -> np.ndarray:
    """(m, T) float64 probability of keeping a candidate of each triangle for each time interval.

    The candidates of a node are drawn once for the keyframe pair, ``candidate_count(sum A)``
    of them in proportion to every triangle's maximum area A over the pair (§3.4.1). An
    interval j whose triangles are smaller (a shrinking surface) needs only
    ``candidate_count(sum A_j)`` candidates in proportion to A_j, its own maximum areas
    (the coupon-collector argument applied to that interval); keeping each candidate of
    triangle t with probability ``p_j(t) = (A_j(t) / A(t)) * (N_j / sum A_j) / (N / sum A)``
    (rejection sampling) turns the shared set into exactly such a draw. A denser set
    than that covers no better but leaves more points after the greedy stratification (it
    converges to a packing with more points: 2.59 instead of 2.47 points per r^2 on a static
    sphere at 10x the density), so thinning lowers the counts of the small-area intervals.

    Parameters
    ----------
    areas : (T,) maximum areas over the keyframe pair (:func:`max_area`)
    interval_area : (m, T) maximum areas within each interval (:func:`interval_areas`)
    spacing, safety : as for :func:`candidate_count`

    Returns
    -------
    (m, T) float64 in [0, 1]; 1 where a triangle's interval area equals its pair area and
    the counts match (one interval), 0 for zero-area triangles.
    """
    A = np.asarray(areas, np.float64)
    Aj = np.asarray(interval_area, np.float64)
    n = candidate_count(float(A.sum()), float(spacing), safety)
    out = np.zeros(Aj.shape)
    if n == 0:
        return out
    for j in range(Aj.shape[0]):
        sj = float(Aj[j].sum())
        nj = candidate_count(sj, float(spacing), safety)
        if nj == 0 or not sj > 0.0:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            p = (Aj[j] / A) * ((nj / sj) / (n / float(A.sum())))
        out[j] = np.clip(np.where(A > 0.0, p, 0.0), 0.0, 1.0)
    return out


def sample_triangles(weights: np.ndarray, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Area-proportional random surface samples in barycentric form (§3.4.1).

    Parameters
    ----------
    weights : (T,) float64 >= 0, sampling weight per triangle (its maximum area)
    count : int, number of samples
    rng : numpy Generator

    Returns
    -------
    tri : (count,) int32 triangle index into ``weights``; never a triangle of
        zero weight.
    bary : (count, 2) float64 barycentric weights (b1, b2) of corners 1 and 2;
        corner 0 has ``1 - b1 - b2``. Uniform on the triangle.
    """
    w = np.asarray(weights, np.float64).reshape(-1)
    if count <= 0 or w.size == 0 or not (w.sum() > 0.0):
        return np.zeros(0, np.int32), np.zeros((0, 2))
    # i.i.d. categorical draws, generated as multinomial counts (same
    # distribution, O(count + T)); samples come out grouped by triangle
    nz = np.flatnonzero(w > 0.0)
    p = w[nz] / w[nz].sum()
    counts = rng.multinomial(int(count), p / p.sum())
    tri = np.repeat(nz, counts)
    r1 = np.sqrt(rng.random(count))
    r2 = rng.random(count)
    bary = np.empty((count, 2))
    bary[:, 0] = r1 * (1.0 - r2)
    bary[:, 1] = r1 * r2
    return tri.astype(np.int32), bary


def sample_positions(v0: np.ndarray, v1: np.ndarray, tri: np.ndarray, bary: np.ndarray, u: float) -> np.ndarray:
    """(N, 3) float64 positions of barycentric samples at time u.

    v0, v1 : (T, 3, 3) corners at u = 0 and 1; tri : (N,) int; bary : (N, 2).
    """
    v = (1.0 - u) * v0[tri] + u * v1[tri] if u not in (0.0, 1.0) else (v0[tri] if u == 0.0 else v1[tri])
    b1 = bary[:, 0:1]
    b2 = bary[:, 1:2]
    return (1.0 - b1 - b2) * v[:, 0] + b1 * v[:, 1] + b2 * v[:, 2]


def sample_candidates(v0: np.ndarray, v1: np.ndarray, spacing: float, rng: np.random.Generator,
                      safety: float = POINTS_SAFETY_FACTOR, areas: np.ndarray | None = None):
    """Candidate set of a node: ``safety * n ln n`` samples by maximum area (§3.4.1).

    Parameters
    ----------
    v0, v1 : (T, 3, 3) float64 corners of the node's triangles at u = 0, 1
    spacing : float, the node's maximum sample distance r
    rng : numpy Generator
    safety : float, coupon-collector factor
    areas : optional (T,) precomputed maximum areas (:func:`max_area`)

    Returns
    -------
    tri : (N,) int32 local triangle index; bary : (N, 2) float64;
    areas : (T,) float64 maximum areas used as weights.
    """
    if areas is None:
        areas, _ = max_area(v0, v1)
    n = candidate_count(float(areas.sum()), float(spacing), safety)
    tri, bary = sample_triangles(areas, n, rng)
    return tri, bary, areas
