"""Full-detail representations and the NoLOD selector."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))
from tiny_characters import tiny_keyframed, tiny_skinned  # noqa: E402

from lod.drawlist import INSTANCE_FLOATS  # noqa: E402
from lod.full.bounds import frame_aabbs, skinned_frame_aabbs  # noqa: E402
from lod.full.mode import NoLodSelector  # noqa: E402
from lod.full.reps import KeyframedRep, SkinnedRep, StaticRep, build_rep  # noqa: E402
from lod.view import Camera  # noqa: E402
from sim.mesh import Mesh  # noqa: E402
from sim.skinning import skin_reference  # noqa: E402
from sim.state import CrowdState  # noqa: E402


@pytest.fixture(scope="module")
def tiny():
    return tiny_skinned()


@pytest.fixture(scope="module")
def rep(tiny):
    return build_rep(tiny, fps=30)


@pytest.fixture(scope="module")
def krep():
    return build_rep(tiny_keyframed())


def _lbs(rep, mats):
    """CPU LBS of rep's bind mesh with (J, 3, 4) matrices (float64)."""
    p = np.c_[rep.positions.astype(np.float64), np.ones(len(rep.positions))]
    m = mats[rep.joints.astype(np.int64)]  # (V, 4, 3, 4)
    blended = np.einsum("vk,vkab->vab", rep.weights.astype(np.float64), m)
    return np.einsum("vab,vb->va", blended, p)


def test_skinned_rep_layout(rep, tiny):
    assert isinstance(rep, SkinnedRep) and rep.key == "none:tiny"
    assert rep.positions.dtype == np.float32 and rep.indices.dtype == np.uint32
    assert rep.joint_table.dtype == np.float32 and rep.joint_table.shape[1:] == (3, 3, 4)
    assert rep.clip_names == ["bend", "twist"]
    # 1 s at 30 fps: 31 frames incl. t = duration; 0.7 s: 22 frames
    assert rep.clip_frames.tolist() == [31, 22]
    assert rep.clip_offset.tolist() == [0, 31]
    assert rep.joint_table.shape[0] == 53
    assert np.allclose(rep.clip_fps, [30.0, 30.0])
    assert np.allclose(rep.weights.sum(1), 1, atol=1e-6)
    # the looping clip's last frame is its first (seamless interpolation back)
    assert np.allclose(rep.joint_table[30], rep.joint_table[0], atol=1e-6)
    # the table holds the skeleton's skinning matrices at the frame times
    ref = tiny.clips["twist"].skinning_matrices(tiny.skeleton, np.array([0.0, 10 / 30, 0.7]))[:, :, :3, :]
    assert np.allclose(rep.joint_table[[31, 31 + 10, 31 + 21]], ref, atol=1e-6)


def test_fps_rounds_to_whole_intervals(tiny):
    r = build_rep(tiny, fps=7)
    assert r.clip_frames.tolist() == [8, 6]  # round(7) + 1, round(4.9) + 1
    assert np.allclose(r.clip_fps, [7.0, 5 / 0.7])


def test_frame_aabbs_match_direct_skinning_also_when_chunked(rep, tiny):
    mats = rep.joint_table[:31].astype(np.float64)
    ref = np.stack([[(q := _lbs(rep, m)).min(0), q.max(0)] for m in mats])
    for scratch in (1, 10 ** 9):
        got = skinned_frame_aabbs(rep.positions, rep.joints, rep.weights, mats, scratch_bytes=scratch)
        assert np.allclose(got, ref, atol=1e-9)
    assert np.allclose(frame_aabbs(rep.positions, rep.joints, rep.weights, mats), ref, atol=1e-9)
    assert frame_aabbs(rep.positions[:0], rep.joints[:0], rep.weights[:0], mats).shape == (31, 2, 3)
    # and the CPU reference of sim agrees at a baked frame
    s4 = np.tile(np.eye(4), (3, 1, 1))
    s4[:, :3, :] = mats[7]
    pos, _ = skin_reference(tiny.mesh, s4)
    assert np.allclose(pos, _lbs(rep, mats[7]), atol=1e-5)


def test_bounds_contain_interpolated_and_continuous_poses(rep, tiny):
    for c, name in enumerate(rep.clip_names):
        lo, hi = rep.clip_aabb[c].astype(np.float64)
        cen, rad = rep.clip_sphere[c, :3], rep.clip_sphere[c, 3]
        off, n = rep.clip_offset[c], rep.clip_frames[c]
        # GPU-equivalent: matrices blended between baked frames
        for f in np.linspace(off, off + n - 1, 97):
            f0 = int(np.floor(f)); f1 = min(f0 + 1, off + n - 1); a = f - f0
            m = (1 - a) * rep.joint_table[f0].astype(np.float64) + a * rep.joint_table[f1]
            q = _lbs(rep, m)
            assert (q >= lo - 1e-5).all() and (q <= hi + 1e-5).all()
            assert (np.linalg.norm(q - cen, axis=1) <= rad + 1e-5).all()
        # continuous clip at 60 times (CPU reference skinning)
        clip = tiny.clips[name]
        mats = clip.skinning_matrices(tiny.skeleton, np.linspace(0, clip.duration, 60))
        for m in mats:
            q, _ = skin_reference(tiny.mesh, m)
            assert (q >= lo - 1e-5).all() and (q <= hi + 1e-5).all()
            assert (np.linalg.norm(q - cen, axis=1) <= rad + 1e-5).all()


def test_frame_coordinate_wraps_loops_and_clamps_others(rep):
    clip = np.array([0, 0, 0, 0, 1, 1, 1])
    t = np.array([0.5, 1.25, -0.25, np.nan, 0.35, 5.0, -1.0])
    f = rep.frame_coordinate(clip, t)
    assert np.allclose(f, [15.0, 7.5, 22.5, 0.0, 31 + 10.5, 31 + 21, 31])


def test_keyframed_rep_segments_and_locate(krep):
    anim = tiny_keyframed().animations["wave"]
    assert isinstance(krep, KeyframedRep)
    assert krep.seg_count.tolist() == [6, 9, 9] and krep.seg_first.tolist() == [0, 6, 15]
    assert krep.positions0.shape == (14, 3) and krep.indices.max() < 14
    # segment 1 -> 2: the grown vertex starts at keyframe 1's vertex 2
    assert np.allclose(krep.positions0[4 + 4], anim.keyframes[1].positions[2])
    assert np.allclose(krep.positions1[4 + 4], anim.keyframes[2].positions[4])
    ts = np.array([-0.2, 0.0, 0.25, 0.5, 0.99, 1.2, 1.5, 3.1, np.nan])
    seg, u = krep.locate(0, ts)
    for t, s, uu in zip(ts, seg, u):
        rs, ru = anim.locate(t)
        assert (s, pytest.approx(uu)) == (rs, pytest.approx(ru))
    # the numba pass equals the numpy reference, also far from the clip and at non-finite times
    many = np.concatenate([np.random.default_rng(0).uniform(-5, 10, 500), [np.inf, -np.inf, 1e12, -1e12, 0.0]])
    for a, b in zip(krep.locate(0, many), krep.locate_numpy(0, many)):
        np.testing.assert_array_equal(a, b)
    # segment bounds contain both ends
    for s in range(3):
        a = slice(int(krep.seg_first[s]), int(krep.seg_first[s] + krep.seg_count[s]))
        v = np.unique(krep.indices.reshape(-1)[a])
        for p in (krep.positions0[v], krep.positions1[v]):
            assert (np.linalg.norm(p - krep.seg_sphere[s, :3], axis=1) <= krep.seg_sphere[s, 3] + 1e-6).all()


def test_static_rep_from_mesh():
    m = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0]], np.float32), np.array([[0, 1, 2]], np.uint32))
    r = build_rep(m, key="ref")
    assert isinstance(r, StaticRep) and r.n_triangles == 1 and r.key == "ref"
    assert np.allclose(r.aabb, [[0, 0, 0], [1, 2, 0]])
    assert np.linalg.norm(r.positions - r.sphere[:3], axis=1).max() <= r.sphere[3] + 1e-9


def test_build_rep_rejects_unknown_input():
    with pytest.raises(TypeError, match="expected a SkinnedCharacter"):
        build_rep(object())


def _state(n):
    s = CrowdState.empty(n)
    return s


def test_select_model_rows_anim_and_batches(rep, krep):
    sel = NoLodSelector([rep, krep])
    st = _state(5)
    st.position[:] = [[0, 0, 0], [2, 0, 0], [-2, 0, 0], [0, 0, -3], [1, 0, -1]]
    st.heading[:] = [0.0, np.pi / 2, 0.3, 0.0, 0.0]
    st.scale[:] = [1, 2, 1, 1, 0.5]
    st.character[:] = [0, 0, 0, 1, 0]
    st.clip[:] = [0, 1, 0, 0, 0]
    st.anim_time[:] = [0.5, 0.35, 1.1, 0.75, 0.0]
    cam = Camera.look_at((0, 2, 12), (0, 1, 0))
    dl = sel.select(st, cam, (640, 360))
    keys = [(b.rep, b.part, b.instance_ids.tolist()) for b in dl.batches]
    assert keys == [("none:tiny", 0, [0, 2, 4]), ("none:tiny", 1, [1]), ("none:flag", 1, [3])]
    assert dl.stats["instances"] == 5 and dl.stats["culled"] == 0
    assert dl.stats["triangles"] == 4 * rep.n_triangles + 3
    assert dl.batches[0].instance_data.dtype == np.float32
    assert dl.batches[0].instance_data.shape == (3, INSTANCE_FLOATS)
    assert np.allclose(dl.batches[0].instance_data[:, 12], [15.0, 3.0, 0.0])
    assert np.allclose(dl.batches[1].instance_data[0, 12], 31 + 10.5)
    assert np.isclose(dl.batches[2].instance_data[0, 12], 0.5)  # t 0.75 in segment 0.5..1.0
    # model rows: agent 1 (heading 90 deg, scale 2) maps model +Z to world +X, doubled
    m = dl.batches[1].instance_data[0, :12].reshape(3, 4)
    assert np.allclose(m[:, :3] @ [0, 0, 1], [2, 0, 0], atol=1e-6)
    assert np.allclose(m[:, 3], st.position[1] - cam.position)
    assert np.allclose(dl.view, cam.view_matrix()) and dl.proj.dtype == np.float32


def test_select_of_some_agents_equals_the_full_select_without_the_others(rep, krep):
    """select(agents=...) culls and packs only those agents, instance ids in the state's numbering:
    the same batches as the full selection with the other agents removed."""
    sel = NoLodSelector([rep, krep])
    rng = np.random.default_rng(2)
    st = _state(40)
    st.position[:] = np.c_[rng.uniform(-6, 6, 40), np.zeros(40), rng.uniform(-8, 2, 40)]
    st.heading[:] = rng.uniform(0, 6.3, 40)
    st.character[:] = rng.integers(0, 2, 40)
    st.anim_time[:] = rng.uniform(0, 2, 40)
    cam = Camera.look_at((0, 2, 12), (0, 1, 0))
    full = sel.select(st, cam, (640, 360))
    agents = np.flatnonzero(rng.random(40) < 0.6)
    part = sel.select(st, cam, (640, 360), agents=agents)
    want = []
    for b in full.batches:
        keep = np.isin(b.instance_ids, agents)
        if keep.any():
            want.append((b.rep, b.part, b.instance_ids[keep].tolist(), b.instance_data[keep]))
    got = [(b.rep, b.part, b.instance_ids.tolist(), b.instance_data) for b in part.batches]
    assert [w[:3] for w in want] == [g[:3] for g in got]
    for w, g in zip(want, got):
        np.testing.assert_array_equal(w[3], g[3])
    assert part.stats["instances"] + part.stats["culled"] == agents.size


def test_select_culls_outside_and_keeps_straddling(rep):
    sel = NoLodSelector([rep])
    cam = Camera.look_at((0, 1.5, 10), (0, 1.5, 0), fov_y=50)
    st = _state(3)
    # half-width of the view at z = 0 (distance 10)
    half = 10 * np.tan(np.radians(25)) * 16 / 9
    st.position[:] = [[0, 0, 0], [half + 0.5, 0, 0], [half + 30, 0, 0]]
    dl = sel.select(st, cam, (1600, 900))
    assert sorted(np.concatenate([b.instance_ids for b in dl.batches]).tolist()) == [0, 1]
    assert dl.stats["culled"] == 1


def test_select_far_from_origin_is_precise_and_finite(rep):
    sel = NoLodSelector([rep])
    off = np.array([1e6, 0.0, -1e6])
    cam = Camera.look_at(off + (0, 1.5, 5), off + (0, 1, 0))
    st = _state(2)
    st.position[:] = off + [[0.0, 0.0, 0.0], [0.001, 0.0, 0.0]]
    dl = sel.select(st, cam, (320, 240))
    d = dl.batches[0].instance_data
    assert np.isfinite(d).all()
    assert np.isclose(d[1, 3] - d[0, 3], 0.001, atol=1e-7)  # a millimetre survives
    assert np.allclose(d[0, [3, 7, 11]], [0, -1.5, -5])


def test_select_statics_and_errors(rep):
    m = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]], np.uint32))
    ground = build_rep(m, key="ground")
    sel = NoLodSelector([rep], static_reps=[ground])
    cam = Camera.look_at((0, 2, 10), (0, 0, 0))
    mat = np.eye(4)
    mat[:3, 3] = (1, 0, 0)
    behind = np.eye(4)
    behind[:3, 3] = (0, 0, 50)
    dl = sel.select(_state(0), cam, (100, 100), statics=[("ground", mat), ("ground", behind)])
    assert len(dl.batches) == 1 and dl.batches[0].rep == "ground"
    assert dl.batches[0].instance_ids.tolist() == [-1]
    assert np.allclose(dl.batches[0].instance_data[0, [3, 7, 11]], [1, -2, -10])
    with pytest.raises(KeyError, match="unknown StaticRep"):
        sel.select(_state(0), cam, (100, 100), statics=[("nope", mat)])
    st = _state(1)
    st.clip[0] = 5
    with pytest.raises(ValueError, match="clip"):
        sel.select(st, cam, (100, 100))
    st = _state(1)
    st.character[0] = 3
    with pytest.raises(ValueError, match="character"):
        sel.select(st, cam, (100, 100))


def test_select_scales_to_100k_instances_vectorised(rep, krep):
    rng = np.random.default_rng(2)
    n = 100_000
    st = _state(n)
    st.position[:, [0, 2]] = rng.uniform(-200, 200, (n, 2))
    st.heading[:] = rng.uniform(-np.pi, np.pi, n)
    st.character[:] = rng.integers(0, 2, n)
    st.clip[:] = np.where(st.character == 0, rng.integers(0, 2, n), 0)
    st.anim_time[:] = rng.uniform(0, 10, n)
    sel = NoLodSelector([rep, krep])
    dl = sel.select(st, Camera.look_at((0, 30, 250), (0, 0, 0)), (1280, 720))
    assert dl.stats["instances"] + dl.stats["culled"] == n
    assert 0 < dl.stats["culled"] < n
    assert len(dl.batches) <= 5
    ids = np.concatenate([b.instance_ids for b in dl.batches])
    assert np.unique(ids).size == ids.size
    for b in dl.batches:
        assert np.all(np.diff(b.instance_ids) > 0)  # stable: agent order within a batch
        assert np.isfinite(b.instance_data).all()


@pytest.mark.parametrize("cull", [True, False])
def test_selection_kernel_matches_numpy_reference(rep, krep, cull):
    rng = np.random.default_rng(5)
    n = 3000
    st = _state(n)
    st.position[:, [0, 2]] = rng.uniform(-60, 60, (n, 2))
    st.position[:5] = st.position[0]  # identical agents
    st.heading[:] = rng.uniform(-7, 7, n)
    st.heading[7] = np.nan  # sanitised to 0 by both
    st.scale[:] = rng.uniform(0.5, 2, n).astype(np.float32)
    st.character[:] = rng.integers(0, 3, n)
    st.clip[:] = np.where(st.character == 0, rng.integers(0, 2, n), 0)
    st.anim_time[:] = rng.uniform(-5, 20, n)
    st.anim_time[9] = np.inf
    m = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]], np.uint32))
    reps = [rep, krep, build_rep(m, key="tri")]
    cam = Camera.look_at((0, 10, 50), (0, 0, 0))
    a = NoLodSelector(reps, cull=cull).select(st, cam, (800, 600))
    b = NoLodSelector(reps, cull=cull, use_kernel=False).select(st, cam, (800, 600))
    assert a.stats == b.stats and len(a.batches) == len(b.batches) >= 4
    for x, y in zip(a.batches, b.batches):
        assert (x.rep, x.part, x.triangles) == (y.rep, y.part, y.triangles)
        assert np.array_equal(x.instance_ids, y.instance_ids)
        assert np.array_equal(x.instance_data[:, :12], y.instance_data[:, :12])
        assert np.allclose(x.instance_data[:, 12:], y.instance_data[:, 12:], rtol=1e-6, atol=1e-6)
    assert NoLodSelector(reps).select(_state(0), cam, (8, 8)).stats["instances"] == 0
