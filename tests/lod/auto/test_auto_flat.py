"""Mode auto's selection over flat arrays of all instances (lod/auto/flat.py, lod/auto/flat_points.py)
against the per-group path it replaces (AutoSelector.flat = False, the reference): the same plans, choices,
telemetry and draw lists (every batch's instances, instance data, point/triangle jobs, cluster cuts) on
crowds with several groups, near and far views, bounds 0-6 px, cost models and candidate sets; and its
numba pieces against their references."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.auto import build as ab
from lod.auto import candidates as ac
from lod.auto import cost_model
from lod.auto import flat, flat_plans
from lod.auto import flat_points as fp
from lod.auto import mode as am
from lod.full.reps import build_keyframed_rep
from lod.points import jobs
from lod.points import mode as pm
from lod.points.jobs import follow_traverse
from lod.view import Camera
from sim.procedural import humanoid

SIZE = (320, 240)
MODEL = cost_model.CostModel()
FREE_PASSES = cost_model.CostModel({"points": 1e-7, "clusters": 1e-6, "splat_pixels": 0.0, "splat_area": 0.0,
                                    "cluster_frames": 0.0})
CHEAP_POINTS = cost_model.CostModel({"points": 1e-9, "point_instances": 1e-9, "splat_pixels": 0.0,
                                     "splat_area": 0.0})
VIEWS = [Camera.look_at((0, 1.6, 8.0), (0, 1.0, -10.0)), Camera.look_at((0, 40.0, 60.0), (0, 0, -60.0)),
         Camera.look_at((30, 1.7, -30), (-30, 1.0, -60)), Camera.look_at((0, 300.0, 400.0), (0, 0, -100.0))]


@pytest.fixture(scope="module")
def built():
    char = humanoid(1200, 5)
    # the per-keyframe-pair octrees: the flat point forest's (hierarchies that follow the animation:
    # test_follow_points_run_the_flat_path)
    reps, sel = ab.build([char], ["h"], [30], {"poe": 0.0, "keyframes": 3}, cache=False, model=MODEL,
                         progress=False, points_params={"animation": "baked"})
    return SimpleNamespace(char=char, reps=reps, tri_reps=[reps[0]], sel=sel)


def _crowd(n, seed, half_width=50.0, depth=300.0, clips=2):
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(-half_width, half_width, n), np.zeros(n), rng.uniform(-depth, 5, n)])
    t = rng.uniform(0, 2, n)
    t[:5] = [np.nan, -3.0, 1e6, 0.0, np.inf]  # non-finite, negative and huge animation times
    return SimpleNamespace(n=n, character=np.zeros(n, np.int64), clip=rng.integers(0, clips, n),
                           anim_time=t, position=pos, scale=rng.uniform(0.8, 1.3, n),
                           heading=rng.uniform(0, 6.3, n))


def _same(a, b):
    """Two DrawLists of the same selection are equal batch for batch."""
    assert [(x.rep, x.part, x.level) for x in a.batches] == [(x.rep, x.part, x.level) for x in b.batches]
    for x, y in zip(a.batches, b.batches):
        assert type(x) is type(y)
        np.testing.assert_array_equal(x.instance_ids, y.instance_ids)
        np.testing.assert_array_equal(x.instance_data, y.instance_data)
        assert (x.triangles, x.points) == (y.triangles, y.points)
        for f in ("point_jobs", "tri_jobs", "offsets", "clusters", "index_range"):
            if hasattr(x, f):
                np.testing.assert_array_equal(getattr(x, f), getattr(y, f))
    sa, sb = dict(a.stats), dict(b.stats)
    aa, ab = sa.pop("auto"), sb.pop("auto")
    assert sa == sb and a.options == b.options
    for k in ("levels", "representations", "options", "plan", "bound"):
        assert aa[k] == ab[k], k
    assert aa["plans_ms"].keys() == ab["plans_ms"].keys()
    for n in aa["plans_ms"]:
        assert aa["plans_ms"][n] == pytest.approx(ab["plans_ms"][n], rel=1e-12)


def _pair(built, cands, poe, model):
    out = []
    for f in (True, False):
        s = am.AutoSelector(built.tri_reps, poe=poe, model=model, candidates=cands)
        s.flat = f
        out.append(s)
    return out


def test_flat_selection_draws_what_the_per_group_path_draws(built, monkeypatch):
    """Every combination: the flat path's groups and plans are used (no silent fallback) and the draw
    lists equal the per-group path's; the cluster cut is skipped for none, some and all of a group."""
    calls, need = [], set()
    orig, count = flat_plans.price, flat._count_by_group
    monkeypatch.setattr(flat_plans, "price", lambda *a, **k: calls.append(1) or orig(*a, **k))

    def counted(gof, mask, G):
        out = count(gof, mask, G)
        need.update("none" if x == 0 else "all" if x == k else "some"
                    for x, k in zip(out.tolist(), np.bincount(gof, minlength=G).tolist()))
        return out

    monkeypatch.setattr(flat, "_count_by_group", counted)
    cl, pts = built.sel.candidates[1], built.sel.candidates[2]
    plans = set()
    st = _crowd(300, 3)
    for model in (MODEL, FREE_PASSES, CHEAP_POINTS):
        for cands in ([cl, pts], [pts], [cl]):
            for poe in (0.0, 1.0, 3.0):
                a, b = _pair(built, cands, poe, model)
                for cam in VIEWS[1:]:
                    da, db = a.select(st, cam, SIZE), b.select(st, cam, SIZE)
                    _same(da, db)
                    plans.add(da.stats["auto"]["plan"])
    assert len(calls) == 3 * 3 * 3 * 3
    assert {"triangles", "points", "mixed"} <= plans, plans
    assert need == {"none", "some", "all"}, need


def test_flat_groups_equal_the_per_group_blocks(built):
    """The blocks the flat path hands back (cheapest admissible option, its column, the optimistic price,
    the skipped instances) and the options the emission reads equal the per-group path's, group by group."""
    cl, pts = built.sel.candidates[1], built.sel.candidates[2]
    st = _crowd(400, 11)
    for poe in (1.0, 3.0):
        a, b = _pair(built, [cl, pts], poe, FREE_PASSES)
        cam = VIEWS[1]
        w, h = SIZE
        frame = ac.Frame(st, cam, SIZE, cam.frustum_planes(w / h), am.viewport_scale(h, cam.fov_y), poe, FREE_PASSES)
        dl = a._inner.select(st, cam, SIZE)
        ga = a._groups(frame, dl, poe, [])
        gb = b._groups(frame, dl, poe, [])
        assert isinstance(ga, flat.FlatGroups) and not isinstance(gb, flat.FlatGroups)
        assert len(ga) == len(gb) == 2
        for (g1, o1, n1), (g2, o2, n2) in zip(ga, gb):
            assert n1 == n2 and g1.char == g2.char and g1.batch is g2.batch
            np.testing.assert_array_equal(g1.rows, g2.rows)
            assert [x.cand.name for x in o1] == [x.cand.name for x in o2]
            for x, y in zip(o1, o2):
                assert (x.a, x.m) == (y.a, y.m)
                for f in ("bmin", "barg", "opt"):
                    np.testing.assert_array_equal(getattr(x, f), getattr(y, f), err_msg=f)
                assert (x.skipped is None) == (y.skipped is None)
                if x.skipped is not None:
                    np.testing.assert_array_equal(x.skipped, y.skipped)
                np.testing.assert_array_equal(np.broadcast_to(x.options.cost, y.options.cost.shape), y.options.cost)
                np.testing.assert_array_equal(x.options.error, y.options.error)
                assert tuple(x.options.labels) == tuple(y.options.labels)
                if x.cand.name == "points":
                    p1, p2 = x.options.plan, y.options.plan
                    for u, v in zip(p1[1:4], p2[1:4]):  # data, ids, order
                        np.testing.assert_array_equal(u, v)
                    assert sorted(p1[4]) == sorted(p2[4])
                    for s in p2[4]:
                        assert p1[4][s][:2] == p2[4][s][:2]
                        np.testing.assert_array_equal(p1[4][s][2], p2[4][s][2])
                        np.testing.assert_array_equal(p1[4][s][3], p2[4][s][3])
                    np.testing.assert_array_equal(p1[5], p2[5])
                    np.testing.assert_array_equal(p1[6], p2[6])


def test_a_candidate_without_a_flat_form_runs_the_per_group_path(built):
    """A subclass (its options may differ) is never priced by the flat kernels."""

    class Mine(ac.PointsCandidate):
        pass

    pts = built.sel.candidates[2]
    mine = Mine.__new__(Mine)
    mine.__dict__.update(pts.__dict__)
    sel = am.AutoSelector(built.tri_reps, poe=2.0, model=MODEL, candidates=[mine])
    cam = VIEWS[1]
    frame = ac.Frame(_crowd(50, 1), cam, SIZE, cam.frustum_planes(SIZE[0] / SIZE[1]),
                     am.viewport_scale(SIZE[1], cam.fov_y), 2.0, MODEL)
    dl = sel._inner.select(frame.state, cam, SIZE)
    assert not isinstance(sel._groups(frame, dl, 2.0, []), flat.FlatGroups)


def test_flat_traversal_equals_traverse_instances():
    """The traversal over a forest of segment hierarchies (every instance with its bin's hierarchy) gives
    the job tables and totals of lod.points.jobs.traverse_instances per segment, serial and in chunks."""
    kf = build_keyframed_rep(pm.keyframed_character(humanoid(800, 2), 3), key="w")
    from lod.points.coarse import add_coarse
    from lod.points.octree import build_hierarchy

    hs = []
    for s in range(2):
        h = build_hierarchy(*pm.segment_arrays(kf, s), seed=s, progress=False)
        if s == 0:
            add_coarse(h)
        hs.append(h)
    rep = SimpleNamespace(hierarchies=hs)
    forest = fp.build_forest({0: rep})
    rng = np.random.default_rng(4)
    cam = Camera.look_at((0, 30.0, 60.0), (0, 0, -40.0))
    planes = cam.frustum_planes(4 / 3)
    vs = 240 / (2 * np.tan(np.radians(cam.fov_y) / 2))
    counts = np.array([700, 500])
    K = int(counts.sum())
    yaw = rng.uniform(0, 6.3, K)
    d = np.zeros((K, 16), np.float32)
    d[:, 0], d[:, 2], d[:, 5], d[:, 8], d[:, 10] = np.cos(yaw), np.sin(yaw), 1, -np.sin(yaw), np.cos(yaw)
    d[:, 3], d[:, 7], d[:, 11] = rng.uniform(-60, 60, K), -30.0, rng.uniform(-400, -40, K)
    d[:, 12] = rng.uniform(-0.1, 1.1, K)
    bstart = np.array([0, 700, K])
    kbin = np.repeat([0, 1], counts)
    for chunk_min in (10 ** 9, 64):
        old = jobs.TRAVERSE_PARALLEL_MIN
        jobs.TRAVERSE_PARALLEL_MIN = chunk_min
        try:
            pj, tj, ps, ts, p_at, t_at = fp.traverse(forest, d, kbin, np.array([0, 1, 0]), bstart, planes, vs, 2.0)
        finally:
            jobs.TRAVERSE_PARALLEL_MIN = old
        for b in range(2):
            rj, rt, rps, rts = jobs.traverse_instances(hs[b], d[bstart[b]:bstart[b + 1]], planes, vs, 2.0, totals=True)
            np.testing.assert_array_equal(pj[p_at[b]:p_at[b + 1]], rj)
            np.testing.assert_array_equal(tj[t_at[b]:t_at[b + 1]], rt)
            np.testing.assert_array_equal(ps[bstart[b]:bstart[b + 1]], rps)
            np.testing.assert_array_equal(ts[bstart[b]:bstart[b + 1]], rts)


def test_flat_locate_equals_keyframed_locate(built):
    """The flat path's segment search (lod.auto.flat_points._locate_kernel) is KeyframedRep.locate's, edge
    times included."""
    kf = built.sel.candidates[2].by_char[0].keyframed
    t = np.concatenate([np.linspace(-3, 5, 997), [np.nan, np.inf, -np.inf, 0.0, 1e9]])
    n = t.shape[0]
    for clip in range(kf.n_clips):
        a0, ns = int(kf.anim_first_seg[clip]), int(kf.anim_n_segs[clip])
        seg, u = kf.locate(clip, t)
        binof, uof = np.empty(n, np.int64), np.empty(n)
        fp._locate_kernel(np.arange(n, dtype=np.int32), np.zeros(n, np.int64), np.ones(1, bool), np.ones(1, bool),
                          np.array([ns]), np.zeros(1, np.int64), np.array([float(kf.anim_t0[clip])]),
                          np.array([float(kf.anim_duration[clip])]), np.array([bool(kf.anim_loop[clip])]),
                          np.array([7]), kf.seg_start[a0:a0 + ns].astype(float), kf.seg_end[a0:a0 + ns].astype(float),
                          t, binof, uof)
        np.testing.assert_array_equal(binof - 7 + a0, seg)
        np.testing.assert_array_equal(uof, u)


@pytest.fixture(scope="module")
def follow_built():
    char = humanoid(600, 3)
    reps, sel = ab.build([char], ["h"], [30], {"poe": 0.0, "keyframes": 2}, cache=False, model=CHEAP_POINTS,
                         progress=False, points_params={"animation": "follow"})
    return SimpleNamespace(reps=reps, sel=sel)


def test_follow_traverse_equals_traverse_instances(follow_built):
    """The flat path's traversal of a follow hierarchy (the root decided in line) gives traverse_instances'
    jobs, totals and deepest nodes exactly: near and far views, whole and fractional baked rows, non-finite
    and out-of-range frame coordinates, splats 1-3, serial and chunked (parallel) runs."""
    from lod.points.traverse import viewport_scale

    pc = [c for c in follow_built.sel.candidates if isinstance(c, ac.PointsCandidate)][0]
    rep = next(iter(pc.by_char.values()))
    vs = viewport_scale(SIZE[1], VIEWS[0].fov_y)
    rng = np.random.default_rng(5)
    n_root = n_deep = 0
    for part in range(rep.n_parts):
        h = rep.view(part)
        F = h.joint_table.shape[0]
        for k, cam in ((600, VIEWS[0]), (600, VIEWS[1]), (600, VIEWS[2]), (30_000, VIEWS[3])):
            pos = np.column_stack([rng.uniform(-60, 60, k), np.zeros(k), rng.uniform(-400, 10, k)])
            th, s = rng.uniform(0, 6.3, k), rng.uniform(0.8, 1.3, k)
            d = np.zeros((k, 16), np.float32)
            d[:, 0], d[:, 2], d[:, 5] = s * np.cos(th), s * np.sin(th), s
            d[:, 8], d[:, 10] = -s * np.sin(th), s * np.cos(th)
            d[:, [3, 7, 11]] = pos - np.asarray(cam.position)
            f = rng.uniform(0, F - 1, k)
            f[::2] = np.round(f[::2])  # whole rows (pose_rate "key") and fractional ones
            f[:6] = [np.nan, -3.0, 1e6, np.inf, 0.0, F - 1]
            d[:, 12] = f
            planes = cam.frustum_planes(SIZE[0] / SIZE[1])
            for p in (1, 2, 3):
                want = jobs.traverse_instances(h, d, planes, vs, p, totals=True, deepest=True)
                got = follow_traverse(h, d, planes, vs, p)
                for x, y in zip(got, want):
                    np.testing.assert_array_equal(x, y)
                n_root += int((want[4] <= 0).sum())
                n_deep += int((want[4] > 0).sum())
    assert n_root > 1000 and n_deep > 100, (n_root, n_deep)


def test_follow_points_run_the_flat_path(follow_built, monkeypatch):
    """A point candidate whose hierarchies follow the animation (lod.points.follow) is priced by the flat path
    (each group's options from one follow_batch, the other candidates and the plans flat) and draws what the
    per-group path draws: several views, bounds, cost models and candidate sets, with clips of both kinds of
    group (several clips per character)."""
    reps, sel = follow_built.reps, follow_built.sel
    pc = [c for c in sel.candidates if isinstance(c, ac.PointsCandidate)][0]
    cl = [c for c in sel.candidates if isinstance(c, ac.ClustersCandidate)][0]
    assert all(getattr(r, "follow", False) for r in pc.by_char.values())
    priced, seen = [], []
    orig, groups = flat_plans.price, flat.groups
    monkeypatch.setattr(flat_plans, "price", lambda *a, **k: priced.append(1) or orig(*a, **k))
    monkeypatch.setattr(flat, "groups", lambda *a, **k: seen.append(groups(*a, **k)) or seen[-1])
    state = _crowd(300, 3)
    plans, n = set(), 0
    for model in (MODEL, FREE_PASSES, CHEAP_POINTS):
        for cands in ([cl, pc], [pc]):
            for poe in (0.0, 1.0, 3.0):
                a, b = (am.AutoSelector(reps[:1], poe=poe, model=model, candidates=cands) for _ in range(2))
                b.flat = False
                for cam in VIEWS:
                    da = a.select(state, cam, SIZE)
                    _same(da, b.select(state, cam, SIZE))
                    plans.add(da.stats["auto"]["plan"])
                    n += da.stats["auto"]["representations"].get("points", 0)
    assert len(priced) == len(seen) == 3 * 2 * 3 * len(VIEWS)
    assert all(isinstance(g, flat.FlatGroups) for g in seen)
    assert {"triangles", "points", "mixed"} <= plans, plans
    assert n > 0


@pytest.mark.parametrize("keyframed", ["baked", "follow"])
def test_follow_and_other_points_in_one_flat_selection(keyframed, monkeypatch):
    """A skinned character that follows the animation beside a keyframed one whose points are the baked
    per-keyframe-pair octrees (the default for a short keyframe animation) or follow too (keyframed follow:
    node boxes at the segment's ends, u in column 12): one flat selection prices both kinds of group and draws
    what the per-group path draws."""
    if keyframed == "follow":
        monkeypatch.setattr(pm, "animation_path", lambda ch, p: ("follow", "test"))
    chars = [humanoid(600, 3), pm.keyframed_character(humanoid(500, 2), 3)]
    reps, sel = ab.build(chars, ["h", "k"], [30, 30], {"poe": 0.0, "keyframes": 2}, cache=False,
                         model=CHEAP_POINTS, progress=False)
    pc = [c for c in sel.candidates if isinstance(c, ac.PointsCandidate)][0]
    cl = [c for c in sel.candidates if isinstance(c, ac.ClustersCandidate)][0]
    assert getattr(pc.by_char[0], "follow", False)
    assert getattr(pc.by_char[1], "follow", False) == (keyframed == "follow")
    priced = []
    orig = flat_plans.price
    monkeypatch.setattr(flat_plans, "price", lambda *a, **k: priced.append(1) or orig(*a, **k))
    state = _crowd(400, 7)
    state.character = np.random.default_rng(2).integers(0, 2, state.n)
    state.clip = np.where(state.character == 0, state.clip, 0)
    n, calls = {0: 0, 1: 0}, 0
    for model in (MODEL, CHEAP_POINTS):
        for cands in ([cl, pc], [pc]):
            for poe in (1.0, 3.0):
                a, b = (am.AutoSelector(reps[:2], poe=poe, model=model, candidates=cands) for _ in range(2))
                b.flat = False
                for cam in VIEWS:
                    da = a.select(state, cam, SIZE)
                    _same(da, b.select(state, cam, SIZE))
                    calls += 1
                    for x in da.batches:
                        if str(x.rep).startswith("points:"):
                            n[0 if x.rep == pc.by_char[0].key else 1] += x.n_instances
    assert len(priced) == calls
    assert n[0] > 0 and n[1] > 0, n
