"""Pose sharing, LOD side (lod/poses/table.py): copies at the same quantised time share a pose slot, others do not;
the numba kernel equals its numpy reference; exact mode gives every copy its own slot; NaN frame coordinates are
refused; ``[lod] pose_rate`` is validated."""
import dataclasses

import numpy as np
import pytest
from tiny_characters import tiny_skinned

from lod.clusters.mode import ClustersRep
from lod.drawlist import DrawBatch, DrawList
from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.poses import KEY_RATE, POSE_PARAMS, SLOT_FLOAT, PoseSharing, assign_slots, assign_slots_numpy
from lod.poses.table import _clip_tables, check_rate
from lod.view import Camera
from sim.params import ParamError
from sim.state import CrowdState

CAM = Camera.look_at((4.0, 6.0, 30.0), (4.0, 1.0, 0.0), fov_y=60)


@pytest.fixture(scope="module")
def rep():
    return build_rep(tiny_skinned(), fps=30)  # clips: bend (1 s, looping, 31 rows), twist (0.7 s, not looping)


def _state(times, clips, chars=None):
    n = len(times)
    st = CrowdState.empty(n)
    st.position[:, 0] = np.arange(n) * 0.3
    st.anim_time[:] = times
    st.clip[:] = clips
    if chars is not None:
        st.character[:] = chars
    return st


def _slots(dl, rep_key=None):
    return {int(i): int(round(float(d[SLOT_FLOAT]))) for b in dl.batches if rep_key in (None, b.rep)
            for i, d in zip(b.instance_ids, b.instance_data)}


def _assign(reps, st, rate, **kw):
    dl = NoLodSelector(reps, cull=False).select(st, CAM, (64, 64))
    ps = PoseSharing(rate, **kw)
    ps.register(reps)
    return dl, ps.assign(dl)


def test_copies_at_the_same_key_share_a_slot_others_do_not(rep):
    t = 7 / 30
    times = [t, t + 0.01, t - 0.01, t + 1 / 30, t, 0.25 * 0.7 + 1.0, 1.0 - 0.001, 0.0]
    clips = [0, 0, 0, 0, 1, 0, 0, 0]
    dl, table = _assign([rep], _state(times, clips), KEY_RATE)
    s = _slots(dl)
    assert s[0] == s[1] == s[2]  # within half a key of frame 7: one pose
    assert len({s[0], s[3], s[4]}) == 3  # the next key, the other clip: poses of their own
    assert s[6] == s[7]  # a looping clip rounded up to its end is its first pose
    ps = table.sets["tiny"]
    assert ps.instances == 8 and ps.n_poses == len(set(s.values())) == dl.stats["poses"]
    frames = ps.frames
    assert frames[s[0]] == 7.0 and frames[s[3]] == 8.0 and frames[s[4]] == rep.clip_offset[1] + 7.0
    assert frames[s[5]] == round(0.175 * 30)  # t = 1.175 wraps to 0.175 s
    assert frames[s[6]] == 0.0
    assert np.all(frames == np.round(frames))  # at the key rate every pose is a baked row
    assert dl.stats["posed_vertices"] == ps.n_poses * rep.positions.shape[0]
    f = {int(i): float(d[12]) for b in dl.batches for i, d in zip(b.instance_ids, b.instance_data)}
    assert all(f[i] == frames[s[i]] for i in s)  # a copy's frame coordinate is now its pose's


def test_exact_rate_gives_every_copy_its_own_slot(rep):
    times = [0.3, 0.3, 0.3, 0.5]
    dl, table = _assign([rep], _state(times, [0, 0, 0, 0]), 0)
    s = _slots(dl)
    assert sorted(s.values()) == [0, 1, 2, 3]
    f = np.concatenate([b.instance_data[:, 12] for b in dl.batches]).astype(np.float64)
    np.testing.assert_array_equal(table.sets["tiny"].frames, f)  # each its own frame coordinate, exactly
    assert table.exact


def test_a_rate_quantises_local_time_and_keeps_an_off_grid_last_key(rep):
    # rate 4/s: poses every 0.25 s; the twist clip (0.7 s, not looping) ends off that grid and keeps its end
    times = [0.12, 0.13, 0.37, 0.69, 0.6, 0.0]
    dl, table = _assign([rep], _state(times, [0, 0, 0, 1, 1, 1]), 4.0)
    s = _slots(dl)
    fr = table.sets["tiny"].frames
    off1 = rep.clip_offset[1]
    assert fr[s[0]] == 0.0 and fr[s[1]] == pytest.approx(7.5)  # 0.12 s -> 0 s; 0.13 s -> 0.25 s (row 7.5)
    assert s[2] == s[1]  # 0.37 s -> 0.25 s
    assert fr[s[3]] == pytest.approx(off1 + 21.0)  # 0.69 -> the clip's last key (0.7 s), not 0.75
    assert fr[s[4]] == pytest.approx(off1 + 15.0)  # 0.6 -> 0.5 s
    assert fr[s[5]] == pytest.approx(off1)


def test_groups_have_their_own_slots_and_a_character_shares_one_group(rep):
    other = build_rep(tiny_skinned("other"), fps=15)
    st = _state([0.2, 0.2, 0.2, 0.2], [0, 0, 0, 0], chars=[0, 1, 0, 1])
    dl, table = _assign([rep, other], st, KEY_RATE)
    assert set(table.sets) == {"tiny", "other"} and table.sets["other"].frames.tolist() == [3.0]
    s = _slots(dl)
    assert s[0] == s[2] == 0 and s[1] == s[3] == 0
    ps = PoseSharing()
    clusters = ClustersRep("clusters:tiny", dataclasses.replace(rep, key="clusters:tiny"), hierarchy=None)
    ps.register([rep, clusters, dataclasses.replace(rep, key="triangles:tiny"), other])
    assert ps.group_of("clusters:tiny") == ps.group_of("triangles:tiny") == ps.group_of("none:tiny") == "tiny"
    odd = dataclasses.replace(other, key="points:tiny")  # same character name, another bake: a group of its own
    ps.register([odd])
    assert ps.group_of("points:tiny") == "points:tiny"


@pytest.mark.parametrize("rate", [KEY_RATE, 0, 7.5, 30, 1000])
def test_kernel_equals_numpy_reference(rep, rate):
    rng = np.random.default_rng(3)
    other = build_rep(tiny_skinned("other"), fps=20)
    ps = PoseSharing(rate)
    ps.register([rep, other])
    clips = _clip_tables(list(ps.groups.values()), ps.rate)
    n = 3000
    gi = rng.integers(0, 2, n)
    src = [rep, other]
    c = rng.integers(0, 2, n)
    f = np.empty(n)
    for i in range(n):
        r = src[gi[i]]
        f[i] = r.clip_offset[c[i]] + rng.uniform(-0.5, 1.0) * (r.clip_frames[c[i]] - 1)
    f[::7] = np.round(f[::7])  # exactly on rows and ends too
    f = np.float32(f).astype(np.float64)
    a = assign_slots(gi, f, clips, 2)
    b = assign_slots_numpy(gi, f, clips, 2)
    p = assign_slots(gi, f, clips, 2, parallel_min=0)  # the parallel quantisation pass
    for x, y, z in zip(a, b, p):
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(x, z)
    slot, qf, pg, pf = a
    for g in range(2):  # per group: slots 0..P-1 in order of first appearance, one pose per slot
        m = gi == g
        first = [slot[m].tolist().index(k) for k in range(int(slot[m].max()) + 1)]
        assert first == sorted(first)
        assert (pg == g).sum() == slot[m].max() + 1
        if rate != 0:  # quantised: distinct slots are distinct poses
            assert np.unique(pf[pg == g]).shape[0] == (pg == g).sum()
        np.testing.assert_array_equal(qf[m], pf[pg == g][slot[m]])  # every copy carries its pose's frame


def test_nan_frame_coordinates_are_refused(rep):
    d = np.zeros((2, 16), np.float32)
    d[:, 0] = d[:, 5] = d[:, 10] = 1.0
    d[1, 12] = np.nan
    dl = DrawList(np.zeros(3), np.eye(4, dtype=np.float32), np.eye(4, dtype=np.float32), (8, 8),
                  [DrawBatch(rep.key, 0, np.arange(2, dtype=np.int32), d)], {})
    ps = PoseSharing()
    ps.register([rep])
    with pytest.raises(FloatingPointError, match="NaN or Inf"):
        ps.assign(dl)


def test_pose_rate_parameter():
    p = POSE_PARAMS["pose_rate"]
    assert p.default == KEY_RATE and p.check("k", "key") == "key"
    assert p.check("k", 0) == 0.0 and p.check("k", 12) == 12.0
    for bad in (-1, "fast", 1e6, float("nan"), True, [1]):
        with pytest.raises(ParamError):
            p.check("lod.pose_rate", bad)
    with pytest.raises(ValueError, match=r"\[lod\] pose_rate"):
        check_rate(-3)
