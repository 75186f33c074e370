"""lod.full.targets: the morph targets of a skinned rep (glTF 2.0 §3.7.2.2) kept,
folded or dropped, made sparse, their weights baked at the joint-table frames,
and bounds that hold the morphed mesh; and which modes carry them."""
import dataclasses

import numpy as np
import pytest

from tiny_characters import tiny_morphed, tiny_skinned

from lod.full.reps import build_rep, build_skinned_rep
from lod.full.targets import ENTRY_BYTES, VERTEX_BYTES, WEIGHT_BYTES
from sim.skinning import morph, skin_morph


@pytest.fixture(scope="module")
def ch():
    return tiny_morphed()


@pytest.fixture(scope="module")
def rep(ch):
    return build_rep(ch, fps=30)


def _baked_times(rep, c):
    return np.arange(int(rep.clip_frames[c])) / rep.clip_fps[c]


def test_animated_targets_are_kept_constant_ones_folded_and_idle_ones_dropped(ch, rep):
    t = rep.targets
    mt = ch.mesh.morph
    assert t.names == ["bulge", "lean"] and list(t.source) == [0, 1]
    assert t.folded == ["squash"]  # held at 0.6 by both clips, default 0.3
    assert t.weights.shape == (rep.joint_table.shape[0], 2)
    # the squash offset (0.6 - 0.3) is in the bind pose
    np.testing.assert_allclose(rep.positions, ch.mesh.positions + 0.3 * mt.positions[2], atol=1e-6)
    np.testing.assert_allclose(rep.normals, ch.mesh.normals + 0.3 * mt.normals[2], atol=1e-6)
    for c, name in enumerate(rep.clip_names):
        rows = slice(int(rep.clip_offset[c]), int(rep.clip_offset[c] + rep.clip_frames[c]))
        want = ch.clips[name].morph_weights(mt, _baked_times(rep, c))[:, :2] - mt.default_weights[:2]
        np.testing.assert_allclose(t.weights[rows], want, atol=1e-6)
    # sparse: exactly the (vertex, kept target) pairs with a non-zero delta, grouped by vertex
    nz = (mt.positions[:2] != 0).any(2) | (mt.normals[:2] != 0).any(2)
    assert t.n_entries == int(nz.sum()) < 2 * ch.mesh.n_vertices
    np.testing.assert_array_equal(t.count, nz.sum(0))
    np.testing.assert_array_equal(t.first, np.concatenate([[0], np.cumsum(t.count)[:-1]]))
    v = np.repeat(np.arange(ch.mesh.n_vertices), t.count)
    np.testing.assert_array_equal(t.dpos, mt.positions[t.column, v])
    assert t.gpu_bytes() == t.n_entries * ENTRY_BYTES + ch.mesh.n_vertices * VERTEX_BYTES + t.weights.size * WEIGHT_BYTES


def test_table_morph_is_the_cpu_morph_at_every_baked_frame(ch, rep):
    mt = ch.mesh.morph
    for c, name in enumerate(rep.clip_names):
        times = _baked_times(rep, c)
        W = ch.clips[name].morph_weights(mt, times)
        for k in range(0, len(times), 5):
            p, n = rep.targets.morph(rep.positions, rep.normals, rep.targets.weights[int(rep.clip_offset[c]) + k])
            cp, cn = morph(ch.mesh, W[k])
            assert np.abs(p - cp).max() < 1e-5
            assert np.abs(n / np.linalg.norm(n, axis=1, keepdims=True) - cn).max() < 1e-5


def test_characters_without_animated_targets_get_the_plain_rep(ch):
    plain = tiny_skinned()
    assert build_rep(plain).targets is None
    # targets that no clip animates cost nothing: no table, the mesh as it is
    still = tiny_morphed()
    for clip in still.clips.values():
        clip.channels = [c for c in clip.channels if c.path != "weights"]
    a, b = build_rep(still), build_rep(plain)
    assert a.targets is None
    for f in dataclasses.fields(a):
        if f.name not in ("key", "targets", "clip_names"):
            np.testing.assert_array_equal(getattr(a, f.name), getattr(b, f.name), err_msg=f.name)
    off = build_skinned_rep(ch, morph_targets=False)
    assert off.targets is None
    np.testing.assert_array_equal(off.positions, ch.mesh.positions)


def test_bounds_hold_the_morphed_mesh_between_frames_and_at_any_time(ch, rep):
    mt = ch.mesh.morph
    frac = 0
    for c, name in enumerate(rep.clip_names):
        clip = ch.clips[name]
        lo, hi = rep.clip_aabb[c].astype(np.float64)
        for t in np.linspace(0.0, clip.duration, 97):  # the continuous clip (CPU reference)
            p, _ = skin_morph(ch.mesh, clip.skinning_matrices(ch.skeleton, [t])[0], clip.morph_weights(mt, [t])[0])
            assert (p >= lo - 1e-6).all() and (p <= hi + 1e-6).all(), (name, t)
        # what the GPU draws at fractional frames: matrices and weights blended linearly
        off = int(rep.clip_offset[c])
        for f in range(int(rep.clip_frames[c]) - 1):
            for a in (0.25, 0.5, 0.75):
                m = (1 - a) * rep.joint_table[off + f].astype(np.float64) + a * rep.joint_table[off + f + 1]
                w = (1 - a) * rep.targets.weights[off + f].astype(np.float64) + a * rep.targets.weights[off + f + 1]
                q, _ = rep.targets.morph(rep.positions, rep.normals, w)
                M = np.einsum("vk,vkab->vab", rep.weights.astype(np.float64), m[rep.joints.astype(np.int64)])
                p = np.einsum("vab,vb->va", M[:, :, :3], q) + M[:, :, 3]
                box = rep.frame_aabb[off + f:off + f + 2].astype(np.float64)
                assert (p >= box[:, 0].min(0) - 1e-6).all() and (p <= box[:, 1].max(0) + 1e-6).all(), (name, f, a)
                frac += 1
    assert frac > 40
    # the morph widens the bounds: the bulge leaves the unmorphed column's box
    plain = build_rep(tiny_skinned())
    assert (rep.clip_aabb[:, 1, 0] > plain.clip_aabb[:, 1, 0] + 0.05).all()


def test_triangle_chains_carry_the_targets_and_clusters_ignore_them(ch, rep):
    from lod.chains import mode as tm
    from lod.clusters import mode as cm

    reps, _ = tm.build([ch], ["m"], [30], {"levels": 3}, cache=False)
    tr = reps[0]
    assert tr.n_levels >= 2 and tr.targets is not None
    assert tr.targets.names == rep.targets.names
    np.testing.assert_array_equal(tr.targets.weights, rep.targets.weights)
    np.testing.assert_array_equal(tr.positions, rep.positions)
    # clusters: the mesh at its default weights, no table, the cache key of the character without morphs
    creps, _ = cm.build([ch], ["m"], [30], {}, cache=False)
    sk = creps[0].skinned
    assert sk.targets is None
    np.testing.assert_array_equal(sk.positions, ch.mesh.positions)
    bare = tiny_morphed()
    bare.mesh.morph = None
    for clip in bare.clips.values():
        clip.channels = [c for c in clip.channels if c.path != "weights"]
    bk = build_skinned_rep(bare, fps=30, key=sk.key)
    assert cm.cache_key(sk, {}) == cm.cache_key(bk, {})
