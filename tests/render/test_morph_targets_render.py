"""Morph targets blended on the GPU before skinning (glTF 2.0 §3.7.2.2;
``shaders/poses/targets.glsl``, ``render/poses/targets.py``) against the CPU reference
``sim.skinning.skin_morph``: vertices read back through transform feedback, and
frames of mode none and of mode triangles (level 0) pixel for pixel against the
reference mesh drawn as a static mesh through the same renderer.

Normals: the skinned shaders and ``sim.skinning`` both take the inverse
transpose of the blended matrix (cofactor times the sign of the determinant,
``skinning.glsl skin_normal``; issue 29), so the static reference draws the CPU
``skin ∘ morph`` positions and normals as they are."""
import numpy as np
import pytest

from tiny_characters import tiny_morphed, tiny_skinned

from lod.chains import chain as tm_chain
from lod.chains import mode as tm
from lod.drawlist import INSTANCE_FLOATS
from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep, build_static_rep
from lod.view import Camera
from render.renderer import Renderer
from render.poses.targets import TARGETS_DEFINE, target_textures
from sim.mesh import Mesh
from sim.skinning import skin, skin_morph
from sim.state import CrowdState

SIZE = (320, 240)
CAM = Camera.look_at((0.5, 2.0, 6.0), (0.2, 1.4, 0.0), fov_y=45)
PATHS = ["palette", "direct"]


@pytest.fixture(scope="module")
def ch():
    return tiny_morphed()


@pytest.fixture(scope="module")
def rep(ch):
    return build_rep(ch, fps=30)


def _frames(rep, c, idx):
    d = np.zeros((len(idx), INSTANCE_FLOATS), np.float32)
    d[:, 0] = d[:, 5] = d[:, 10] = 1.0
    d[:, 12] = rep.clip_offset[c] + np.asarray(idx, np.float64)
    return d


def _reference(ch, clip_name, t, morphed=True):
    """CPU skin ∘ morph positions and normals (inverse transpose, module docstring)."""
    clip = ch.clips[clip_name]
    mats = clip.skinning_matrices(ch.skeleton, [t])[0]
    w = clip.morph_weights(ch.mesh.morph, [t])[0] if morphed else ch.mesh.morph.default_weights
    return skin_morph(ch.mesh, mats, w)


@pytest.mark.parametrize("skinning", PATHS)
def test_gpu_vertices_are_skin_of_morph_at_baked_frames(gl_ctx, ch, rep, skinning):
    r = Renderer((8, 8), ctx=gl_ctx, debug=True, skinning=skinning)
    r.upload(rep)
    extent = float(np.ptp(rep.positions, axis=0).max())
    moved = 0.0
    for c, name in enumerate(rep.clip_names):
        idx = np.arange(int(rep.clip_frames[c]))
        gp, gn = r.capture(rep.key, _frames(rep, c, idx))
        for k in idx:
            t = k / rep.clip_fps[c]
            p, n = _reference(ch, name, t)
            assert np.abs(gp[k] - p).max() <= 1e-5 * extent, (name, k)
            unit = gn[k] / np.linalg.norm(gn[k], axis=1, keepdims=True)
            assert np.abs(unit - n / np.linalg.norm(n, axis=1, keepdims=True)).max() < 1e-5, (name, k)
            moved = max(moved, float(np.abs(gp[k] - skin(ch.mesh, ch.clips[name].skinning_matrices(
                ch.skeleton, [t])[0])[0]).max()))
    assert moved > 0.2  # the targets move vertices by up to decimetres
    r.release()


def test_gpu_blends_weights_between_frames_like_the_matrices(gl_ctx, rep):
    r = Renderer((8, 8), ctx=gl_ctx, debug=True)
    r.upload(rep)
    fr = np.array([3.25, 17.5, 29.9, 31.0 + 4.75])  # clip 0 (31 frames) and clip 1
    d = _frames(rep, 0, fr)
    gp, _ = r.capture(rep.key, d)
    for k, f in enumerate(fr):
        f0, a = int(np.floor(f)), f - np.floor(f)
        m = (1 - a) * rep.joint_table[f0].astype(np.float64) + a * rep.joint_table[f0 + 1]
        w = (1 - a) * rep.targets.weights[f0].astype(np.float64) + a * rep.targets.weights[f0 + 1]
        q, _ = rep.targets.morph(rep.positions, rep.normals, w)
        M = np.einsum("vk,vkab->vab", rep.weights.astype(np.float64), m[rep.joints.astype(np.int64)])
        want = np.einsum("vab,vb->va", M[:, :, :3], q) + M[:, :, 3]
        assert np.abs(gp[k] - want).max() < 1e-5, f
    r.release()


def test_only_characters_with_targets_use_the_morph_variant(gl_ctx, rep):
    r = Renderer((8, 8), ctx=gl_ctx, debug=True)
    r.specialize_influences = False  # the programs differ by the targets define only (no SKIN_INFLUENCES_n)
    plain = build_rep(tiny_skinned(), fps=30)
    r.upload(plain)
    r.upload(rep)
    pp, mp = r._reps[plain.key].vao.program, r._reps[rep.key].vao.program
    assert pp is r.program("skinned") and mp is r.program("skinned", defines=(TARGETS_DEFINE,))
    assert not any(u in pp for u in ("u_targets_index", "u_targets_delta", "u_targets_weight"))
    assert all(u in mp for u in ("u_targets_index", "u_targets_delta", "u_targets_weight"))
    assert r._reps[plain.key].targets is None and len(r._reps[rep.key].targets) == 3
    bad = rep.targets.__class__(**{**rep.targets.__dict__, "weights": rep.targets.weights * np.float32(np.nan)})
    with pytest.raises(ValueError, match="NaN or Inf"):
        target_textures(gl_ctx, bad, rep.joint_table.shape[0], "bad")
    r.release()


def _crowd():
    st = CrowdState.empty(3)
    st.position[:] = [[-1.2, 0, 0], [0.2, 0, -0.5], [1.5, 0, 0.3]]
    st.heading[:] = [0.3, -0.7, 1.9]
    st.clip[:] = [0, 1, 0]
    st.anim_time[:] = [7 / 30, 12 / 30, 22 / 30]  # baked frames
    return st


def _reference_image(r, ch, st, morphed=True):
    statics, sreps = [], []
    for i in range(st.n):
        p, n = _reference(ch, ["bend", "twist"][int(st.clip[i])], float(st.anim_time[i]), morphed)
        m = Mesh(p.astype(np.float32), ch.mesh.indices, normals=n.astype(np.float32), colors=ch.mesh.colors)
        sr = build_static_rep(m, key=f"static:ref{i}")
        r.upload(sr)
        sreps.append(sr)
        c, s, sc = np.cos(st.heading[i]), np.sin(st.heading[i]), float(st.scale[i])
        world = np.array([[c * sc, 0, s * sc, st.position[i, 0]], [0, sc, 0, st.position[i, 1]],
                          [-s * sc, 0, c * sc, st.position[i, 2]], [0, 0, 0, 1]])
        statics.append((sr.key, world))
    r.draw(NoLodSelector([], static_reps=sreps).select(CrowdState.empty(0), CAM, SIZE, statics=statics))
    return r.read_pixels().astype(np.int32)


def _compare(r, ch, image):
    ref = _reference_image(r, ch, _crowd())
    unmorphed = _reference_image(r, ch, _crowd(), morphed=False)
    diff = np.abs(image - ref).max(axis=2)
    fg = int((image.max(axis=2) > 40).sum())
    changed = int((np.abs(unmorphed - ref).max(axis=2) > 2).sum())
    return int(diff.max()), fg, changed


@pytest.mark.parametrize("skinning", PATHS)
def test_mode_none_frame_is_pixel_equal_to_the_cpu_reference(gl_ctx, ch, rep, skinning):
    r = Renderer(SIZE, ctx=gl_ctx, debug=True, skinning=skinning)
    r.upload(rep)
    r.draw(NoLodSelector([rep]).select(_crowd(), CAM, SIZE))
    worst, fg, changed = _compare(r, ch, r.read_pixels().astype(np.int32))
    assert worst <= 2, f"max difference {worst}/255"
    assert fg > 5000 and changed > 1000  # three characters in view, and the morphs change many pixels
    r.release()


@pytest.fixture(scope="module")
def chain(ch):
    reps, sel = tm.build([ch], ["m"], [30], {"poe": 0.0, "levels": 4}, cache=False)
    return reps[0], sel


@pytest.mark.parametrize("skinning", PATHS)
def test_mode_triangles_level_0_is_pixel_equal_to_the_cpu_reference(gl_ctx, ch, chain, skinning):
    trep, sel = chain
    r = Renderer(SIZE, ctx=gl_ctx, debug=True, skinning=skinning)
    r.upload(trep)
    dl = sel.select(_crowd(), CAM, SIZE)
    assert all(b.level == 0 for b in dl.batches) and dl.stats["levels"][0] == 3
    r.draw(dl)
    worst, fg, changed = _compare(r, ch, r.read_pixels().astype(np.int32))
    assert worst <= 2, f"max difference {worst}/255"
    assert fg > 5000 and changed > 1000
    r.release()


@pytest.mark.parametrize("skinning", PATHS)
def test_chain_geomorph_ends_are_the_two_morphed_levels(gl_ctx, chain, skinning):
    """A geomorphed level (shaders/*_morph.vert) morphs its vertices and their
    collapse targets alike: weight 0 is the level, weight 1 the coarser level."""
    trep, sel = chain
    assert trep.n_levels >= 3
    r = Renderer(SIZE, ctx=gl_ctx, debug=True, skinning=skinning)
    r.upload(trep)

    def image(level, morph=None):
        dl = sel.select(_crowd(), CAM, SIZE)
        dl.batches = [tm_chain.TriangleDrawBatch(b.rep, b.part, b.instance_ids, b.instance_data, level=level,
                                                 index_range=(3 * int(trep.level_first[level]),
                                                              3 * int(trep.level_count[level])), morph=morph)
                      for b in dl.batches]
        r.draw(dl)
        return r.read_pixels().astype(np.int32)

    for level in (0, 1):
        fine, coarse = image(level), image(level + 1)
        assert np.abs(image(level, (level + 1, 0.0)) - fine).max() <= 1
        assert np.abs(image(level, (level + 1, 1.0)) - coarse).max() <= 1
        assert (np.abs(fine - coarse).max(axis=2) > 2).sum() > 50  # the levels differ
    r.release()


def test_shader_defines_go_after_the_version_line_and_only_into_the_variant():
    from render.shaders import program_sources, with_defines

    plain = program_sources("skinned")["vertex_shader"]
    var = program_sources("skinned", defines=(TARGETS_DEFINE,))["vertex_shader"]
    assert var.splitlines()[0] == plain.splitlines()[0] == "#version 330 core"
    assert var.splitlines()[1] == "#define MORPH_TARGETS 1" and "#define" not in plain
    assert var.replace("#define MORPH_TARGETS 1\n", "", 1) == plain
    with pytest.raises(ValueError, match="GLSL identifier"):
        with_defines(plain, ("NOT OK",))
