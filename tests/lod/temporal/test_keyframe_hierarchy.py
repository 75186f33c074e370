"""Interpolating keyframe hierarchies (lod.temporal.interpolating): Definition 2, Theorem 1, eq. (1)."""
import numpy as np
import pytest

from lod.temporal.bisection import BisectionForest
from lod.temporal.interpolating import (
    bernstein_weights, check_interpolation_constraints, interpolate, linear_weights, union_hierarchy,
    values_on_union,
)


def root_complex():
    v = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], np.float64)
    t = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    return v, t


def refined(seed, steps=6, coarsen=True):
    v, t = root_complex()
    f = BisectionForest(v, t, [0, 0, 0, 0])
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        lv = f.leaves()
        f.refine(rng.choice(lv, size=max(1, lv.size // 4), replace=False))
        if coarsen and rng.random() < 0.5:
            inner = np.flatnonzero(f.active[: f.n_nodes] & ~f.leaf[: f.n_nodes])
            f.coarsen(rng.choice(inner, size=max(1, inner.size // 5), replace=False))
    return f


def surface_a(uv):
    return np.stack([uv[:, 0], np.sin(3 * uv[:, 0]) * np.cos(2 * uv[:, 1]), uv[:, 1]], 1)


def surface_b(uv):
    return np.stack([uv[:, 0] + 0.1, 0.5 * uv[:, 0] ** 2 - uv[:, 1], uv[:, 1]], 1)


def keyframe_values(f, fn):
    return fn(f.verts[: f.n_verts])


def conforming_union(u):
    return u.hanging_leaves().size == 0


def pl_surface(f, values, uv):
    """Piecewise-linear value of forest ``f``'s current mesh at domain points ``uv`` (brute force)."""
    lt = f.leaf_triangles()
    p = f.verts[lt]
    out = np.full((uv.shape[0], values.shape[1]), np.nan)
    for q, x in enumerate(uv):
        for j in range(lt.shape[0]):
            A = np.stack([p[j, :, 0], p[j, :, 1], np.ones(3)], 1)
            lam = np.linalg.solve(A.T, np.array([x[0], x[1], 1.0]))
            if (lam >= -1e-9).all():
                out[q] = lam @ values[lt[j]]
                break
    return out


def test_constraints_are_checked():
    f = refined(0)
    check_interpolation_constraints([f, refined(1)])
    v, t = root_complex()
    g = BisectionForest(v, t, [1, 0, 0, 0])  # a different root refinement edge
    with pytest.raises(ValueError, match="refinement edges"):
        check_interpolation_constraints([f, g])
    with pytest.raises(ValueError):
        check_interpolation_constraints([])


@pytest.mark.parametrize("seeds", [(0, 1), (2, 3), (4, 5)])
def test_independent_hierarchies_interpolate_without_cracks(seeds):
    f0, f1 = refined(seeds[0]), refined(seeds[1])
    assert {tuple(x) for x in f0.leaf_triangles()} != {tuple(x) for x in f1.leaf_triangles()}
    u, ident = union_hierarchy([f0, f1])
    assert conforming_union(u)
    assert u.leaves().size >= max(f0.leaves().size, f1.leaves().size)
    # every keyframe's vertices are union vertices
    for f, idm in zip((f0, f1), ident):
        assert np.count_nonzero(idm >= 0) == np.count_nonzero(f.vuse[: f.n_verts] > 0)
    v0, v1 = keyframe_values(f0, surface_a), keyframe_values(f1, surface_b)
    u0 = values_on_union(u, ident[0], v0)
    u1 = values_on_union(u, ident[1], v1)
    # t = 0 and t = 1 reproduce each keyframe's surface exactly (extra vertices lie on it)
    uv = u.verts[: u.n_verts]
    np.testing.assert_allclose(u0, pl_surface(f0, v0, uv), atol=1e-12)
    np.testing.assert_allclose(u1, pl_surface(f1, v1, uv), atol=1e-12)
    for t in (0.0, 0.3, 1.0):
        tris, pos, uu = interpolate([f0, f1], [v0, v1], t)
        np.testing.assert_allclose(pos, (1 - t) * u0 + t * u1, atol=1e-12)
        assert np.isfinite(pos).all()
        # shared vertices coincide: one vertex array, conforming leaves, every edge used <= twice
        e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), 1)
        _, cnt = np.unique(e, axis=0, return_counts=True)
        assert cnt.max() == 2
    # the keyframe's own vertices keep their exact values
    have = ident[0] >= 0
    np.testing.assert_array_equal(u0[have], v0[ident[0][have]])


def test_union_with_itself_is_itself():
    f = refined(9)
    u, ident = union_hierarchy([f, f])
    assert {tuple(ident[0][x]) for x in u.leaf_triangles()} == {tuple(x) for x in f.leaf_triangles()}
    assert u.leaves().size == f.leaves().size
    assert (ident[0] >= 0).all()


def test_bernstein_weights_and_linear_precision():
    for n in range(5):
        for t in (0.0, 0.2, 0.5, 1.0):
            w = bernstein_weights(n, t)
            assert w.sum() == pytest.approx(1.0)
            assert (w >= 0).all()
        assert bernstein_weights(n, 0.0)[0] == 1.0 and bernstein_weights(n, 1.0)[-1] == 1.0
    with pytest.raises(ValueError):
        bernstein_weights(-1, 0.5)
    np.testing.assert_allclose(linear_weights(3, 0.75), [0, 0.5, 0.5])


def test_degree_n_interpolant_endpoints_and_linear_precision():
    fs = [refined(s) for s in (11, 12, 13, 14)]
    A = lambda f: f.verts[: f.n_verts] @ np.array([[1.0, 0.0, 0.5], [0.0, 1.0, -0.25]])  # noqa: E731
    B = np.array([0.0, 0.3, 0.1])
    vals = [A(f) + i * B for i, f in enumerate(fs)]  # keyframes linear in i (affine in uv)
    n = len(fs) - 1
    u, ident = union_hierarchy(fs)
    assert conforming_union(u)
    ends = [values_on_union(u, ident[k], vals[k]) for k in (0, n)]
    for t in (0.0, 0.37, 1.0):
        tris, pos, _ = interpolate(fs, vals, t, scheme="bernstein")
        # linear precision: H(t) = A + n t B
        np.testing.assert_allclose(pos, A(u) + n * t * B, atol=1e-12)
    np.testing.assert_allclose(interpolate(fs, vals, 0.0, "bernstein")[1], ends[0], atol=1e-12)
    np.testing.assert_allclose(interpolate(fs, vals, 1.0, "bernstein")[1], ends[1], atol=1e-12)
    # a non-linear key sequence: Bernstein still passes through its end keyframes only
    vals2 = [A(f) + (i % 2) * B for i, f in enumerate(fs)]
    mid = interpolate(fs, vals2, 1 / 3, "bernstein")[1]
    lin = interpolate(fs, vals2, 1 / 3, "linear")[1]
    assert np.abs(mid - lin).max() > 0.01
    with pytest.raises(ValueError):
        interpolate(fs, vals, 0.5, scheme="cubic")
