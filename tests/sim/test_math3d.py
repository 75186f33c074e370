"""sim.math3d: quaternion and matrix helpers, degenerate inputs included."""
import numpy as np
import pytest

from sim import math3d as m3


def rand_quats(n, seed=0):
    rng = np.random.default_rng(seed)
    return m3.quat_normalize(rng.normal(size=(n, 4)))


def test_normalize_zero_and_nan_become_identity():
    q = np.array([[0, 0, 0, 0], [np.nan, 0, 0, 1], [0, 0, 0, 2.0]])
    out = m3.quat_normalize(q)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, [[0, 0, 0, 1], [0, 0, 0, 1], [0, 0, 0, 1]])


def test_multiply_matches_matrix_product():
    a, b = rand_quats(50, 1), rand_quats(50, 2)
    ab = m3.quat_multiply(a, b)
    np.testing.assert_allclose(m3.quat_to_matrix(ab), m3.quat_to_matrix(a) @ m3.quat_to_matrix(b), atol=1e-12)


def test_rotate_matches_matrix():
    q = rand_quats(20, 3)
    v = np.random.default_rng(4).normal(size=(20, 3))
    np.testing.assert_allclose(m3.quat_rotate(q, v), np.einsum("nij,nj->ni", m3.quat_to_matrix(q), v), atol=1e-12)


def test_matrix_is_rotation_and_roundtrips():
    q = rand_quats(100, 5)
    R = m3.quat_to_matrix(q)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    q2 = m3.matrix_to_quat(R)
    same = np.minimum(np.abs(q2 - q).max(1), np.abs(q2 + q).max(1))
    assert same.max() < 1e-10
    # 180 degree rotations about each axis
    for ax in np.eye(3):
        qq = m3.quat_from_axis_angle(ax, np.pi)
        r = m3.matrix_to_quat(m3.quat_to_matrix(qq))
        assert min(np.abs(r - qq).max(), np.abs(r + qq).max()) < 1e-12


def test_axis_angle_roundtrip_and_identity():
    axis, angle = m3.quat_to_axis_angle(m3.quat_from_axis_angle([0, 0, 2.0], 0.7))
    np.testing.assert_allclose(axis, [0, 0, 1], atol=1e-12)
    assert angle == pytest.approx(0.7)
    axis, angle = m3.quat_to_axis_angle([0, 0, 0, 1.0])
    assert angle == 0.0 and np.all(np.isfinite(axis))
    np.testing.assert_allclose(m3.quat_from_axis_angle([0, 0, 0], 1.0), [0, 0, 0, 1])


def test_slerp_endpoints_and_midpoint():
    a = m3.quat_from_axis_angle([0, 1, 0], 0.0)
    b = m3.quat_from_axis_angle([0, 1, 0], 1.0)
    np.testing.assert_allclose(m3.quat_slerp(a, b, 0.0), a, atol=1e-12)
    np.testing.assert_allclose(m3.quat_slerp(a, b, 1.0), b, atol=1e-12)
    np.testing.assert_allclose(m3.quat_slerp(a, b, 0.5), m3.quat_from_axis_angle([0, 1, 0], 0.5), atol=1e-12)


def test_slerp_takes_shortest_path_for_negated_quat():
    a = m3.quat_from_axis_angle([0, 1, 0], 0.2)
    b = -m3.quat_from_axis_angle([0, 1, 0], 0.6)  # same rotation as +b
    mid = m3.quat_slerp(a, b, 0.5)
    _, ang = m3.quat_to_axis_angle(mid)
    assert ang == pytest.approx(0.4)
    # q to -q is no rotation at all
    np.testing.assert_allclose(np.abs(m3.quat_slerp(a, -a, 0.3)), np.abs(a), atol=1e-12)


def test_slerp_180_degrees_and_nearly_equal():
    a = np.array([0, 0, 0, 1.0])
    b = m3.quat_from_axis_angle([1, 0, 0], np.pi)
    mid = m3.quat_slerp(a, b, 0.5)
    np.testing.assert_allclose(mid, m3.quat_from_axis_angle([1, 0, 0], np.pi / 2), atol=1e-12)
    c = m3.quat_from_axis_angle([0, 0, 1], 1e-9)
    for t in (0.0, 0.25, 1.0):
        r = m3.quat_slerp(a, c, t)
        assert np.all(np.isfinite(r))
        assert np.linalg.norm(r) == pytest.approx(1.0)
    # zero quaternion input -> identity, no NaN
    assert np.all(np.isfinite(m3.quat_slerp([0, 0, 0, 0], b, 0.5)))


def test_slerp_vectorised_constant_angular_speed():
    a = rand_quats(30, 7)
    b = rand_quats(30, 8)
    t = np.linspace(0, 1, 30)
    out = m3.quat_slerp(a, b, t)
    for i in range(30):
        d_ab = 2 * np.arccos(min(1, abs(np.dot(a[i], b[i]))))
        d_ao = 2 * np.arccos(min(1, abs(np.dot(a[i], out[i]))))
        assert d_ao == pytest.approx(t[i] * d_ab, abs=1e-6)


def test_trs_and_inverse():
    rng = np.random.default_rng(9)
    t = rng.normal(size=(10, 3))
    q = rand_quats(10, 10)
    s = rng.uniform(0.5, 2, size=(10, 3))
    M = m3.trs_matrix(t, q, s)
    p = rng.normal(size=3)
    expect = m3.quat_rotate(q, p * s) + t
    np.testing.assert_allclose(np.einsum("nij,j->ni", M[:, :3, :3], p) + M[:, :3, 3], expect, atol=1e-12)
    Mi = m3.invert_affine(M)
    np.testing.assert_allclose(Mi @ M, np.broadcast_to(np.eye(4), M.shape), atol=1e-10)
    # singular linear part: finite result
    Z = m3.trs_matrix([1, 2, 3], [0, 0, 0, 1], [0, 1, 1])
    assert np.all(np.isfinite(m3.invert_affine(Z)))


def test_cofactor_is_det_times_inverse_transpose():
    A = np.random.default_rng(11).normal(size=(5, 3, 3))
    C = m3.cofactor3(A)
    expect = np.linalg.det(A)[:, None, None] * np.swapaxes(np.linalg.inv(A), -1, -2)
    np.testing.assert_allclose(C, expect, atol=1e-10)
    assert np.all(np.isfinite(m3.cofactor3(np.zeros((3, 3)))))
