"""Sphere-versus-frustum culling of instances.

Inputs are *camera-relative* sphere centres: the float64 subtraction of the
camera position happens before anything is cast to float32, so instances a
million metres from the origin cull exactly as near ones do.

A sphere is culled when it lies entirely on the outer side of at least one
plane (``n . c + d < -r``). This is conservative: a sphere near a frustum
corner may be kept although it is outside, never the reverse.

``cull_spheres`` is the public entry point (validates, then calls the numba
kernel); ``cull_spheres_numpy`` is the plain reference the tests compare with.
The kernel is serial: at 100K spheres it takes well under a millisecond, and a
``parallel=True`` variant did not pay on the shared 2-core development machine
(thread start-up exceeds the work).
"""
from __future__ import annotations

import numpy as np
from numba import njit


def cull_spheres_numpy(centers: np.ndarray, radii: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """Reference: (N,) bool, True where the sphere is (at least partly) inside.

    centers : (N, 3) float64 camera-relative; radii : (N,) float64 >= 0;
    planes : (P, 4) float64 unit inward planes (``Camera.frustum_planes``).
    """
    c = np.asarray(centers, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).reshape(-1)
    pl = np.asarray(planes, np.float64).reshape(-1, 4)
    dist = c @ pl[:, :3].T + pl[:, 3]
    return ~np.any(dist < -r[:, None], axis=1)


@njit(cache=True)
def _cull_spheres(centers, radii, planes, out):  # pragma: no cover - compiled
    n = centers.shape[0]
    p = planes.shape[0]
    for i in range(n):
        cx = centers[i, 0]
        cy = centers[i, 1]
        cz = centers[i, 2]
        r = radii[i]
        vis = True
        for k in range(p):
            d = planes[k, 0] * cx + planes[k, 1] * cy + planes[k, 2] * cz + planes[k, 3]
            if d < -r:
                vis = False
                break
        out[i] = vis
    return out


def cull_spheres(centers: np.ndarray, radii: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """(N,) bool visibility of spheres against planes (numba kernel).

    Parameters
    ----------
    centers : (N, 3) float64, camera-relative sphere centres
    radii : (N,) float64, radii >= 0 (a NaN radius or centre counts as visible
        so that bad data is never silently dropped; callers keep NaN out)
    planes : (P, 4) float64 unit inward planes

    Returns
    -------
    (N,) bool, True = draw.
    """
    c = np.ascontiguousarray(centers, np.float64).reshape(-1, 3)
    r = np.ascontiguousarray(radii, np.float64).reshape(-1)
    pl = np.ascontiguousarray(planes, np.float64).reshape(-1, 4)
    if r.shape[0] != c.shape[0]:
        raise ValueError(f"cull_spheres: expected {c.shape[0]} radii (one per centre), got {r.shape[0]}")
    out = np.empty(c.shape[0], np.bool_)
    if c.shape[0] == 0:
        return out
    return _cull_spheres(c, r, pl, out)
