"""Camera: look-at robustness, matrices, frustum planes and pixel projection."""
import math

import numpy as np
import pytest

from lod.view import Camera, rotation_from_forward


def _is_rotation(r):
    return np.allclose(r.T @ r, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(r), 1.0)


def test_look_at_points_minus_z_at_the_target():
    cam = Camera.look_at((1.0, 2.0, 10.0), (1.0, 2.0, 0.0))
    assert _is_rotation(cam.rotation)
    assert np.allclose(cam.rotation, np.eye(3))
    assert np.allclose(cam.forward, (0, 0, -1))


@pytest.mark.parametrize("target", [(0, 10, 0), (0, -10, 0), (0, 0, 0), (1e-300, 5, 0)])
def test_look_at_degenerate_directions_give_a_rotation_without_nan(target):
    cam = Camera.look_at((0.0, 0.0, 0.0), target)
    assert np.isfinite(cam.rotation).all()
    assert _is_rotation(cam.rotation)
    if np.linalg.norm(target) > 1:
        assert np.allclose(cam.forward, np.array(target) / np.linalg.norm(target))
    assert np.isfinite(cam.frustum_planes(16 / 9)).all()


def test_rotation_from_forward_zero_up():
    r = rotation_from_forward((0, 0, -1), up=(0, 0, 0))
    assert _is_rotation(r)


@pytest.mark.parametrize("yaw,pitch", [(0.0, 0.0), (0.7, 0.3), (-2.5, -1.2), (3.0, 1.5)])
def test_yaw_pitch_round_trip(yaw, pitch):
    cam = Camera.from_yaw_pitch((1, 2, 3), yaw, pitch)
    assert _is_rotation(cam.rotation)
    assert math.isclose(cam.yaw, yaw, abs_tol=1e-9)
    assert math.isclose(cam.pitch, pitch, abs_tol=1e-9)
    # no roll: camera +X stays horizontal
    assert abs(cam.rotation[1, 0]) < 1e-12


def test_yaw_zero_looks_down_minus_z_and_positive_turns_left():
    assert np.allclose(Camera.from_yaw_pitch((0, 0, 0), 0.0, 0.0).forward, (0, 0, -1))
    assert np.allclose(Camera.from_yaw_pitch((0, 0, 0), math.pi / 2, 0.0).forward, (-1, 0, 0))


def test_view_matrix_is_rotation_only_and_matches_world_view():
    cam = Camera.look_at((5, 3, -2), (0, 1, 0))
    v = cam.view_matrix()
    assert np.allclose(v[:3, 3], 0) and np.allclose(v[:3, :3], cam.rotation.T)
    p = np.array([0.3, 1.2, 0.4])
    a = cam.world_view_matrix() @ np.append(p, 1)
    b = v @ np.append(p - cam.position, 1)
    assert np.allclose(a, b)


def test_projection_maps_near_and_far_to_minus_one_and_one():
    cam = Camera(fov_y=60, near=0.5, far=200)
    p = cam.projection(2.0)
    for z, ndc in ((-0.5, -1.0), (-200.0, 1.0)):
        c = p @ np.array([0, 0, z, 1.0])
        assert math.isclose(c[2] / c[3], ndc, abs_tol=1e-9)
    # the top edge of the field of view maps to y = 1, the right edge to x = 1
    t = math.tan(math.radians(30))
    c = p @ np.array([2 * t * 10, t * 10, -10, 1.0])
    assert np.allclose(c[:2] / c[3], (1, 1))


def test_frustum_planes_agree_with_clip_space_containment():
    rng = np.random.default_rng(3)
    cam = Camera.look_at((2, 3, 9), (0, 1, 0), fov_y=45, near=0.2, far=40)
    aspect = 1.6
    planes = cam.frustum_planes(aspect)
    assert planes.shape == (6, 4)
    assert np.allclose(np.linalg.norm(planes[:, :3], axis=1), 1)
    rel = rng.uniform(-45, 45, (4000, 3))
    inside_planes = np.all(rel @ planes[:, :3].T + planes[:, 3] >= 0, axis=1)
    clip = (cam.projection(aspect) @ cam.view_matrix() @ np.c_[rel, np.ones(len(rel))].T).T
    inside_clip = np.all(np.abs(clip[:, :3]) <= clip[:, 3:4], axis=1) & (clip[:, 3] > 0)
    assert inside_planes.sum() > 50
    assert np.array_equal(inside_planes, inside_clip)


def test_project_centre_and_edges():
    cam = Camera.look_at((0, 0, 10), (0, 0, 0), fov_y=90)
    px, depth = cam.project(np.array([[0, 0, 0], [0, 10, 0], [-20, 0, 0], [0, 0, 20]]), (200, 100), return_depth=True)
    assert np.allclose(px[0], (100, 50))
    assert np.allclose(px[1], (100, 0))  # top edge (y down)
    assert np.allclose(px[2], (0, 50))  # left edge at aspect 2
    assert depth[3] < 0 and np.isfinite(px).all()


def test_invalid_parameters_raise_one_clear_error():
    with pytest.raises(ValueError, match="fov_y"):
        Camera(fov_y=0)
    with pytest.raises(ValueError, match="near/far"):
        Camera(near=1, far=1)
    with pytest.raises(ValueError, match="finite"):
        Camera(position=(np.nan, 0, 0))
    with pytest.raises(ValueError, match="aspect"):
        Camera().projection(0)
