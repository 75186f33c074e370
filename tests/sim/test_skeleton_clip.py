"""sim.skeleton forward kinematics and sim.clip sampling (glTF interpolation modes)."""
import numpy as np
import pytest

from sim import math3d as m3
from sim.clip import Channel, Clip
from sim.skeleton import Skeleton


def chain(root_transform=None):
    """root at (0,1,0), child and grandchild 1 m above each other along +Y."""
    J = 3
    sk = Skeleton(
        names=["root", "mid", "tip"],
        parents=np.array([-1, 0, 1], np.int32),
        rest_translation=np.array([[0, 1, 0], [0, 1, 0], [0, 1, 0]], np.float64),
        rest_rotation=np.tile([0, 0, 0, 1.0], (J, 1)),
        rest_scale=np.ones((J, 3)),
        inverse_bind=np.tile(np.eye(4), (J, 1, 1)),
        root_transform=root_transform,
    )
    sk.inverse_bind = sk.rest_inverse_bind()
    return sk


def test_fk_rest_positions_and_identity_skinning():
    sk = chain()
    np.testing.assert_allclose(sk.joint_positions(), [[0, 1, 0], [0, 2, 0], [0, 3, 0]])
    S = sk.skinning_matrices(*sk.rest_pose())
    np.testing.assert_allclose(S, np.broadcast_to(np.eye(4), S.shape), atol=1e-12)


def test_fk_rotation_propagates_to_children():
    sk = chain()
    t, r, s = sk.rest_pose()
    r[1] = m3.quat_from_axis_angle([0, 0, 1], np.pi / 2)  # bend at mid: tip goes to -X
    G = sk.global_matrices(t, r, s)
    np.testing.assert_allclose(G[2, :3, 3], [-1, 2, 0], atol=1e-12)
    np.testing.assert_allclose(G[1, :3, 3], [0, 2, 0], atol=1e-12)


def test_root_transform_applies_to_roots():
    rt = m3.trs_matrix([5, 0, 0], m3.quat_from_axis_angle([0, 1, 0], np.pi), [2, 2, 2])
    sk = chain(rt)
    np.testing.assert_allclose(sk.joint_positions()[2], [5, 6, 0], atol=1e-12)
    # inverse bind built from the same rest pose -> identity skinning
    S = sk.skinning_matrices(*sk.rest_pose())
    np.testing.assert_allclose(S, np.broadcast_to(np.eye(4), S.shape), atol=1e-12)


def test_fk_batched_matches_single():
    sk = chain()
    rng = np.random.default_rng(0)
    R = m3.quat_normalize(rng.normal(size=(5, 3, 4)))
    T = rng.normal(size=(5, 3, 3))
    S = np.ones((5, 3, 3))
    G = sk.global_matrices(T, R, S)
    assert G.shape == (5, 3, 4, 4)
    for i in range(5):
        np.testing.assert_allclose(G[i], sk.global_matrices(T[i], R[i], S[i]), atol=1e-12)


def test_fk_wrong_joint_count_raises():
    with pytest.raises(ValueError, match="expected 3 joints"):
        chain().global_matrices(np.zeros((2, 3)), np.tile([0, 0, 0, 1.0], (2, 1)), np.ones((2, 3)))


def q(angle):
    return m3.quat_from_axis_angle([0, 1, 0], angle)


def make_clip(interp="LINEAR", loop=True):
    times = np.array([0.0, 1.0, 2.0])
    if interp == "CUBICSPLINE":
        tv = np.zeros((3, 3, 3))
        tv[:, 1] = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]
        tv[:, 0] = tv[:, 2] = [1, 0, 0]  # slope 1 m/s: Hermite reproduces the line
        rv = np.zeros((3, 3, 4))
        rv[:, 1] = [q(0), q(1), q(2)]
        tchan = Channel(1, "translation", times, tv, interp)
        rchan = Channel(0, "rotation", times, rv, interp)
    else:
        tchan = Channel(1, "translation", times, np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]), interp)
        rchan = Channel(0, "rotation", times, np.array([q(0), -q(1), q(2)]), interp)  # -q: same rotation
    return Clip("c", 2.0, [tchan, rchan], loop=loop)


def test_linear_sampling_slerp_and_rest_for_missing_channels():
    sk = chain()
    clip = make_clip()
    t, r, s = clip.sample(sk, 0.5)
    np.testing.assert_allclose(t[1], [0.5, 0, 0])
    np.testing.assert_allclose(t[2], [0, 1, 0])  # no channel: rest
    np.testing.assert_allclose(np.abs(r[0]), np.abs(q(0.5)), atol=1e-12)
    _, ang = m3.quat_to_axis_angle(clip.sample(sk, 1.5)[1][0])
    assert ang == pytest.approx(1.5)  # shortest path through the negated key
    np.testing.assert_allclose(s, np.ones((3, 3)))


def test_clamp_before_first_and_after_last_key():
    sk = chain()
    times = np.array([0.5, 1.5])
    ch = Channel(1, "translation", times, np.array([[1, 0, 0], [3, 0, 0.0]]))
    clip = Clip("c", 2.0, [ch], loop=False)
    assert clip.sample(sk, 0.0)[0][1, 0] == 1.0
    assert clip.sample(sk, 1.8)[0][1, 0] == 3.0
    assert clip.sample(sk, 10.0)[0][1, 0] == 3.0
    assert clip.sample(sk, -3.0)[0][1, 0] == 1.0


def test_loop_wraps_modulo_duration():
    sk = chain()
    clip = make_clip()
    a = clip.sample(sk, 0.25)[0]
    np.testing.assert_allclose(clip.sample(sk, 2.25)[0], a)
    np.testing.assert_allclose(clip.sample(sk, -1.75)[0], a)
    clip.loop = False
    np.testing.assert_allclose(clip.sample(sk, 2.25)[0][1], [2, 0, 0])


def test_step_interpolation():
    sk = chain()
    clip = make_clip("STEP")
    np.testing.assert_allclose(clip.sample(sk, 0.99)[0][1], [0, 0, 0])
    np.testing.assert_allclose(clip.sample(sk, 1.0)[0][1], [1, 0, 0])
    np.testing.assert_allclose(clip.sample(sk, 1.7)[0][1], [1, 0, 0])


def test_cubicspline_hermite():
    sk = chain()
    clip = make_clip("CUBICSPLINE")
    for t in (0.0, 0.3, 1.0, 1.6):
        np.testing.assert_allclose(clip.sample(sk, t)[0][1], [t, 0, 0], atol=1e-12)
    # zero tangents: smoothstep between keys
    ch = Channel(1, "translation", np.array([0.0, 1.0]), np.array([[[0, 0, 0], [0, 0, 0], [0, 0, 0]], [[0, 0, 0], [1, 0, 0], [0, 0, 0]]], float), "CUBICSPLINE")
    c2 = Clip("s", 1.0, [ch], loop=False)
    assert c2.sample(sk, 0.25)[0][1, 0] == pytest.approx(3 * 0.25**2 - 2 * 0.25**3)
    # rotations come back unit length
    r = clip.sample(sk, 0.5)[1][0]
    assert np.linalg.norm(r) == pytest.approx(1.0)


def test_sample_times_matches_sample_and_zero_duration():
    sk = chain()
    clip = make_clip()
    ts = np.linspace(-1, 5, 13)
    T, R, S = clip.sample_times(sk, ts)
    for i, t in enumerate(ts):
        t1, r1, s1 = clip.sample(sk, t)
        np.testing.assert_allclose(T[i], t1)
        np.testing.assert_allclose(R[i], r1)
    z = Clip("z", 0.0, make_clip().channels)
    T, R, S = z.sample_times(sk, [0.0, 1.0, np.nan])
    assert np.all(np.isfinite(T)) and np.all(np.isfinite(R))
    np.testing.assert_allclose(T[2, 1], [0, 0, 0])


def test_single_key_channel_and_bad_interpolation():
    sk = chain()
    ch = Channel(2, "scale", np.array([0.3]), np.array([[2, 2, 2.0]]))
    np.testing.assert_allclose(Clip("k", 1.0, [ch]).sample(sk, 0.9)[2][2], [2, 2, 2])
    bad = Clip("b", 1.0, [Channel(0, "translation", np.array([0, 1.0]), np.zeros((2, 3)), "QUADRATIC")])
    with pytest.raises(ValueError, match="QUADRATIC"):
        bad.sample(sk, 0.5)


def test_unordered_parents_raise():
    sk = chain()
    sk.parents = np.array([-1, 2, 0], np.int32)
    with pytest.raises(ValueError, match="joint 1 .* topologically ordered"):
        sk.global_matrices(*sk.rest_pose())
