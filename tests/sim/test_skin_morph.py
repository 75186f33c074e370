"""Morph targets of skinned meshes on the CPU (glTF 2.0 §3.7.2.2): clip weights,
``morph``, ``skin ∘ morph`` (numba against numpy), and the keyframes
``bake_skinned`` makes of them."""
import numpy as np
import pytest

from tiny_characters import tiny_morphed, tiny_skinned

from sim.clip import Channel, Clip
from sim.keyframes import bake_skinned
from sim.skinning import morph, pose_positions, skin, skin_morph, skin_morph_reference


@pytest.fixture(scope="module")
def ch():
    return tiny_morphed()


def test_clip_weights_follow_their_channels_and_defaults_elsewhere(ch):
    mt = ch.mesh.morph
    bend = ch.clips["bend"]
    t = np.linspace(0.0, 1.0, 9)
    W = bend.morph_weights(mt, t)
    assert W.shape == (9, 4)
    np.testing.assert_allclose(W[:, 0], 0.5 + 0.5 * np.sin(2 * np.pi * t), atol=1e-12)
    np.testing.assert_allclose(W[:, 2], 0.6)  # STEP single key
    np.testing.assert_allclose(W[:, 3], 0.0)  # no channel: default weight
    # LINEAR between keys: the mean of the two neighbours
    mid = bend.morph_weights(mt, [0.0625])[0]
    np.testing.assert_allclose(mid[1], 0.5 * (W[0, 1] + W[1, 1]), atol=1e-12)
    # looping: t = duration + 0.25 is t = 0.25
    np.testing.assert_allclose(bend.morph_weights(mt, [1.25]), bend.morph_weights(mt, [0.25]), atol=1e-12)
    # CUBICSPLINE: the key values at the keys, the Hermite spline between them (glTF Appendix C:
    # tangents scaled by the key interval 0.35): at u = 1/2, v0/2 + (m0 - m1) * 0.35 / 8 + v1/2
    tw = ch.clips["twist"]
    np.testing.assert_allclose(tw.morph_weights(mt, [0.0, 0.35, 0.7])[:, :2], [[0, 1], [1, 0.2], [0.3, 0]], atol=1e-12)
    assert tw.morph_weights(mt, [0.175])[0, 0] == pytest.approx(0.5 + (3.0 - 2.0) * 0.35 / 8, abs=1e-12)
    assert tw.has_morph_weights() and not tiny_skinned().clips["bend"].has_morph_weights()


def test_clip_weights_channel_outside_the_targets_is_an_error(ch):
    bad = Clip("bad", 1.0, [Channel(3, "weights", np.array([0.0]), np.array([[1.0, 1.0]]))])
    with pytest.raises(ValueError, match="drives targets 3..4, the mesh has 4 morph targets"):
        bad.morph_weights(ch.mesh.morph, [0.0])
    with pytest.raises(ValueError, match="expected 4 per row"):
        ch.mesh.morph.offsets(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        ch.mesh.morph.offsets([np.nan, 0, 0, 0])


def test_morph_is_the_gltf_sum_over_the_weight_zero_base(ch):
    m = ch.mesh
    mt = m.morph
    w = np.array([0.7, -0.4, 1.3, 0.25])
    base = m.positions.astype(np.float64) - np.einsum("m,mvc->vc", mt.default_weights, mt.positions)
    p, n = morph(m, w)
    np.testing.assert_allclose(p, base + np.einsum("m,mvc->vc", w, mt.positions.astype(np.float64)), atol=1e-6)
    nb = m.normals.astype(np.float64) - np.einsum("m,mvc->vc", mt.default_weights, mt.normals)
    want = nb + np.einsum("m,mvc->vc", w, mt.normals.astype(np.float64))
    np.testing.assert_allclose(n, want / np.linalg.norm(want, axis=1, keepdims=True), atol=1e-6)
    # default weights: the mesh itself
    p0, n0 = morph(m, mt.default_weights)
    np.testing.assert_array_equal(p0, m.positions.astype(np.float64))
    np.testing.assert_array_equal(n0, m.normals.astype(np.float64))


def test_skin_morph_kernel_matches_numpy_reference_and_is_skin_at_default_weights(ch):
    clip = ch.clips["twist"]
    for t in (0.0, 0.13, 0.41, 0.7):
        mats = clip.skinning_matrices(ch.skeleton, [t])[0]
        w = clip.morph_weights(ch.mesh.morph, [t])[0]
        p, n = skin_morph(ch.mesh, mats, w)
        pr, nr = skin_morph_reference(ch.mesh, mats, w)
        assert np.abs(p - pr).max() < 1e-12 and np.abs(n - nr).max() < 1e-12
        assert np.isfinite(n).all() and np.allclose(np.linalg.norm(n, axis=1), 1.0)
        ps, ns = skin(ch.mesh, mats)
        pd, nd = skin_morph(ch.mesh, mats, ch.mesh.morph.default_weights)
        np.testing.assert_array_equal(pd, ps)
        np.testing.assert_array_equal(nd, ns)
        assert np.abs(p - ps).max() > 0.05  # the morph moves the mesh


def test_pose_positions_plays_the_morph_weights(ch):
    clip = ch.clips["bend"]
    t = 0.3
    want, _ = skin_morph(ch.mesh, clip.skinning_matrices(ch.skeleton, [t])[0], clip.morph_weights(ch.mesh.morph, [t])[0])
    got, _ = pose_positions(ch, "bend", t)
    np.testing.assert_array_equal(got, want)
    plain = tiny_skinned()
    np.testing.assert_array_equal(pose_positions(plain, "bend", t)[0],
                                  skin(plain.mesh, plain.clips["bend"].skinning_matrices(plain.skeleton, [t])[0])[0])


@pytest.mark.parametrize("clip_name", ["bend", "twist"])
def test_baked_keyframes_are_skin_morph_at_the_key_times(ch, clip_name):
    anim = bake_skinned(ch, clip_name, 7)
    clip = ch.clips[clip_name]
    assert len(anim.keyframes) == 7
    for t, kf in zip(anim.times, anim.keyframes):
        p, n = skin_morph(ch.mesh, clip.skinning_matrices(ch.skeleton, [t])[0], clip.morph_weights(ch.mesh.morph, [t])[0])
        assert np.abs(kf.positions - p).max() < 1e-6
        assert np.abs(kf.normals - n).max() < 1e-6


def test_describe_lists_the_targets_and_bounds_the_morphed_clips(ch):
    from sim.describe import _sample_times, describe

    d = describe(ch)
    assert d["morph_targets"] == ["bulge", "lean", "squash", "idle"]
    assert describe(tiny_skinned())["morph_targets"] == []
    lo, hi = np.array(d["bounds"]["animated"]["min"]), np.array(d["bounds"]["animated"]["max"])
    for t in _sample_times(1.0)[::3]:  # the sampled poses, morphed
        p, _ = pose_positions(ch, "bend", t)
        assert (p >= lo - 1e-9).all() and (p <= hi + 1e-9).all()
    assert hi[0] > describe(tiny_skinned())["bounds"]["animated"]["max"][0] + 0.05
