"""Projected error of each triangle chain level per instance (Luebke et al. 2003, §4.1): the rule of
:func:`lod.chains.mode.choose_levels` for many instances at once, in numba, with a plain numpy reference.
Used by mode auto's triangle candidate (:mod:`lod.auto.candidates`) and its flat selection."""
from __future__ import annotations

import numpy as np
from numba import njit


def projected_errors_numpy(errors, rows, sphere, scale_px: float) -> np.ndarray:
    """Reference of :func:`projected_errors` (plain numpy)."""
    rows = np.asarray(rows, np.float64).reshape(-1, 3, 4)
    e = np.asarray(errors, np.float64)
    s = np.linalg.norm(rows[:, :, :3], axis=1).max(axis=1)
    c = rows[:, :, :3] @ np.asarray(sphere[:3], np.float64) + rows[:, :, 3]
    d = np.linalg.norm(c, axis=1) - float(sphere[3]) * s
    inside = ~(d > 0.0)
    px = e[None, :] * (s * scale_px / np.where(inside, 1.0, d))[:, None]
    px[inside] = np.where(e > 0.0, np.inf, 0.0)[None, :]
    return px


@njit(cache=True, inline="always")
def _axis_scale(rows, i):  # pragma: no cover - compiled
    """The largest axis scale (column norm of the 3x3 part) of instance i's model rows."""
    s = 0.0
    for b in range(3):
        n = np.sqrt(rows[i, 0, b] ** 2 + rows[i, 1, b] ** 2 + rows[i, 2, b] ** 2)
        if n > s:
            s = n
    return s


@njit(cache=True)
def _projected_errors_kernel(e, rows, sphere, scale_px, out):  # pragma: no cover - compiled
    for i in range(rows.shape[0]):
        s = _axis_scale(rows, i)
        d2 = 0.0
        for a in range(3):
            c = rows[i, a, 0] * sphere[0] + rows[i, a, 1] * sphere[1] + rows[i, a, 2] * sphere[2] + rows[i, a, 3]
            d2 += c * c
        d = np.sqrt(d2) - sphere[3] * s
        if d > 0.0:
            f = s * scale_px / d
            for k in range(e.shape[0]):
                out[i, k] = e[k] * f
        else:
            for k in range(e.shape[0]):
                out[i, k] = np.inf if e[k] > 0.0 else 0.0


def projected_errors(errors, rows, sphere, scale_px: float) -> np.ndarray:
    """(k, L) float64 pixels of error of each chain level per instance (numba).

    Same rule as :func:`lod.chains.mode.choose_levels` (Luebke et al.
    2003, §4.1): ``error_l * s * scale_px / d`` with s the largest axis scale
    and d the distance to the scaled clip sphere; inside the sphere (d <= 0)
    level 0 projects 0 and every other level +inf.
    :func:`projected_errors_numpy` is the reference.

    Parameters
    ----------
    errors : (L,) float64 metres, model space; rows : (k, 3, 4) float64
        camera-relative model rows; sphere : (4,) float64 model-space
        centre and radius; scale_px : pixels per metre at unit distance
    """
    rows = np.ascontiguousarray(np.asarray(rows, np.float64).reshape(-1, 3, 4))
    e = np.ascontiguousarray(errors, np.float64).reshape(-1)
    out = np.empty((rows.shape[0], e.shape[0]), np.float64)
    _projected_errors_kernel(e, rows, np.ascontiguousarray(sphere, np.float64).reshape(4), float(scale_px), out)
    return out


__all__ = ["projected_errors", "projected_errors_numpy"]
