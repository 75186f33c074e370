"""sim.angles.atan2_fast against math.atan2: every quadrant, the axes, the diagonals, tiny and huge arguments."""
import math

import numpy as np
from numba import njit

from sim.angles import atan2_fast, sincos_fast


@njit(cache=True)
def _all(y, x):
    out = np.empty(y.shape[0])
    for i in range(y.shape[0]):
        out[i] = atan2_fast(y[i], x[i])
    return out


def test_atan2_fast_is_within_2e_15_of_libm():
    rng = np.random.default_rng(11)
    y = np.concatenate([rng.normal(size=200000), rng.uniform(-1, 1, 1000) * 1e-300, rng.normal(size=1000) * 1e300,
                        [0.0, 0.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 3.0, 1e-320, 5.0]])
    x = np.concatenate([rng.normal(size=200000), rng.uniform(-1, 1, 1000) * 1e-300, rng.normal(size=1000) * 1e300,
                        [1.0, -1.0, 0.0, 0.0, 1.0, 1.0, -1.0, -1.0, 3.0 * math.tan(math.pi / 8), 1.0, -1e-320]])
    got = _all(y, x)
    want = np.arctan2(y, x)
    assert np.isfinite(got).all()
    assert np.abs(got - want).max() < 2e-15


def test_atan2_fast_at_the_origin_is_zero():
    assert _all(np.zeros(1), np.zeros(1))[0] == 0.0


@njit(cache=True)
def _sincos(x):
    out = np.empty((x.shape[0], 2))
    for i in range(x.shape[0]):
        out[i, 0], out[i, 1] = sincos_fast(x[i])
    return out


def test_sincos_fast_is_within_2e_15_of_libm():
    rng = np.random.default_rng(12)
    x = np.concatenate([rng.uniform(-4 * np.pi, 4 * np.pi, 200000), rng.uniform(-1e5, 1e5, 2000),
                        rng.uniform(-1e-300, 1e-300, 100), np.arange(-16, 17) * (np.pi / 4), [0.0, 3e5, -7e8]])
    got = _sincos(x)
    assert np.isfinite(got).all()
    err = np.abs(got - np.stack([np.sin(x), np.cos(x)], axis=1))
    small = np.abs(x) <= 20.0  # headings: the reduction adds |x| * 1e-16 further out
    assert err[small].max() < 2e-15 and err.max() < 1e-11
    assert np.isnan(_sincos(np.array([np.nan]))).all()
