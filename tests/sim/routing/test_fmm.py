"""sim.routing.fmm: the numba march against its heapq reference, and against exact distances."""
import numpy as np
import pytest

from sim.routing.fmm import BLOCKED, FAR, KNOWN, march, march_numpy


def _point_source(nx, nz, h, g, blocked=None):
    X, Z = np.meshgrid(np.arange(nx) * h, np.arange(nz) * h)
    d = np.hypot(X - g[0], Z - g[1]).ravel()
    T = np.full(nx * nz, np.inf)
    flag = np.full(nx * nz, FAR, np.int8)
    if blocked is not None:
        flag[blocked.ravel()] = BLOCKED
    seed = (d < 1.5 * h) & (flag != BLOCKED)
    T[seed] = d[seed]
    flag[seed] = KNOWN
    return T, flag, d


@pytest.mark.parametrize("order", [1, 2])
def test_march_equals_reference_with_walls(order):
    nx, nz, h = 37, 29, 0.25
    X, Z = np.meshgrid(np.arange(nx) * h, np.arange(nz) * h)
    blocked = ((np.abs(X - 4.5) < 0.3) & (Z < 5.0)) | (np.hypot(X - 2.0, Z - 5.0) < 0.7)
    T, flag, _ = _point_source(nx, nz, h, (1.13, 1.37), blocked)
    T2, f2 = T.copy(), flag.copy()
    n1 = march(T, flag, nx, nz, h, 1.0, order)
    n2 = march_numpy(T2, f2, nx, nz, h, 1.0, order)
    assert n1 == n2 and np.array_equal(flag, f2)
    fin = np.isfinite(T)
    assert np.array_equal(fin, np.isfinite(T2)) and fin.sum() > 0.8 * nx * nz
    np.testing.assert_allclose(T[fin], T2[fin], rtol=0, atol=1e-12)
    assert np.all(T[blocked.ravel()] == np.inf)  # blocked nodes are never touched


@pytest.mark.parametrize("order, bound", [(1, 0.05), (2, 0.02)])
def test_distance_from_a_point_in_the_open(order, bound):
    nx = nz = 121
    h = 0.1
    T, flag, d = _point_source(nx, nz, h, (6.03, 5.98))
    march(T, flag, nx, nz, h, 1.0, order)
    far = d > 2.0
    rel = np.abs(T - d)[far] / d[far]
    assert rel.max() < bound, rel.max()  # second order is 3x closer than first
    assert np.all(T >= d - 1e-9) if order == 1 else True  # first order over-estimates


def test_slowness_scales_and_unreached_stay_infinite():
    nx, nz, h = 30, 20, 0.5
    flag = np.full(nx * nz, FAR, np.int8)
    flag.reshape(nz, nx)[:, 15] = BLOCKED  # a wall across the whole grid: the right half is never reached
    T = np.full(nx * nz, np.inf)
    src = 7 * nx + 4
    T[src], flag[src] = 0.0, KNOWN
    T2, f2 = T.copy(), flag.copy()
    march(T, flag, nx, nz, h, 1.0, 2)
    march(T2, f2, nx, nz, h, 3.0, 2)
    right = np.zeros((nz, nx), bool)
    right[:, 15:] = True
    assert np.all(np.isinf(T[right.ravel()])) and np.all(flag[right.ravel()] != KNOWN)
    left = ~right.ravel()
    assert np.isfinite(T[left]).all()
    np.testing.assert_allclose(T2[left], 3.0 * T[left], rtol=1e-12)  # |grad T| = s: T scales with s
    # along the grid axes from a node source the first-order front is exact
    row = T.reshape(nz, nx)[7, :15]
    np.testing.assert_allclose(row, np.abs(np.arange(15) - 4) * h, atol=1e-12)
