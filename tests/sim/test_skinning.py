"""sim.skinning: numba LBS kernel vs numpy reference, bind pose, degenerate blends."""
import numpy as np
import pytest

from sim import math3d as m3
from sim.mesh import Mesh
from sim.skeleton import Skeleton
from sim.skinning import bind_pose_matrices, blend_matrices, skin, skin_reference


def two_bone():
    sk = Skeleton(
        names=["a", "b"],
        parents=np.array([-1, 0], np.int32),
        rest_translation=np.array([[0, 0, 0], [0, 1, 0.0]]),
        rest_rotation=np.tile([0, 0, 0, 1.0], (2, 1)),
        rest_scale=np.ones((2, 3)),
        inverse_bind=np.tile(np.eye(4), (2, 1, 1)),
    )
    sk.inverse_bind = sk.rest_inverse_bind()
    return sk


def random_mesh(V=200, J=2, seed=0):
    rng = np.random.default_rng(seed)
    pos = rng.normal(size=(V, 3)).astype(np.float32)
    idx = rng.integers(0, V, size=(V, 3)).astype(np.uint32)
    nrm = m3.normalize_vectors(rng.normal(size=(V, 3))).astype(np.float32)
    joints = rng.integers(0, J, size=(V, 4)).astype(np.uint16)
    w = rng.uniform(size=(V, 4))
    w /= w.sum(1, keepdims=True)
    return Mesh(pos, idx, nrm, joints=joints, weights=w.astype(np.float32))


def test_kernel_matches_reference_random_pose():
    rng = np.random.default_rng(1)
    J = 6
    mesh = random_mesh(500, J)
    S = m3.trs_matrix(rng.normal(size=(J, 3)), m3.quat_normalize(rng.normal(size=(J, 4))), rng.uniform(0.5, 2, (J, 3)))
    p1, n1 = skin(mesh, S)
    p2, n2 = skin_reference(mesh, S)
    np.testing.assert_allclose(p1, p2, atol=1e-10)
    np.testing.assert_allclose(n1, n2, atol=1e-10)
    np.testing.assert_allclose(np.linalg.norm(n1, axis=1), 1.0, atol=1e-12)


def test_bind_pose_is_identity_and_reproduces_rest_mesh():
    sk = two_bone()
    mesh = random_mesh(100, 2)
    S = bind_pose_matrices(sk)
    np.testing.assert_allclose(S, np.broadcast_to(np.eye(4), S.shape), atol=1e-12)
    p, n = skin(mesh, S)
    np.testing.assert_allclose(p, mesh.positions, atol=1e-6)
    np.testing.assert_allclose(n, mesh.normals, atol=1e-6)


def test_rotating_a_bone_moves_its_vertices_and_normals():
    sk = two_bone()
    mesh = Mesh(np.array([[1, 1, 0], [1, 0, 0]], np.float32), np.zeros((0, 3), np.uint32),
                np.array([[1, 0, 0], [1, 0, 0]], np.float32),
                joints=np.array([[1, 0, 0, 0], [0, 0, 0, 0]], np.uint16),
                weights=np.array([[1, 0, 0, 0], [1, 0, 0, 0]], np.float32))
    t, r, s = sk.rest_pose()
    r[1] = m3.quat_from_axis_angle([0, 1, 0], np.pi / 2)  # x -> -z about joint b at (0,1,0)
    p, n = skin(mesh, sk.skinning_matrices(t, r, s))
    np.testing.assert_allclose(p, [[0, 1, -1], [1, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(n, [[0, 0, -1], [1, 0, 0]], atol=1e-12)


def test_nonuniform_scale_uses_inverse_transpose():
    sk = two_bone()
    # a plane x + y = 0 has normal (1,1)/sqrt2; scaling x by 2 maps it to x/2 + y = 0 -> normal (1,2)
    mesh = Mesh(np.zeros((1, 3), np.float32), np.zeros((0, 3), np.uint32),
                np.array([[1, 1, 0]], np.float32) / np.sqrt(2),
                joints=np.zeros((1, 4), np.uint16), weights=np.array([[1, 0, 0, 0]], np.float32))
    S = np.tile(np.eye(4), (2, 1, 1))
    S[0, 0, 0] = 2.0
    _, n = skin(mesh, S)
    np.testing.assert_allclose(n[0], np.array([1, 2, 0]) / np.sqrt(5), atol=1e-7)


def test_degenerate_blends_never_nan():
    mesh = random_mesh(50, 2)
    mesh.weights[:10] = 0.0  # all-zero weights -> zero matrix
    S = np.tile(np.eye(4), (2, 1, 1))
    S[1, :3, :3] = 0.0  # a joint scaled to nothing
    for fn in (skin, skin_reference):
        p, n = fn(mesh, S)
        assert np.all(np.isfinite(p)) and np.all(np.isfinite(n))
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    p1, n1 = skin(mesh, S)
    p2, n2 = skin_reference(mesh, S)
    np.testing.assert_allclose(p1, p2, atol=1e-12)
    np.testing.assert_allclose(n1, n2, atol=1e-6)


def test_bad_inputs_raise_clear_errors():
    mesh = random_mesh(10, 4)
    with pytest.raises(ValueError, match="only 2 matrices"):
        skin(mesh, np.tile(np.eye(4), (2, 1, 1)))
    with pytest.raises(ValueError, match="not a skinned mesh"):
        skin(Mesh(mesh.positions, mesh.indices), np.tile(np.eye(4), (4, 1, 1)))
    assert blend_matrices(mesh, np.tile(np.eye(4), (4, 1, 1))).shape == (10, 4, 4)
