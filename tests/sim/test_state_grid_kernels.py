"""The parallel bookkeeping kernels of a step at scale: the state's finiteness check, the grid's extent and its
cells, each against the numpy or serial path it replaces above a size (same answers, same grid)."""
import numpy as np
import pytest

from sim import grid as G
from sim.state import FINITE_KERNEL_MIN, CrowdState, all_finite


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("where", [None, 0, 123_457, -1])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_all_finite_matches_numpy(dtype, where, bad):
    a = np.random.default_rng(1).normal(size=(FINITE_KERNEL_MIN + 17, 3)).astype(dtype)
    if where is not None:
        a.reshape(-1)[where] = bad
    assert all_finite(a) == bool(np.isfinite(a).all())
    assert all_finite(a[:100]) == bool(np.isfinite(a[:100]).all())  # below the threshold: numpy's


def test_check_finite_names_the_array_at_scale():
    st = CrowdState.empty(FINITE_KERNEL_MIN + 1)
    st.check_finite()
    st.anim_time[-1] = np.nan
    with pytest.raises(FloatingPointError, match="anim_time"):
        st.check_finite()


def test_extent_kernel_matches_numpy_and_keeps_nan():
    p = np.random.default_rng(2).uniform(-1e6, 1e6, (G.EXTENT_KERNEL_MIN + 5, 3))
    x, z = p[:, 0], p[:, 2]
    assert G._extent(p) == (x.min(), z.min(), x.max(), z.max())
    p[7, 2] = np.nan  # numpy's answer with a NaN (the layout then sees NaN, as before the kernel)
    got = G._extent(p)
    assert np.isnan(got[1]) and np.isnan(got[3]) and got[0] == x.min()


def test_parallel_cells_build_the_same_grid(monkeypatch):
    rng = np.random.default_rng(3)
    n = 5000
    p = np.zeros((n, 3))
    p[:, 0] = rng.uniform(-50, 50, n)
    p[:, 2] = rng.uniform(-30, 30, n)
    p[:10] = p[10]  # coincident agents
    for dense_factor in (G.GRID_DENSE_FACTOR, 1e-3):  # dense keys and hashed ones
        monkeypatch.setattr(G, "CELLS_KERNEL_MIN", 10 ** 9)
        a = G.build_grid(p, 2.0, dense_factor=dense_factor)
        monkeypatch.setattr(G, "CELLS_KERNEL_MIN", 1)
        b = G.build_grid(p, 2.0, dense_factor=dense_factor)
        for k in ("cx", "cz", "key", "start", "order"):
            assert np.array_equal(getattr(a, k), getattr(b, k)), k
