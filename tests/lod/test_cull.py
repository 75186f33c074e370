"""Sphere-vs-frustum culling: numba kernel against the numpy reference."""
import numpy as np
import pytest

from lod.cull import cull_spheres, cull_spheres_numpy
from lod.view import Camera


@pytest.fixture(scope="module")
def planes():
    return Camera.look_at((0, 2, 10), (0, 1, 0), fov_y=50, near=0.1, far=100).frustum_planes(16 / 9)


@pytest.mark.parametrize("parallel", [False, True, None])
def test_kernels_match_reference_on_random_spheres(planes, parallel):
    rng = np.random.default_rng(0)
    c = rng.uniform(-120, 120, (30000, 3))
    r = rng.uniform(0, 20, 30000)
    got = cull_spheres(c, r, planes, parallel=parallel)
    assert np.array_equal(got, cull_spheres_numpy(c, r, planes))
    assert 0 < got.sum() < got.size


def test_edge_cases(planes):
    assert cull_spheres(np.zeros((0, 3)), np.zeros(0), planes).shape == (0,)
    one = cull_spheres(np.array([[0.0, -1.0, -8.0]]), np.array([0.5]), planes)
    assert one.tolist() == [True]
    # identical spheres, zero radius, behind the camera
    c = np.array([[0.0, -1.0, -8.0]] * 3 + [[0.0, 0.0, 5.0]])
    r = np.array([0.0, 0.0, 0.0, 1.0])
    assert cull_spheres(c, r, planes).tolist() == [True, True, True, False]
    # NaN centres are kept by all (never silently dropped)
    n = np.array([[np.nan, 0, -5.0]])
    for par in (False, True):
        assert cull_spheres(n, np.array([1.0]), planes, parallel=par)[0]
    assert cull_spheres_numpy(n, np.array([1.0]), planes)[0]


def test_straddling_sphere_is_kept_and_outside_one_culled(planes):
    cam = Camera.look_at((0, 2, 10), (0, 1, 0), fov_y=50, near=0.1, far=100)
    # a point just outside the left plane, at distance d from it
    left = planes[0]
    p_in = np.array([0.0, 1.0, -10.0])
    d = left[:3] @ p_in + left[3]
    p_edge = p_in - left[:3] * (d + 0.5)  # 0.5 m outside the left plane
    vis = cull_spheres(np.stack([p_edge, p_edge]), np.array([1.0, 0.25]), planes)
    assert vis.tolist() == [True, False]
    assert cam is not None


def test_far_from_origin_culls_like_near_the_origin():
    off = np.array([1e6, 0, -1e6])
    cam_near = Camera.look_at((0, 2, 10), (0, 1, 0))
    cam_far = Camera.look_at(off + (0, 2, 10), off + (0, 1, 0))
    rng = np.random.default_rng(1)
    c = rng.uniform(-60, 60, (5000, 3))
    r = rng.uniform(0, 3, 5000)
    a = cull_spheres((c) - cam_near.position, r, cam_near.frustum_planes(1.5))
    b = cull_spheres((c + off) - cam_far.position, r, cam_far.frustum_planes(1.5))
    assert np.array_equal(a, b)


def test_radius_count_mismatch_raises(planes):
    with pytest.raises(ValueError, match="radii"):
        cull_spheres(np.zeros((3, 3)), np.zeros(2), planes)
