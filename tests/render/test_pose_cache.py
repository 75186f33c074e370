"""Pose sharing, render side (render/poses/cache.py, shaders/poses/pose_skin.comp, shaders/poses/posed.vert): the posed
vertices against the CPU reference skinning (positions and inverse-transpose normals, morph targets included),
exact-rate frames of every triangle mode against per-copy skinning, key-rate frames within the quantisation,
windows at the binding limit, and nothing non-finite sent to the GPU."""
import dataclasses

import numpy as np
import pytest
from tiny_characters import tiny_morphed, tiny_skinned

import render.poses.cache as pc
from crowd.image_metrics import psnr
from lod.chains import chain as tm_chain
from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.modes import mode_module
from lod.poses import KEY_RATE, SLOT_FLOAT, PoseSharing
from lod.view import Camera
from render.renderer import Renderer
from sim.mesh import Mesh
from sim.skinning import skin
from sim.state import CrowdState

SIZE = (160, 120)
CAM = Camera.look_at((2.0, 2.2, 4.2), (2.0, 0.9, -1.4), fov_y=55)


@pytest.fixture(scope="module")
def plain():
    return build_rep(tiny_skinned(), fps=30)


@pytest.fixture(scope="module")
def morphed():
    return build_rep(tiny_morphed(), fps=30)


def _crowd(rep, n=12, seed=0, on_keys=False):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:, 0] = (np.arange(n) % 4) * 1.4
    st.position[:, 2] = -(np.arange(n) // 4) * 1.6
    st.heading[:] = rng.uniform(-1, 1, n)
    st.scale[:] = 0.6
    st.clip[:] = np.arange(n) % rep.n_parts
    st.anim_time[:] = rng.integers(0, 20, n) / 30.0 if on_keys else rng.uniform(0, 2, n)
    return st


def _drawlist(reps, st, rate, selector=None):
    dl = (selector or NoLodSelector(reps)).select(st, CAM, SIZE)
    if rate is not None:
        ps = PoseSharing(rate)
        ps.register(reps)
        ps.assign(dl)
    return dl


def _image(r, dl, sharing=True):
    r.pose_sharing = sharing
    r.draw(dl)
    return r.read_pixels()


def _reference(rep, frame):
    """CPU skin ∘ morph (sim.skinning: normals by the inverse transpose) at a fractional frame coordinate, the
    baked rows blended as the GPU blends them."""
    f0 = int(np.floor(frame))
    a = frame - f0
    f1 = min(f0 + 1, rep.joint_table.shape[0] - 1)
    m = (1 - a) * rep.joint_table[f0].astype(np.float64) + a * rep.joint_table[f1]
    S = np.tile(np.eye(4), (m.shape[0], 1, 1))
    S[:, :3, :] = m
    pos, nrm = np.asarray(rep.positions, np.float64), np.asarray(rep.normals, np.float64)
    if rep.targets is not None:
        w = (1 - a) * rep.targets.weights[f0].astype(np.float64) + a * rep.targets.weights[f1]
        pos, nrm = rep.targets.morph(pos, nrm, w)
        nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    return skin(Mesh(pos, rep.indices, normals=nrm, joints=rep.joints, weights=rep.weights), S)


@pytest.mark.parametrize("which", ["plain", "morphed"])
@pytest.mark.parametrize("skinning", pc.SKINNING_PASSES)
def test_posed_vertices_are_the_cpu_reference_skinning(gl_ctx, request, which, skinning):
    rep = request.getfixturevalue(which)
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    r.poses.skinning = skinning
    r.upload(rep)
    dl = _drawlist([rep], _crowd(rep), 0)  # exact: every copy its own fractional frame
    r.draw(dl)
    posed = r.poses.posed(rep.key)
    got = posed.read()
    frames = dl.poses.set_of(rep.key).frames
    assert got.shape == (12, rep.positions.shape[0], 8) and not np.equal(frames, np.round(frames)).all()
    extent = float(np.ptp(rep.positions, axis=0).max())
    for p, f in enumerate(frames):
        want_p, want_n = _reference(rep, f)
        assert np.abs(got[p, :, :3] - want_p).max() <= 2e-5 * extent, (p, f)
        assert np.abs(got[p, :, 4:7] - want_n).max() <= 2e-4, (p, f)
    assert (got[:, :, 3] == 1).all() and (got[:, :, 7] == 0).all()
    r.release()


@pytest.mark.parametrize("mode", ["none", "triangles", "clusters"])
def test_exact_rate_draws_every_mode_as_per_copy_skinning(gl_ctx, morphed, mode):
    ch = tiny_morphed()
    params = {"poe": 0.5} if mode != "none" else {}
    kw = {} if mode == "none" else {"cache": False}
    reps, sel = mode_module(mode).build([ch], ["tinymorph"], [30], params, **kw)
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    for rep in reps:
        r.upload(rep)
    st = _crowd(morphed)
    before = _image(r, _drawlist(reps, st, None, sel), sharing=False)  # per-copy palettes, as before issue 29
    dl = _drawlist(reps, st, 0, sel)
    after = _image(r, dl)
    assert dl.stats["poses"] == 12 and (before.max(axis=2) > 40).sum() > 2000
    assert np.abs(before.astype(int) - after).max() <= 2, mode
    r.release()


def test_geomorphed_chain_levels_read_the_pose_palettes(gl_ctx, morphed):
    reps, sel = mode_module("triangles").build([tiny_morphed()], ["tinymorph"], [30], {"poe": 0.0, "levels": 4},
                                               cache=False)
    trep = reps[0]
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    r.upload(trep)

    def drawlist(rate):
        dl = sel.select(_crowd(morphed), CAM, SIZE)
        dl.batches = [tm_chain.TriangleDrawBatch(b.rep, b.part, b.instance_ids, b.instance_data, level=1,
                                                 index_range=(3 * int(trep.level_first[1]),
                                                              3 * int(trep.level_count[1])), morph=(2, 0.4))
                      for b in dl.batches]
        if rate is not None:
            ps = PoseSharing(rate)
            ps.register(reps)
            ps.assign(dl)
        return dl

    before = _image(r, drawlist(None), sharing=False)
    after = _image(r, drawlist(0))
    assert np.abs(before.astype(int) - after).max() <= 2
    r.release()


def test_a_mesh_is_skinned_only_in_the_slots_its_copies_draw(gl_ctx, morphed):
    """Twelve copies of one character in twelve poses, eleven drawn at full detail and one by a chain level of
    vertices of their own: the full mesh is skinned in its copies' eleven slots, the chain in its copy's one (not
    in all twelve: issue 49's 140 ms frame), and the LOD side counts the same; the pixels are the per-copy
    skinning's. A later request skins only the slots not skinned yet that frame; posing_cost prices exactly
    that. A chain drawn from the full mesh's own vertices shares its posed vertices."""
    reps, _ = mode_module("triangles").build([tiny_morphed()], ["tinymorph"], [30], {"poe": 0.0, "levels": 3},
                                             cache=False)
    shared_chain = reps[0]
    # the same chain over vertices of its own (a copy of the mesh: another posed mesh)
    trep = dataclasses.replace(shared_chain, key="triangles:tinymorph#own", positions=shared_chain.positions + 0.0,
                               normals=-(-shared_chain.normals), weights=shared_chain.weights * 1.0)
    assert pc.mesh_digest(trep) == pc.mesh_digest(shared_chain) == pc.mesh_digest(morphed)
    trep = dataclasses.replace(trep, positions=trep.positions * np.float32(1.0001))
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    for rep in (morphed, trep, shared_chain):
        r.upload(rep)
    st = _crowd(morphed)

    def drawlist(rate, chain):
        dl = NoLodSelector([morphed]).select(st, CAM, SIZE)
        *others, b = dl.batches  # one batch per clip
        last = np.arange(b.n_instances) == b.n_instances - 1
        dl.batches = others + [
            dataclasses.replace(b, instance_ids=b.instance_ids[~last], instance_data=b.instance_data[~last]),
            tm_chain.TriangleDrawBatch(chain.key, b.part, b.instance_ids[last], b.instance_data[last], level=1,
                                       index_range=(3 * int(chain.level_first[1]), 3 * int(chain.level_count[1])))]
        if rate is not None:
            ps = PoseSharing(rate)
            ps.register([morphed, trep, shared_chain])
            ps.assign(dl)
        return dl

    V = morphed.positions.shape[0]
    for chain, want in ((trep, 11 * V + V), (shared_chain, 12 * V)):
        before = _image(r, drawlist(None, chain), sharing=False)
        dl = drawlist(0, chain)
        after = _image(r, dl)
        assert dl.stats["poses"] == 12 and (before.max(axis=2) > 40).sum() > 2000
        assert r.poses.last_stats["posed_vertices"] == dl.stats["posed_vertices"] == want
        assert np.abs(before.astype(int) - after).max() <= 2
    _image(r, drawlist(0, trep))
    assert r.poses.posing_cost(trep.key, slots=[0, 11, 11, 3.0]) == 2 * V  # slot 11 is skinned already
    assert r.poses.posing_cost(morphed.key, slots=[11, -1, 12, np.nan]) == V  # out of range: nothing
    posed = r.poses.posed(trep.key, slots=[0, 3])
    assert r.poses.last_stats["posed_vertices"] == 11 * V + 3 * V and posed.done.sum() == 3
    assert r.poses.posing_cost(trep.key, slots=[0, 3, 11]) == 0
    got = posed.read()[[0, 3, 11]]
    frames = dl.poses.set_of(trep.key).frames
    extent = float(np.ptp(trep.positions, axis=0).max())
    for row, p in zip(got, (0, 3, 11)):
        want_p, _ = _reference(trep, frames[p])
        assert np.abs(row[:, :3] - want_p).max() <= 2e-5 * extent, p
    r.release()


def test_key_rate_frames_are_exact_on_keys_and_within_the_quantisation_between(gl_ctx, morphed):
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    r.upload(morphed)
    on = _crowd(morphed, on_keys=True)
    exact, shared = _image(r, _drawlist([morphed], on, 0)), _image(r, _drawlist([morphed], on, KEY_RATE))
    assert np.abs(exact.astype(int) - shared).max() <= 1  # every copy on a baked key: nothing quantised
    between = _crowd(morphed, seed=5)
    exact = _image(r, _drawlist([morphed], between, 0)) / 255.0
    errs = {rate: psnr(_image(r, _drawlist([morphed], between, rate)) / 255.0, exact) for rate in (5, KEY_RATE, 240)}
    assert 20.0 < errs[5] < errs[KEY_RATE] < errs[240] < np.inf, errs  # the error falls with the rate
    r.release()


def test_windows_at_the_binding_limit(gl_ctx, morphed):
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    r.upload(morphed)
    st = _crowd(morphed, n=16, seed=2)
    st.anim_time[::-1] = np.sort(st.anim_time)  # later copies reuse earlier slots: windows out of order
    st.anim_time[8:] = st.anim_time[:8]
    one = _image(r, _drawlist([morphed], st, KEY_RATE))
    whole = r.poses.posed(morphed.key).read()
    V = morphed.positions.shape[0]
    r.poses.window_bytes = 2 * V * pc.POSED_VERTEX_BYTES + 100  # two poses per window
    dl = _drawlist([morphed], st, KEY_RATE)
    cut = _image(r, dl)
    posed = r.poses.posed(morphed.key)
    P = dl.poses.set_of(morphed.key).n_poses
    assert len(posed.windows) == -(-P // 2) >= 3 and all(w.count * V * pc.POSED_VERTEX_BYTES <= r.poses.window_bytes
                                                        for w in posed.windows)
    np.testing.assert_array_equal(posed.read(), whole)
    assert (cut == one).all()
    slots = np.concatenate([b.instance_data[:, SLOT_FLOAT] for b in dl.batches])
    assert (np.diff(posed.window_of(slots.round())) < 0).any()  # the renderer sorted them by window
    for window_bytes, budget in ((V * pc.POSED_VERTEX_BYTES - 1, pc.POSED_BUDGET_BYTES),  # a pose beyond a window
                                 (pc.POSED_WINDOW_BYTES, V * pc.POSED_VERTEX_BYTES)):  # poses beyond the budget
        r.poses.window_bytes, r.poses.budget_bytes = window_bytes, budget
        fallback = _image(r, _drawlist([morphed], st, KEY_RATE))
        assert r.poses.posed(morphed.key) is None and r.poses.last_stats["fallback"] == 1
        assert np.abs(fallback.astype(int) - one).max() <= 2  # skinned per copy from the pose palettes
    r.release()


def test_palettes_beyond_the_texture_fall_back_to_per_copy_palettes(gl_ctx, plain, monkeypatch):
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    r.upload(plain)
    st = _crowd(plain)
    before = _image(r, _drawlist([plain], st, None))
    monkeypatch.setattr(pc, "PALETTE_MAX_TEXELS", 10)
    dl = _drawlist([plain], st, 0)
    after = _image(r, dl)
    assert r.poses.palette(plain.key) is None and r.poses.last_stats["fallback"] == 1
    assert (before == after).all()
    r.release()


def test_nothing_non_finite_reaches_the_gpu(gl_ctx, plain):
    r = Renderer(SIZE, ctx=gl_ctx, debug=True)
    r.upload(plain)
    dl = _drawlist([plain], _crowd(plain), KEY_RATE)
    bad = dataclasses.replace(dl.poses.sets["tiny"], frames=dl.poses.sets["tiny"].frames * np.nan)
    with pytest.raises(FloatingPointError, match="NaN or Inf"):
        r.poses.begin(dataclasses.replace(dl.poses, sets={"tiny": bad}))
    table = plain.joint_table.copy()
    table[3, 0, 0, 0] = np.inf
    broken = dataclasses.replace(dl.poses.sets["tiny"].group, source=dataclasses.replace(plain, joint_table=table))
    ps = dataclasses.replace(dl.poses.sets["tiny"], group=broken, frames=np.array([3.0]))
    with pytest.raises(FloatingPointError, match="NaN or Inf"):
        r.poses.begin(dataclasses.replace(dl.poses, sets={"tiny": ps}))
    r.release()
