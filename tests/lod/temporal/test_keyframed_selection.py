"""Keyframed selection of the crowd's LOD (lod/temporal/selection.py): n = 1 is
the inner selector, n > 1 selects only at keyframes, every visible instance is
drawn exactly once outside transitions and exactly twice (complementary fades)
inside them, per-row payloads (cluster cuts, point jobs) follow their rows."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.temporal import selection as ks
from lod.chains import chain as tm_chain
from lod.chains import mode as tm
from lod.clusters.mode import ClusterDrawBatch
from lod.drawlist import FADE_IN, FADE_OUT, DrawBatch
from lod.points.rep import PointsBatch
from lod.view import Camera
from sim.procedural import humanoid
from sim.state import CrowdState

SIZE = (320, 240)


@pytest.fixture(scope="module")
def chain():
    reps, _ = tm.build([humanoid(1500, 3)], ["h"], [30], {"poe": 1.0, "levels": 5}, cache=False)
    return reps


class Counting:
    """A triangles selector that counts its ``select`` calls (and exposes its base)."""

    def __init__(self, reps, poe=1.0):
        self.sel = tm.TrianglesSelector(reps, poe=poe)
        self._inner = self.sel._inner
        self.calls = 0
        self.poe = poe

    def select(self, state, camera, size, statics=()):
        self.calls += 1
        self.sel.poe = self.poe
        return self.sel.select(state, camera, size, statics)


def crowd(n=60, seed=0, spread=40.0):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:] = np.c_[rng.uniform(-spread, spread, n), np.zeros(n), rng.uniform(-spread * 3, 0, n)]
    st.heading[:] = rng.uniform(0, 6.28, n)
    st.scale[:] = 1.0
    st.anim_time[:] = rng.uniform(0, 1, n)
    st.anim_rate[:] = 1.0
    return st


def cam_at(f, speed=1.2, yaw_rate=0.06):
    """A camera flying forward (-z) and turning: instances change level and enter / leave the view."""
    return Camera.from_yaw_pitch(np.array([0.0, 1.7, 30.0 - speed * f]), yaw_rate * f, -0.05, 50.0, 0.1, 500.0)


def advance(st, dt=1 / 30):
    st.anim_time[:] = st.anim_time + dt
    st.position[:, 0] += 0.5 * dt * np.cos(st.heading)


def drawn(dl):
    """(unfaded ids, outgoing ids, incoming ids) of a DrawList (agents only)."""
    out = {None: [], FADE_OUT: [], FADE_IN: []}
    for b in dl.batches:
        ids = np.asarray(b.instance_ids, np.int64)
        if ids.size and ids[0] < 0:
            continue
        out[None if b.fade is None else b.fade[1]].append(ids)
    return tuple(np.sort(np.concatenate(out[k])) if out[k] else np.zeros(0, np.int64)
                 for k in (None, FADE_OUT, FADE_IN))


def test_n1_is_the_inner_selector_exactly(chain):
    st = crowd()
    a, b = Counting(chain), tm.TrianglesSelector(chain)
    w = ks.KeyframedSelector(a, n=1)
    for f in range(4):
        cam = cam_at(f)
        da, db = w.select(st, cam, SIZE), b.select(st, cam, SIZE)
        assert len(da.batches) == len(db.batches) and da.stats == db.stats
        for x, y in zip(da.batches, db.batches):
            assert (x.rep, x.part, x.level, x.index_range, x.fade) == (y.rep, y.part, y.level, y.index_range, None)
            assert np.array_equal(x.instance_ids, y.instance_ids)
            assert np.array_equal(x.instance_data, y.instance_data)
        advance(st)
    assert a.calls == 4 and w.n_selections == 4
    assert ks.keyframed(b, 1) is b


@pytest.mark.parametrize("mode,per_key", [("current", 1), ("delayed", 1), ("extrapolated", 1)])
def test_selection_runs_only_on_keyframes(chain, mode, per_key):
    st = crowd(spread=10.0)  # all in view of a still camera: no instance needs a selection on the spot
    inner = Counting(chain)
    n = 4
    w = ks.KeyframedSelector(inner, n=n, mode=mode)
    cam = Camera.from_yaw_pitch(np.array([0.0, 20.0, 60.0]), 0.0, -0.3, 60.0, 0.1, 500.0)
    keys = []
    for f in range(3 * n):
        dl = w.select(st, cam, SIZE)
        keys.append(dl.stats["keyframe"])
        advance(st, 0.002)  # tiny steps keep every instance in its clip segment
    assert keys == [f % n == 0 for f in range(3 * n)]
    expected = 3 + (1 if mode == "extrapolated" else 0)  # mode 3 selects keys 0 and 1 at frame 0
    assert w.n_fresh_selections == 0
    assert inner.calls == expected == w.n_selections


@pytest.mark.parametrize("mode,margin", [("current", 0.0), ("current", 15.0), ("extrapolated", 15.0)])
def test_no_instance_dropped_or_doubled_outside_transitions(chain, mode, margin):
    st = crowd(n=80, seed=1)
    inner = Counting(chain)
    n = 5
    w = ks.KeyframedSelector(inner, n=n, mode=mode, cull_margin=margin)
    ref = tm.TrianglesSelector(chain)
    n_trans = n_fresh = 0
    for f in range(4 * n):
        cam = cam_at(f)
        dl = w.select(st, cam, SIZE)
        plain, out, inn = drawn(dl)
        visible = np.sort(np.concatenate([b.instance_ids for b in ref.select(st, cam, SIZE).batches]))
        assert np.unique(plain).size == plain.size  # nobody drawn twice unfaded
        assert np.array_equal(out, inn)  # a transition draws its instance once in each role
        assert np.intersect1d(plain, out).size == 0
        assert np.array_equal(np.sort(np.concatenate([plain, out])), visible)  # nobody dropped
        for b in dl.batches:
            if b.fade is not None:
                assert b.fade[0] == pytest.approx((f % n) / n)
        assert dl.stats["transitions"] == out.size
        assert dl.stats["instances"] == visible.size
        n_trans += out.size
        n_fresh += dl.stats["fresh"]
        advance(st)
    assert n_trans > 0  # the path makes levels change between keyframes
    if margin == 0.0:
        assert n_fresh > 0  # instances enter the turning view mid-interval and are selected on the spot
    # selections: one per keyframe (mode 3: keys 0 and 1 at frame 0) plus the on-the-spot ones
    assert w.n_selections == 4 + (mode == "extrapolated")
    assert inner.calls == w.n_selections + w.n_fresh_selections


def test_inbetween_frames_draw_current_transforms_and_keyframe_levels(chain):
    st = crowd(n=30, seed=2, spread=15.0)
    w = ks.KeyframedSelector(tm.TrianglesSelector(chain), n=4, mode="current")
    base = ks.base_selector_of(w.inner)
    cam = Camera.from_yaw_pitch(np.array([0.0, 10.0, 40.0]), 0.0, -0.2, 50.0, 0.1, 500.0)
    k0 = w.select(st, cam, SIZE)
    levels = {int(i): b.level for b in k0.batches for i in b.instance_ids}
    for _ in range(3):
        advance(st, 0.002)
        dl = w.select(st, cam, SIZE)
        cur = base.select(st, cam, SIZE)
        rows = {int(i): d for b in cur.batches for i, d in zip(b.instance_ids, b.instance_data)}
        for b in dl.batches:
            assert b.fade is None
            for i, d in zip(b.instance_ids, b.instance_data):
                assert np.array_equal(d, rows[int(i)])  # current transform and animation
                assert b.level == levels[int(i)]  # the keyframe's level
        assert not dl.stats["keyframe"]


def test_live_attributes_forwarded(chain):
    inner = tm.TrianglesSelector(chain, poe=1.0)
    w = ks.KeyframedSelector(inner, n=3)
    assert w.poe == 1.0
    w.poe = 2.5
    assert inner.poe == 2.5 and "poe" not in w.__dict__
    w.set_interval(6)
    assert w.n == 6 and w.frame == 0
    with pytest.raises(AttributeError):
        _ = w.no_such_attribute


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_bad_interval_rejected(chain, bad):
    with pytest.raises(ValueError, match="keyframe_every"):
        ks.KeyframedSelector(tm.TrianglesSelector(chain), n=bad)


def test_bad_mode_rejected(chain):
    with pytest.raises(ValueError, match="keyframe_extrapolation"):
        ks.KeyframedSelector(tm.TrianglesSelector(chain), n=2, mode="future")


def test_unkeyframable_selector_is_a_clear_error():
    class Bare:
        def select(self, state, camera, size, statics=()):
            raise AssertionError

    with pytest.raises(TypeError, match="cannot be keyframed"):
        ks.KeyframedSelector(Bare(), n=2)


def test_empty_crowd(chain):
    w = ks.KeyframedSelector(tm.TrianglesSelector(chain), n=3)
    st = CrowdState.empty(0)
    for f in range(4):
        dl = w.select(st, cam_at(f), SIZE)
        assert dl.batches == [] and dl.stats["instances"] == 0


# ---------------------------------------------------------------------------------------- per-row payloads
def _data(k):
    d = np.zeros((k, 16), np.float32)
    d[:, 0] = np.arange(k)
    return d


def test_take_rows_subsets_cluster_cuts():
    b = ClusterDrawBatch("clusters:h", 0, np.array([10, 11, 12], np.int32), _data(3), triangles=60,
                         offsets=np.array([0, 2, 2, 5]), clusters=np.array([7, 8, 1, 2, 3], np.int32))
    out = ks.take_rows(b, np.array([2, 0]), np.array([12, 10], np.int32), _data(2), fade=(0.5, FADE_IN))
    assert isinstance(out, ClusterDrawBatch) and out.fade == (0.5, FADE_IN)
    assert out.offsets.tolist() == [0, 3, 5] and out.clusters.tolist() == [1, 2, 3, 7, 8]
    assert out.instance_ids.tolist() == [12, 10]
    sig = ks.row_signatures(b)
    assert sig[0] != sig[2] and sig[0] != sig[1]
    b2 = ClusterDrawBatch("clusters:h", 0, np.array([1], np.int32), _data(1), offsets=np.array([0, 2]),
                          clusters=np.array([8, 7], np.int32))  # the same cut in another order
    assert ks.row_signatures(b2)[0] == sig[0]
    tri, _ = ks.row_counts(b)
    assert tri.tolist() == [24.0, 0.0, 36.0]


def test_take_rows_renumbers_point_jobs():
    b = PointsBatch("points:h", 1, np.array([4, 5, 6], np.int32), _data(3), triangles=9, points=70,
                    point_jobs=np.array([[0, 0, 10], [2, 100, 50], [1, 5, 10]]),
                    tri_jobs=np.array([[2, 0, 9]]))
    out = ks.take_rows(b, np.array([2, 1]), np.array([6, 5], np.int32), _data(2))
    assert isinstance(out, PointsBatch) and out.part == 1
    assert sorted(out.point_jobs.tolist()) == [[0, 100, 50], [1, 5, 10]]
    assert out.tri_jobs.tolist() == [[0, 0, 9]]
    tri, pts = ks.row_counts(b)
    assert tri.tolist() == [0, 0, 9] and pts.tolist() == [10, 10, 50]
    s = ks.row_signatures(b)
    assert len(set(s.tolist())) == 3


def test_row_signature_distinguishes_levels_not_rows():
    a = tm_chain.TriangleDrawBatch("triangles:h", 0, np.array([1, 2], np.int32), _data(2), level=1, index_range=(0, 30))
    b = tm_chain.TriangleDrawBatch("triangles:h", 0, np.array([3], np.int32), _data(1), level=1, index_range=(0, 30))
    c = tm_chain.TriangleDrawBatch("triangles:h", 0, np.array([3], np.int32), _data(1), level=2, index_range=(30, 12))
    sa, sb, sc = ks.row_signatures(a), ks.row_signatures(b), ks.row_signatures(c)
    assert sa[0] == sa[1] == sb[0] != sc[0]
    assert ks.row_signatures(DrawBatch("none:h", 0, np.zeros(0, np.int32), _data(0))).shape == (0,)


def test_subset_state_of_namespace_and_crowdstate():
    st = crowd(n=5)
    sub = ks.subset_state(st, np.array([4, 1]))
    assert isinstance(sub, CrowdState) and sub.n == 2 and np.array_equal(sub.position, st.position[[4, 1]])
    ns = SimpleNamespace(n=3, position=np.arange(9.0).reshape(3, 3), heading=np.arange(3.0), tag="x")
    s2 = ks.subset_state(ns, np.array([2]))
    assert s2.n == 1 and s2.position.tolist() == [[6.0, 7.0, 8.0]] and s2.tag == "x"


def test_margin_camera_culls_wider_but_projects_the_same():
    cam = Camera.from_yaw_pitch(np.array([1.0, 2.0, 3.0]), 0.3, -0.1, 50.0, 0.1, 100.0)
    m = ks.MarginCamera.of(cam, 10.0)
    assert np.array_equal(m.projection(1.5), cam.projection(1.5)) and m.fov_y == cam.fov_y
    assert np.array_equal(ks.MarginCamera.of(cam, 0.0).frustum_planes(1.5), cam.frustum_planes(1.5))
    # a point just outside the view's left edge is inside the margin frustum, one far outside is not
    half_h = np.arctan(1.5 * np.tan(np.radians(25.0)))
    for ang, inside in ((half_h + np.radians(5.0), True), (half_h + np.radians(15.0), False)):
        d = np.array([-np.sin(ang), 0.0, -np.cos(ang)]) * 20.0
        p = cam.rotation @ d  # camera-relative world point
        assert not (cam.frustum_planes(1.5)[:, :3] @ p + cam.frustum_planes(1.5)[:, 3] >= 0).all()
        assert (m.frustum_planes(1.5)[:, :3] @ p + m.frustum_planes(1.5)[:, 3] >= 0).all() == inside


def test_clip_change_keeps_the_keyframe_level(chain):
    """A chain level does not depend on the clip: an instance whose clip changes
    between keyframes is drawn with its keyframe level and its new clip, without
    a selection on the spot."""
    st = crowd(n=10, seed=4, spread=8.0)
    inner = Counting(chain)
    w = ks.KeyframedSelector(inner, n=4, mode="current")
    cam = Camera.from_yaw_pitch(np.array([0.0, 10.0, 40.0]), 0.0, -0.2, 50.0, 0.1, 500.0)
    k0 = w.select(st, cam, SIZE)
    level = {int(i): b.level for b in k0.batches for i in b.instance_ids}
    n_clips = chain[0].n_parts
    assert n_clips >= 2
    st.clip[:3] = 1
    dl = w.select(st, cam, SIZE)
    assert dl.stats["fresh"] == 0 and inner.calls == 1
    for b in dl.batches:
        for i in b.instance_ids.tolist():
            assert b.level == level[i] and b.part == (1 if i < 3 else 0)


def test_points_segment_change_is_selected_on_the_spot(tmp_path):
    """Point jobs index one keyframe segment's octree (part-dependent): an instance
    whose segment changed between keyframes is selected again, never drawn with
    the old segment's jobs, never dropped."""
    from lod.points import mode as pm
    from lod.points import rep as pm_rep

    from tiny_characters import tiny_keyframed

    reps, sel = pm.build([tiny_keyframed()], ["q"], [30], {"splat_size": 2}, cache=pm_rep.HierarchyCache(tmp_path),
                         progress=lambda it, d: it)
    w = ks.KeyframedSelector(sel, n=4, mode="current")
    st = CrowdState.empty(6)
    st.position[:, 0] = np.arange(6) * 1.5 - 4.0
    cam = Camera.look_at((0.0, 1.0, 8.0), (0.0, 0.5, 0.0), fov_y=60)
    kf = reps[0].keyframed
    fresh = 0
    for f in range(8):
        dl = w.select(st, cam, SIZE)
        plain, out, inn = drawn(dl)
        assert np.array_equal(np.sort(np.concatenate([plain, out])), np.arange(6))
        for b in dl.batches:
            assert isinstance(b, PointsBatch)
            seg, _ = kf.locate(0, st.anim_time[np.asarray(b.instance_ids)])
            assert (seg == b.part).all()  # drawn with the current segment's octree
        fresh += dl.stats["fresh"]
        st.anim_time[:] += 0.15
    assert fresh > 0
