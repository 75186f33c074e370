"""§3.5 attribute filtering: kernel vs reference, constants, edges, fallbacks, start/end."""
import numpy as np

from lod.points.filter import filter_points, gaussian_filter, gaussian_filter_numpy
from lod.points.sampling import max_area, triangle_vertices


def _random_sets(seed, R=60, F=800):
    rng = np.random.default_rng(seed)
    rep = rng.random((R, 3)) * [1, 1, 0.1]
    fp = rng.random((F, 3)) * [1, 1, 0.1]
    fc = rng.random((F, 4))
    fn = rng.normal(size=(F, 3))
    fw = rng.random(F)
    return rep, fp, fc, fn, fw, rng.random((R, 4)), np.tile([0.0, 0.0, 1.0], (R, 1))


def test_kernel_matches_reference():
    for seed in range(3):
        rep, fp, fc, fn, fw, fbc, fbn = _random_sets(seed)
        c1, n1 = gaussian_filter(rep, fp, fc, fn, fw, 0.05, fbc, fbn)
        c2, n2 = gaussian_filter_numpy(rep, fp, fc, fn, fw, 0.05, fbc, fbn)
        assert np.allclose(c1, c2, atol=1e-12) and np.allclose(n1, n2, atol=1e-12)


def test_fallbacks_without_neighbours_and_for_opposite_normals():
    rep = np.array([[0.0, 0, 0], [5.0, 5, 5]])
    fp = np.array([[0.0, 0, 0.001], [0.0, 0, -0.001]])
    fn = np.array([[0.0, 0, 1], [0.0, 0, -1]])  # a thin sheet seen from both sides
    fc = np.array([[1.0, 0, 0, 1], [0.0, 0, 1, 1]])
    fbc = np.array([[0.2, 0.2, 0.2, 1], [0.3, 0.3, 0.3, 1]])
    fbn = np.array([[1.0, 0, 0], [0.0, 0, 0]])
    c, n = gaussian_filter(rep, fp, fc, fn, np.ones(2), 0.1, fbc, fbn)
    assert np.allclose(c[0], [0.5, 0, 0.5, 1])  # averaged colour
    # the normals' mean cancels; their principal axis is the sheet's (lit alike from both sides)
    assert np.allclose(np.abs(n[0]), [0, 0, 1])
    assert np.allclose(c[1], fbc[1])  # nobody within 2 sigma: own colour
    assert np.allclose(n[1], [0, 1, 0])  # own normal is zero too: +Y
    assert np.isfinite(c).all() and np.isfinite(n).all()


def _strip():
    """Two-coloured strip of 2 x 20 quads in the xy plane (x < 1 red, x > 1 blue), moving +z and changing colour."""
    nx = 20
    x = np.linspace(0, 2, nx + 1)
    X, Y = np.meshgrid(x, [0.0, 0.5], indexing="ij")
    p0 = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    p1 = p0 + [0.0, 0.0, 1.0]
    i = np.arange(nx)
    a = 2 * i
    tri = np.r_[np.c_[a, a + 2, a + 1], np.c_[a + 1, a + 2, a + 3]]
    red, blue, green = [1.0, 0, 0, 1], [0.0, 0, 1, 1], [0.0, 1, 0, 1]
    c0 = np.where((p0[:, 0] <= 1.0)[:, None], red, blue)
    c1 = np.tile(green, (p0.shape[0], 1))
    n = np.tile([0.0, 0, 1], (p0.shape[0], 1))
    return p0, p1, tri, c0, c1, n


def test_filtered_attributes_of_a_two_coloured_strip():
    p0, p1, tri, c0, c1, n = _strip()
    v0, v1 = triangle_vertices(p0, tri), triangle_vertices(p1, tri)
    cc0, cc1, nn = c0[tri], c1[tri], n[tri]
    areas, _ = max_area(v0, v1)
    rng = np.random.default_rng(0)
    rt = np.array([0, 5, 9, 10, 19, 20, 35])
    rb = np.full((rt.size, 2), 1 / 3)
    fc0, fc1, fn0, fn1 = filter_points(v0, v1, cc0, cc1, nn, nn, areas, rt, rb, 0.2, rng, 20000, 0.25)
    cx = (v0[rt].mean(1))[:, 0]
    far = np.abs(cx - 1.0) > 0.2
    assert np.allclose(fc0[far & (cx < 1)], [1, 0, 0, 1], atol=1e-9)
    assert np.allclose(fc0[far & (cx > 1)], [0, 0, 1, 1], atol=1e-9)
    assert np.allclose(fc1, [0, 1, 0, 1], atol=1e-9)  # end keyframe colour
    assert np.allclose(fn0, [0, 0, 1]) and np.allclose(fn1, [0, 0, 1])
    near = ~far
    assert near.any()
    mixed = fc0[near]
    assert np.all((mixed[:, 0] > 0.0) & (mixed[:, 2] > 0.0))  # edge points blend both sides
    assert np.allclose(mixed[:, 0] + mixed[:, 2], 1.0)


def test_principal_normal_keeps_the_axis_the_light_sees():
    """Issue 43: a coarse node's normal is the principal axis of its normals' second moment. A slab's front
    and back (the torso in one far node) keep their axis where the renormalised mean was the sideways remnant;
    one normal is kept as it is; a spread cone keeps its axis; degenerate inputs give finite unit normals."""
    from lod.points.filter import principal_normal

    def moments(n, w):
        n = np.asarray(n, float)
        return np.array([[(w * n[:, i] * n[:, j]).sum() for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]])

    # front (+z, 48 % of the area) and back (-z, 47 %) of a slab, a little side (+x, 5 %)
    n = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]])
    w = np.array([0.48, 0.47, 0.05])
    mean = (w[:, None] * n).sum(0, keepdims=True)
    got = principal_normal(moments(n, w), mean, np.array([[0, 1.0, 0]]))
    assert np.allclose(got, [[0, 0, 1]], atol=1e-9)
    renorm = mean / np.linalg.norm(mean)
    assert abs(renorm[0, 0]) > 0.7  # the mean's remnant leans sideways: lit as seen edge-on
    # one normal: itself
    one = np.array([[0.48, 0.6, 0.64]])
    assert np.allclose(principal_normal(moments(one, np.ones(1)), one, one), one)
    # a cone of normals around +y (half-angle 30 deg)
    a = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    cone = np.c_[0.5 * np.cos(a), np.full(12, np.sqrt(0.75)), 0.5 * np.sin(a)]
    assert np.allclose(principal_normal(moments(cone, np.ones(12)), cone.sum(0, keepdims=True), one), [[0, 1, 0]],
                       atol=1e-9)
    # nothing, NaN, zero fallbacks: finite unit vectors
    bad = principal_normal(np.array([[0.0] * 6, [np.nan] * 6]), np.zeros((2, 3)), np.zeros((2, 3)))
    assert np.isfinite(bad).all() and np.allclose(np.linalg.norm(bad, axis=1), 1.0)
