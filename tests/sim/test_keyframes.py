"""sim.keyframes: Wand & Straßer §3 keyframe animations with topology changes."""
import numpy as np
import pytest

from sim import procedural
from sim.keyframes import Correspondence, KeyframeAnimation, Segment, bake_skinned, from_meshes
from sim.mesh import Mesh
from sim.skinning import pose_positions


def tri_area(p, t):
    t = np.asarray(t, np.int64)
    return 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)


def two_keyframes():
    """Keyframe 0: a quad (two triangles). Keyframe 1: triangle 0 moved, triangle 1 of k0
    gone (shrinks into vertex 0), a new triangle (1, 3, 2) grows out of vertex 1 of k0."""
    m0 = Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32),
              np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
              colors=np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [1, 1, 1, 1]], np.float32))
    m1 = Mesh(np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [2, 0.5, 1]], np.float32),
              np.array([[0, 1, 2], [1, 3, 2]], np.uint32),
              colors=np.array([[0, 0, 0, 1], [0.5, 0.5, 0.5, 1], [1, 1, 0, 1], [0, 1, 1, 1]], np.float32))
    fwd = Correspondence(pairs=[(0, 0), (1, 1), (2, 2)], appear=[(1, 1)], vanish=[(1, 0)])
    back = {"pairs": [(0, 0), (1, 1), (2, 2)], "appear": [(1, 0)], "vanish": [(1, 1)]}
    return m0, m1, fwd, back


def anim():
    m0, m1, fwd, back = two_keyframes()
    return from_meshes("quad", [0.0, 1.0], [m0, m1], [fwd, back], loop=True, duration=2.0)


def test_endpoints_reproduce_keyframes_exactly():
    a = anim()
    for k, u, kf_side in ((0, 0.0, "src"), (0, 1.0, "dst"), (1, 0.0, "src"), (1, 1.0, "dst")):
        seg = a.segments[k]
        kf = a.segment_keyframes(k)[0 if kf_side == "src" else 1]
        vid = seg.src if kf_side == "src" else seg.dst
        p, n, c, idx = a.interpolate_segment(k, u)
        np.testing.assert_array_equal(p, kf.positions[vid])
        np.testing.assert_array_equal(c, kf.colors[vid])
        np.testing.assert_allclose(n, kf.normals[vid], atol=1e-6)
        assert idx.dtype == np.uint32 and p.dtype == np.float32


def test_appearing_triangle_grows_from_a_point_and_vanishing_one_shrinks():
    a = anim()
    seg = a.segments[0]
    # segment triangles: [surviving, vanishing, appearing]
    assert seg.indices.shape == (3, 3)
    p0, _, _, idx = a.interpolate_segment(0, 0.0)
    p1, _, _, _ = a.interpolate_segment(0, 1.0)
    ph, _, _, _ = a.interpolate_segment(0, 0.5)
    area0, area1, areah = tri_area(p0, idx), tri_area(p1, idx), tri_area(ph, idx)
    assert area0[0] == pytest.approx(0.5) and area1[0] == pytest.approx(0.5)
    assert area0[1] == pytest.approx(0.5) and area1[1] == 0.0  # vanishes into vertex 0 of k1
    assert area0[2] == 0.0 and area1[2] == pytest.approx(0.5)  # grows out of vertex 1 of k0
    assert 0 < areah[2] < 0.5 and 0 < areah[1] < 0.5
    # the appearing triangle's three vertices start at vertex 1 of keyframe 0
    np.testing.assert_array_equal(p0[idx[2]], np.tile([1, 0, 0], (3, 1)))
    # the loop segment back to keyframe 0 mirrors it
    p, _, _, idx = a.interpolate_segment(1, 1.0)
    assert tri_area(p, idx)[1] == 0.0 and tri_area(p, idx)[2] == pytest.approx(0.5)


def test_locate_wraps_and_clamps():
    a = anim()
    assert a.locate(0.0) == (0, 0.0)
    assert a.locate(0.5) == (0, 0.5)
    assert a.locate(1.5) == (1, 0.5)
    k, u = a.locate(2.25)
    assert (k, u) == (0, pytest.approx(0.25))
    k, u = a.locate(-0.5)
    assert (k, u) == (1, pytest.approx(0.5))
    assert a.locate(float("nan")) == (0, 0.0)
    a.loop = False
    a.segments = a.segments[:1]
    assert a.locate(5.0) == (0, 1.0) and a.locate(-1.0) == (0, 0.0)


def test_interpolate_linear_midpoint_and_unit_normals():
    a = anim()
    p, n, c, _ = a.interpolate(0.25)
    seg = a.segments[0]
    k0, k1 = a.segment_keyframes(0)
    np.testing.assert_allclose(p, 0.75 * k0.positions[seg.src] + 0.25 * k1.positions[seg.dst], atol=1e-6)
    np.testing.assert_allclose(c, 0.75 * k0.colors[seg.src] + 0.25 * k1.colors[seg.dst], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)


def test_opposite_normals_never_nan():
    m0 = Mesh(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.uint32))
    m1 = Mesh(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.uint32), normals=-m0.ensure_normals())
    a = from_meshes("flip", [0, 1], [m0, m1], loop=False)
    _, n, _, _ = a.interpolate(0.5)
    assert np.all(np.isfinite(n))
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)


def test_builder_errors_are_clear():
    m0, m1, fwd, back = two_keyframes()
    with pytest.raises(ValueError, match="pair 0: keyframes 0 and 1 differ"):
        from_meshes("x", [0, 1], [m0, m1], loop=False)
    with pytest.raises(ValueError, match="expected 2 correspondences"):
        from_meshes("x", [0, 1], [m0, m1], [fwd], loop=True)
    with pytest.raises(ValueError, match="strictly increasing"):
        from_meshes("x", [1, 0], [m0, m1], [fwd], loop=False)
    no_appear = Correspondence(pairs=fwd.pairs, vanish=fwd.vanish)
    with pytest.raises(ValueError, match="triangle 1 of keyframe 1 is neither"):
        from_meshes("x", [0, 1], [m0, m1], [no_appear], loop=False)
    no_vanish = Correspondence(pairs=fwd.pairs, appear=fwd.appear)
    with pytest.raises(ValueError, match="vertex 3 of keyframe 0 lies on a surviving triangle"):
        from_meshes("x", [0, 1], [m0, m1], [no_vanish], loop=False)


def test_explicit_segment_and_single_keyframe():
    m0, m1, _, _ = two_keyframes()
    seg = Segment(np.array([0, 1, 2]), np.array([0, 1, 2]), np.array([[0, 1, 2]]))
    a = from_meshes("s", [0, 1], [m0, m1], [seg], loop=False)
    assert a.duration == 1.0 and len(a.segments) == 1
    one = from_meshes("one", [0.0], [m0], loop=False)
    p, _, _, idx = one.interpolate(3.0)
    np.testing.assert_array_equal(p, m0.positions)
    loop1 = from_meshes("one", [0.0], [m0], loop=True)
    assert loop1.duration == 1.0 and len(loop1.segments) == 1
    np.testing.assert_array_equal(loop1.interpolate(0.3)[0], m0.positions)


def test_bake_skinned_matches_skinning_at_keys():
    c = procedural.humanoid(500, seed=1)
    a = bake_skinned(c, "walk", 8)
    assert isinstance(a, KeyframeAnimation) and len(a.keyframes) == 8 and len(a.segments) == 8
    assert a.duration == pytest.approx(c.clips["walk"].duration)
    for i in (0, 3):
        t = a.times[i]
        p, n, col, idx = a.interpolate(t)
        ref, refn = pose_positions(c, "walk", t)
        np.testing.assert_allclose(p, ref, atol=1e-5)
        np.testing.assert_allclose(n, refn, atol=1e-5)
        np.testing.assert_array_equal(idx, c.mesh.indices)
    # the loop closes: just before the end we are close to the first keyframe
    p_end = a.interpolate(a.duration - 1e-6)[0]
    np.testing.assert_allclose(p_end, a.keyframes[0].positions, atol=1e-4)


def test_keyframed_character_helpers():
    from sim.character import KeyframedCharacter

    a = anim()
    ch = KeyframedCharacter("q", {"quad": a})
    assert ch.clip(0) is a and ch.clip("quad") is a and ch.clip_index("quad") == 0
    assert ch.duration(0) == 2.0
    lo, hi = ch.rest_bounds()
    np.testing.assert_allclose(lo, [0, 0, 0])
    np.testing.assert_allclose(hi, [1, 1, 0])
