"""§3.4.1 candidates: maximum area of moving triangles and area-proportional samples."""
import math

import numpy as np
import pytest

from lod.points.octree import sample_positions_at
from lod.points.sampling import (candidate_count, max_area, max_area_numpy, sample_candidates, sample_positions,
                                 sample_triangles, squared_area_coefficients, triangle_area_at)


def _brute_max(v0, v1, steps=200_001):
    """Dense-time maximum of the area, (T,), computed from positions (no polynomial)."""
    best = np.zeros(v0.shape[0])
    for u in np.array_split(np.linspace(0.0, 1.0, steps), 200):
        v = (1.0 - u)[:, None, None, None] * v0[None] + u[:, None, None, None] * v1[None]
        a = 0.5 * np.linalg.norm(np.cross(v[..., 1, :] - v[..., 0, :], v[..., 2, :] - v[..., 0, :]), axis=-1)
        best = np.maximum(best, a.max(0))
    return best


def _special_triangles():
    rng = np.random.default_rng(3)
    base = rng.normal(size=(3, 3))
    cases = [
        (base, base + [1.0, 2.0, 3.0]),                            # pure translation: constant area
        (base, 3.0 * base),                                         # uniform growth: max at u = 1
        (3.0 * base, 0.1 * base),                                   # shrinking: max at u = 0
        (np.zeros((3, 3)), base),                                   # grows out of a point
        (base, base[[0, 2, 1]]),                                    # flips through zero area: max at ends
        (base, base[[1, 2, 0]] * -1.0),                             # interior maximum likely
        (np.zeros((3, 3)), np.zeros((3, 3))),                       # always degenerate
        (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]),              # collinear start
         np.array([[0, 0, 0], [1, 1, 0], [2, 0, 0.0]])),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]),              # rises then falls
         np.array([[0, 0, 0], [-1, 0, 0], [0, 1, 0.0]])),
    ]
    return np.array([c[0] for c in cases], float), np.array([c[1] for c in cases], float)


def test_max_area_matches_dense_time_brute_force():
    rng = np.random.default_rng(0)
    v0 = rng.normal(size=(40, 3, 3))
    v1 = rng.normal(size=(40, 3, 3))
    s0, s1 = _special_triangles()
    v0, v1 = np.concatenate([v0, s0]), np.concatenate([v1, s1])
    area, when = max_area(v0, v1)
    bf = _brute_max(v0, v1)
    assert np.all(area >= bf * (1 - 1e-12))  # the exact maximum is never below a sampled one
    assert np.max(np.abs(area - bf) / np.where(bf > 0, bf, 1.0)) < 1e-6
    # the reported time attains the maximum
    at = np.array([triangle_area_at(v0[i:i + 1], v1[i:i + 1], when[i])[0] for i in range(len(when))])
    assert np.allclose(at, area, rtol=1e-9, atol=1e-300)


def test_max_area_kernel_matches_numpy_reference():
    rng = np.random.default_rng(1)
    v0 = rng.normal(size=(300, 3, 3))
    v1 = v0 + rng.normal(scale=0.7, size=(300, 3, 3))
    a, _ = max_area(v0, v1)
    b, _ = max_area_numpy(v0, v1)
    assert np.allclose(a, b, rtol=1e-9, atol=1e-12)


def test_special_cases_have_expected_maxima():
    s0, s1 = _special_triangles()
    area, when = max_area(s0, s1)
    a0 = triangle_area_at(s0, s1, 0.0)
    a1 = triangle_area_at(s0, s1, 1.0)
    assert area[0] == pytest.approx(a0[0], rel=1e-12)
    assert when[1] == 1.0 and area[1] == pytest.approx(9 * a0[1], rel=1e-12)
    assert when[2] == 0.0
    assert area[3] == pytest.approx(a1[3], rel=1e-12)
    assert area[6] == 0.0 and np.isfinite(area).all()
    assert 0.0 < when[8] < 1.0 or area[8] >= max(a0[8], a1[8])


def test_squared_area_polynomial_is_exact():
    rng = np.random.default_rng(2)
    v0, v1 = rng.normal(size=(20, 3, 3)), rng.normal(size=(20, 3, 3))
    c = squared_area_coefficients(v0, v1)
    for u in (0.0, 0.3, 0.77, 1.0):
        direct = (2.0 * triangle_area_at(v0, v1, u)) ** 2
        assert np.allclose(np.polynomial.polynomial.polyval(u, c.T), direct, rtol=1e-9, atol=1e-12)


def test_max_area_rejects_non_finite():
    v = np.zeros((1, 3, 3))
    v[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        max_area(v, v)


def test_candidate_count_is_coupon_collector():
    r = 0.1
    h = r / (2 * math.sqrt(3))
    n = math.ceil(1.0 / h**2)
    assert candidate_count(1.0, r, 3.0) == math.ceil(3.0 * n * math.log(n))
    assert candidate_count(0.0, r) == 0 and candidate_count(1.0, 0.0) == 0
    assert candidate_count(1e-9, 1.0, 3.0) == 3  # one bin, ln clamped at 1
    assert candidate_count(1e6, 1e-6, 3.0, cap=1000) == 1000


def test_sampling_is_area_proportional_and_skips_zero_area():
    w = np.array([1.0, 0.0, 3.0, 0.0, 6.0, 0.0])
    tri, bary = sample_triangles(w, 100_000, np.random.default_rng(0))
    counts = np.bincount(tri, minlength=6)
    assert counts[[1, 3, 5]].sum() == 0
    assert np.allclose(counts[[0, 2, 4]] / 1e5, [0.1, 0.3, 0.6], atol=0.01)
    assert (bary >= 0).all() and (bary.sum(1) <= 1 + 1e-12).all()
    # uniform on the triangle: the mean barycentric is the centroid
    assert np.allclose(bary.mean(0), [1 / 3, 1 / 3], atol=0.01)
    t2, b2 = sample_triangles(w, 1000, np.random.default_rng(5))
    t3, b3 = sample_triangles(w, 1000, np.random.default_rng(5))
    assert np.array_equal(t2, t3) and np.array_equal(b2, b3)
    t4, _ = sample_triangles(np.zeros(4), 10, np.random.default_rng(0))
    assert t4.size == 0


def test_samples_move_with_the_surface():
    rng = np.random.default_rng(4)
    v0 = rng.normal(size=(10, 3, 3))
    v1 = rng.normal(size=(10, 3, 3))
    tri, bary, areas = sample_candidates(v0, v1, 0.5, rng)
    assert tri.size == candidate_count(areas.sum(), 0.5)
    times = np.array([0.0, 0.25, 1.0])
    got = sample_positions_at(v0, v1, tri, bary, times)
    for k, u in enumerate(times):
        ref = sample_positions(v0, v1, tri, bary, float(u))
        assert np.allclose(got[k], ref, atol=1e-12)
        # the sample lies in the plane of its interpolated triangle
        v = (1 - u) * v0[tri] + u * v1[tri]
        nrm = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        assert np.allclose(np.einsum("ij,ij->i", got[k] - v[:, 0], nrm), 0.0, atol=1e-9)
