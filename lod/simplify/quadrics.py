"""Per-pose plane quadrics of a mesh (Garland & Heckbert 1997; one quadric per
pose and vertex as in DeCoro & Rusinkiewicz 2005, VDR-AM §4.3): the numba
accumulation :func:`plane_quadrics` beside its numpy reference.
"""
from __future__ import annotations

import numpy as np
from numba import njit


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
