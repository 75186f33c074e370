"""The vertex shaders against the CPU references, read back through transform
feedback (the capture programs share the draw shaders' GLSL)."""
import numpy as np
import pytest

from tiny_characters import tiny_keyframed, tiny_skinned

from lod.drawlist import INSTANCE_FLOATS
from lod.full.pack import model_rows
from lod.full.reps import build_rep
from render.renderer import Renderer
from sim.procedural import humanoid, quadruped
from sim.skinning import skin


@pytest.fixture(scope="module", params=["palette", "direct"])
def renderer(gl_ctx, request):
    r = Renderer((64, 64), ctx=gl_ctx, debug=True, skinning=request.param)
    yield r
    r.release()


def _identity_instances(frames):
    d = np.zeros((len(frames), INSTANCE_FLOATS), np.float32)
    d[:, 0] = d[:, 5] = d[:, 10] = 1.0
    d[:, 12] = frames
    return d


@pytest.mark.parametrize("make", [lambda: humanoid(3000, seed=1), lambda: quadruped(1500, seed=2), tiny_skinned],
                         ids=["humanoid", "quadruped", "tiny"])
def test_gpu_skinning_matches_cpu_reference_at_baked_frames(renderer, make):
    ch = make()
    rep = build_rep(ch, fps=30)
    renderer.upload(rep)
    for c, name in enumerate(rep.clip_names):
        clip = ch.clips[name]
        n = int(rep.clip_frames[c])
        idx = np.unique(np.linspace(0, n - 1, 6).round().astype(int))
        frames = rep.clip_offset[c] + idx
        gpu, _ = renderer.capture(rep.key, _identity_instances(frames))
        mats = clip.skinning_matrices(ch.skeleton, idx / rep.clip_fps[c])
        extent = float(np.ptp(rep.positions, axis=0).max())
        for k in range(len(idx)):
            cpu, _ = skin(ch.mesh, mats[k])
            err = np.abs(gpu[k] - cpu).max()
            assert err <= 1e-4 * extent, f"{name} frame {idx[k]}: max error {err}"


def test_gpu_normals_are_the_inverse_transpose_of_the_blended_matrix(renderer):
    """Issue 29 item 5: where blended joints rotate apart the blended matrix is not a rotation, and its linear
    part bends normals wrongly; both GPU paths now take its inverse transpose, as sim.skinning does."""
    ch = humanoid(3000, seed=1)
    rep = build_rep(ch, fps=30)
    renderer.upload(rep)
    c = 0
    clip = ch.clips[rep.clip_names[c]]
    idx = np.array([4, 11, 19])
    _, gpu = renderer.capture(rep.key, _identity_instances(rep.clip_offset[c] + idx))
    worst_linear = 0.0
    for k, M in enumerate(clip.skinning_matrices(ch.skeleton, idx / rep.clip_fps[c])):
        _, cpu = skin(ch.mesh, M)
        unit = gpu[k] / np.linalg.norm(gpu[k], axis=1, keepdims=True)
        assert np.abs(unit - cpu).max() < 2e-4, f"frame {idx[k]}"
        B = np.einsum("vk,vkab->vab", rep.weights.astype(np.float64), M[rep.joints.astype(np.int64)])[:, :3, :3]
        lin = np.einsum("vab,vb->va", B, np.asarray(ch.mesh.ensure_normals(), np.float64))
        lin /= np.linalg.norm(lin, axis=1, keepdims=True)
        worst_linear = max(worst_linear, float(np.abs(lin - cpu).max()))
    assert worst_linear > 1e-2  # the blended matrix's linear part would be visibly off


def test_gpu_interpolates_matrices_between_frames_and_applies_instance(renderer):
    ch = tiny_skinned()
    rep = build_rep(ch, fps=30)
    renderer.upload(rep)
    rel = np.array([[3.0, -1.0, -7.0]])
    rows = model_rows(rel, np.array([0.8]), np.array([1.5]))
    d = np.zeros((1, INSTANCE_FLOATS), np.float32)
    d[0, :12] = rows[0]
    d[0, 12] = 12.25
    gpu, nrm = renderer.capture(rep.key, d)
    m = 0.75 * rep.joint_table[12].astype(np.float64) + 0.25 * rep.joint_table[13]
    S = np.tile(np.eye(4), (3, 1, 1))
    S[:, :3, :] = m
    cpu, _ = skin(ch.mesh, S)
    M = rows[0].reshape(3, 4).astype(np.float64)
    world = cpu @ M[:, :3].T + M[:, 3]
    assert np.abs(gpu[0] - world).max() < 1e-4 * 10
    assert np.isfinite(nrm).all()


def test_keyframe_interpolation_on_gpu_gives_keyframes_at_u0_and_u1(renderer):
    ch = tiny_keyframed()
    anim = ch.animations["wave"]
    rep = build_rep(ch)
    renderer.upload(rep)
    d = _identity_instances([0.0, 1.0, 0.5])
    gpu, _ = renderer.capture(rep.key, d)
    K = len(anim.keyframes)
    for s, seg in enumerate(anim.segments):
        a = int(rep.seg_first[s])
        verts = np.unique(rep.indices.reshape(-1)[a:a + int(rep.seg_count[s])])
        base = verts.min()
        src = anim.keyframes[s % K].positions[seg.src]
        dst = anim.keyframes[(s + 1) % K].positions[seg.dst]
        got0 = gpu[0, base:base + len(seg.src)]
        got1 = gpu[1, base:base + len(seg.src)]
        assert np.allclose(got0, src, atol=1e-6)
        assert np.allclose(got1, dst, atol=1e-6)
        assert np.allclose(gpu[2, base:base + len(seg.src)], 0.5 * (src + dst), atol=1e-6)


def test_static_path_applies_the_instance_matrix(renderer):
    from sim.mesh import Mesh

    m = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]], np.uint32))
    rep = build_rep(m, key="tri")
    renderer.upload(rep)
    d = np.zeros((1, INSTANCE_FLOATS), np.float32)
    d[0, :12] = model_rows(np.array([[1.0, 2.0, 3.0]]), np.array([np.pi / 2]), np.array([2.0]))[0]
    gpu, _ = renderer.capture("tri", d)
    assert np.allclose(gpu[0], [[1, 2, 3], [1, 2, 1], [1, 4, 3]], atol=1e-6)


def test_palette_blocks_wrapping_across_texture_rows_match_direct_skinning(gl_ctx):
    """A narrow palette (12 texels: 9-texel blocks straddle rows) and many
    instances at fractional frames give the direct path's vertices."""
    ch = tiny_skinned()
    rep = build_rep(ch, fps=30)
    frames = np.linspace(0.0, rep.joint_table.shape[0] - 1.0, 57)
    out = []
    for mode in ("palette", "direct"):
        r = Renderer((8, 8), ctx=gl_ctx, debug=True, skinning=mode)
        r.palette_width = 12
        r.upload(rep)
        out.append(r.capture(rep.key, _identity_instances(frames))[0])
        if mode == "palette":
            assert r._palette_tex.width == 12 and r._palette_tex.height >= 57 * 9 // 12
        r.release()
    assert np.abs(out[0] - out[1]).max() < 1e-5
