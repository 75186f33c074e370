"""Hierarchical instantiation (lod/points/instancing.py, Wand & Straßer §3.6):
the weighted point octree, clip surfaces, super-hierarchies and the per-frame
top-down choice between super-hierarchies and instances."""
import numpy as np
import pytest

from lod.points import instancing as pi
from lod.points import mode as pm
from lod.points import rep as pm_rep
from lod.points.traverse import traverse, traverse_reference, viewport_scale
from lod.view import Camera
from sim.character import KeyframedCharacter
from sim.instancing import Hierarchy, Instancing, parse_levels
from sim.keyframes import Keyframe, KeyframeAnimation, Segment
from tiny_characters import uv_sphere


def walker_character(n_lat=12, n_lon=16, name="walker") -> KeyframedCharacter:
    """A looping 3-keyframe 'walker': an ellipsoid 1.8 m tall, 0.6 m wide,
    swaying left and right and changing colour (about 350 triangles, one
    triangle list for every segment)."""
    nrm, idx = uv_sphere(n_lat, n_lon)
    base = nrm * [0.3, 0.9, 0.3] + [0, 0.9, 0]
    keys = []
    for sway, col in ((0.0, (0.8, 0.3, 0.2)), (0.35, (0.2, 0.6, 0.3)), (-0.35, (0.2, 0.3, 0.8))):
        p = base.copy()
        p[:, 0] += sway * (p[:, 1] / 1.8) ** 2
        keys.append(Keyframe(p.astype(np.float32), nrm.astype(np.float32),
                             np.tile([*col, 1.0], (len(p), 1)).astype(np.float32), idx))
    ident = np.arange(len(base), dtype=np.int32)
    segs = [Segment(ident, ident, idx.copy()) for _ in range(3)]
    anim = KeyframeAnimation("walk", np.array([0.0, 0.4, 0.8]), keys, segs, duration=1.2, loop=True)
    return KeyframedCharacter(name, {"walk": anim})


LEVELS = [{"layout": "grid", "nx": 5, "nz": 5, "spacing": [2.0, 2.0], "phase_step": 0.13},
          {"layout": "grid", "nx": 2, "nz": 2, "spacing": [12.0, 12.0], "phase_step": 0.37}]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A 2 x 2 grid of 5 x 5 blocks of walkers (depth 2) in mode "points"."""
    h = Hierarchy(parse_levels(LEVELS), character=0, clip=0, period=1.2, origin=(3.0, 0.0, -2.0), yaw=0.3)
    cache = pm_rep.HierarchyCache(tmp_path_factory.mktemp("cache"))
    # coarse prefixes off: the super-hierarchies (§3.6) are compared with flat instances drawn from whole
    # roots (the flat instances' coarse prefixes, lod/points/coarse.py, draw about as few points as a node)
    reps, sel = pm.build([walker_character()], ["w"], [30], {"splat_size": 2, "coarse": False}, progress=False,
                         cache=cache,
                         instancing=Instancing([(0, h)]))
    return h, reps, sel, cache


# ---------------------------------------------------------------------------- weighted point octree
def _plate(n, rng, move=(0.0, 0.0, 0.0)):
    p0 = np.zeros((n, 3))
    p0[:, [0, 2]] = rng.uniform(0, 4.0, (n, 2))
    p1 = p0 + np.asarray(move)
    c = np.tile([0.5, 0.5, 0.5, 1.0], (n, 1))
    nr = np.tile([0.0, 1.0, 0.0], (n, 1))
    return p0, p1, c, nr


def test_point_octree_covers_every_source_at_every_interval_time():
    rng = np.random.default_rng(3)
    p0, p1, c, nr = _plate(3000, rng, move=(0.7, 0.2, -0.4))
    p1[:, 0] += 0.3 * p0[:, 2]  # shear: points move differently
    h = pi.build_point_octree(p0, p1, c, c, nr, nr, np.full(3000, 16.0 / 3000), r_stop=0.2, intervals=3)
    assert h.n_points and np.isfinite(h.pos0).all() and h.tri_order.size == 0
    inner = np.flatnonzero(h.spacing > 0)
    assert inner.size >= 5 and (h.child_count[h.child_count == 0] == 0).all()
    times = np.linspace(0.0, 1.0, 4)
    for i in inner:
        # the node's sources: those inside its start box (children cubes are disjoint)
        lo, hi = h.box0[i]
        src = np.flatnonzero(((p0 >= lo - 1e-9) & (p0 <= hi + 1e-9)).all(1))
        for j in range(3):
            s, k = h.point_start[i, j], h.point_count[i, j]
            assert k > 0
            for t in (times[j], times[j + 1]):
                q = (1 - t) * h.pos0[s:s + k].astype(float) + t * h.pos1[s:s + k].astype(float)
                ps = (1 - t) * p0[src] + t * p1[src]
                d = np.sqrt(((ps[:, None, :] - q[None]) ** 2).sum(-1)).min(1)
                # every candidate within r/2 (all sources are candidates at these densities)
                assert d.max() <= 0.5 * h.spacing[i] + 1e-4, (i, j, d.max(), h.spacing[i])


def test_point_octree_spacing_halves_and_leaves_stop_near_r_stop():
    rng = np.random.default_rng(4)
    p0, p1, c, nr = _plate(4000, rng)
    h = pi.build_point_octree(p0, p1, c, c, nr, nr, np.ones(4000), r_stop=0.1, intervals=1)
    kids = np.flatnonzero(h.parent >= 0)
    assert (h.spacing[kids] <= 0.5 * h.spacing[h.parent[kids]] + 1e-12).all()
    leaves = h.child_count == 0
    assert (h.spacing[leaves] <= pi.LEAF_SLACK * 0.1 + 1e-12).all()
    assert (h.spacing[~leaves] > pi.LEAF_SLACK * 0.1).all()
    assert (h.point_count[leaves, 0] > 0).all()  # leaves hold points (drawn by the traversal)


def test_point_octree_ignores_zero_weight_sources_and_checks_input():
    rng = np.random.default_rng(5)
    p0, p1, c, nr = _plate(500, rng)
    w = np.ones(500)
    w[:250] = 0.0
    p0[:250] += [100.0, 0.0, 0.0]  # far away, but weightless: not in the tree
    p1[:250] += [100.0, 0.0, 0.0]
    h = pi.build_point_octree(p0, p1, c, c, nr, nr, w, r_stop=0.2)
    assert h.box0[0, 1, 0] < 5.0 and h.pos0[:, 0].max() < 5.0
    e = pi.build_point_octree(p0[:0], p1[:0], c[:0], c[:0], nr[:0], nr[:0], w[:0], r_stop=0.2)
    assert e.n_points == 0 and e.n_nodes == 1
    with pytest.raises(ValueError, match="r_stop"):
        pi.build_point_octree(p0, p1, c, c, nr, nr, w, r_stop=0.0)
    bad = p0.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        pi.build_point_octree(bad, p1, c, c, nr, nr, w, r_stop=0.2)
    with pytest.raises(ValueError, match="agree"):
        pi.build_point_octree(p0, p1, c, c, nr, nr, w[:10], r_stop=0.2)


def test_traversal_kernel_draws_leaf_points_like_the_reference():
    rng = np.random.default_rng(6)
    p0, p1, c, nr = _plate(3000, rng, move=(0.0, 0.5, 0.0))
    h = pi.build_point_octree(p0, p1, c, c, nr, nr, np.ones(3000), r_stop=0.15, intervals=2)
    cam = Camera.look_at((2.0, 3.0, 9.0), (2.0, 0.0, 2.0), fov_y=50.0)
    planes = cam.frustum_planes(4 / 3)
    model = np.hstack([np.eye(3), -cam.position[:, None]])
    for splat in (0.3, 1.0, 3.0):
        a = traverse(h, 0.7, planes, viewport_scale(480, 50.0), splat, model)
        b = traverse_reference(h, 0.7, planes, viewport_scale(480, 50.0), splat, model)
        np.testing.assert_array_equal(a.point_ranges, b.point_ranges)
        np.testing.assert_array_equal(a.point_nodes, b.point_nodes)
    fine = traverse(h, 0.7, planes, viewport_scale(480, 50.0), 0.3, model)
    assert (h.child_count[fine.point_nodes] == 0).any()  # too close for inner nodes: the leaves draw


# ---------------------------------------------------------------------------- clip surface
def test_clip_surface_evaluates_the_keyframes_and_rejects_changing_topology():
    from lod.full.reps import build_keyframed_rep

    kf = build_keyframed_rep(walker_character(), key="x")
    s = pi.clip_surface(kf, 0)
    assert s is not None and s.tris.shape[1] == 3 and s.vbase.shape == (3,)
    # a sample at a corner (bary (0, 0)) is that vertex at the keyframe time
    tri = np.array([7, 7, 7])
    p, n, c = s.evaluate(np.array([0.0, 0.4, 1.2 + 0.4]), tri, np.zeros((3, 2)))
    v = int(s.tris[7, 0])
    np.testing.assert_allclose(p[0], kf.positions0[s.vbase[0] + v], atol=1e-6)
    np.testing.assert_allclose(p[1], kf.positions0[s.vbase[1] + v], atol=1e-6)
    np.testing.assert_allclose(p[2], p[1], atol=1e-6)  # looping: one period later, same place
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    assert s.area > 0 and pi.clip_surface(kf, 5) is None
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))
    from tiny_characters import tiny_keyframed

    assert pi.clip_surface(build_keyframed_rep(tiny_keyframed(), key="y"), 0) is None  # 2 -> 3 triangles


# ---------------------------------------------------------------------------- build and selection
def test_build_makes_one_super_rep_per_depth_and_hits_the_cache(built, tmp_path):
    h, reps, sel, cache = built
    keys = [r.key for r in reps]
    assert keys == ["points:w", "points:super:w:g0:d1", "points:super:w:g0:d2"]
    g = sel.instancing.groups[0]
    s1, s2 = g.supers
    assert s1.segments == s2.segments == 3 and len(s1.rep.hierarchies) == 3
    # the block's finest leaves reach the instances' root spacing; the grid's reach the block's
    r_inst = max(float(hh.spacing[0]) for hh in reps[0].hierarchies)
    assert s1.r_leaf <= pi.LEAF_SLACK * r_inst + 1e-9 and s2.r_leaf <= pi.LEAF_SLACK * s1.r_root + 1e-9
    assert s1.n_source >= 25 * 50 and s2.n_source >= 100
    # every super rep is finite and uploadable (no triangles)
    for s in (s1, s2):
        for hh in s.rep.hierarchies:
            assert np.isfinite(hh.pos0).all() and np.isfinite(hh.col1).all() and hh.tri_order.size == 0
        assert s.rep.segment_triangles(0).shape == (0, 3)
    c2 = pm_rep.HierarchyCache(cache.folder)
    reps2, _ = pm.build([walker_character()], ["w"], [30], {"splat_size": 2, "coarse": False}, progress=False, cache=c2,
                        instancing=Instancing([(0, h)]))
    assert c2.misses == 0 and c2.hits >= 3 + 2
    np.testing.assert_array_equal(reps2[1].hierarchies[1].pos1, reps[1].hierarchies[1].pos1)


def _state(h, t=0.45):
    st = h.flatten(copy=True)
    st.anim_time[:] += t
    return st


def _partition(h, plan, draws, flat):
    """Instances represented by drawn super nodes, and those left flat."""
    rep = np.zeros(h.n_instances, np.int64)
    for sup, seg, data, ids, m in draws:
        for a, k in zip(ids.tolist(), m.tolist()):
            rep[a:a + k] += 1
    return rep, flat[:h.n_instances]


def test_far_camera_draws_the_whole_tree_from_the_root_super_hierarchy(built):
    h, reps, sel, _ = built
    st = _state(h)
    cam = Camera.look_at((0.0, 200.0, 400.0), (0.0, 0.0, 0.0), fov_y=50.0, far=5000.0)
    dl = sel.select(st, cam, (640, 480))
    sb = [b for b in dl.batches if b.rep.startswith("points:super")]
    assert [b.rep for b in sb] == ["points:super:w:g0:d2"] and sb[0].n_instances == 1
    assert dl.stats["instances"] == h.n_instances and dl.stats["super_nodes"] == 1
    assert 0 < dl.stats["points"] < h.n_instances * 5 and dl.stats["triangles"] == 0
    # the node's time: the tree root's offset is 0, so u locates anim_time[0] in the period
    x = np.mod(st.anim_time[0], 1.2) / 1.2 * 3
    assert sb[0].part == int(x) and sb[0].instance_data[0, 12] == pytest.approx(x - int(x), abs=1e-6)
    flat_sel = pm.PointsSelector(reps[:1], splat_size=2)
    assert flat_sel.select(st, cam, (640, 480)).stats["points"] > 5 * dl.stats["points"]


def test_nearer_cameras_refine_nodes_and_every_visible_instance_is_drawn_once(built):
    h, reps, sel, _ = built
    st = _state(h, 0.8)
    vs = viewport_scale(480, 50.0)
    seen = set()
    for pos in ((0.0, 200.0, 400.0), (0.0, 40.0, 80.0), (6.0, 10.0, 30.0), (9.0, 2.0, 6.0)):
        cam = Camera.look_at(pos, (3.0, 0.0, -2.0), fov_y=50.0, far=5000.0)
        planes = cam.frustum_planes(640 / 480)
        draws, flat = sel.instancing.select(st, cam.position, planes, vs, 2)
        rep, fl = _partition(h, sel.instancing, draws, flat)
        assert rep.max() <= 1 and not (fl & (rep > 0)).any()  # never drawn twice
        # instances neither represented nor flat were culled: their spheres are outside the frustum
        gone = np.flatnonzero((rep == 0) & ~fl)
        if gone.size:
            sph = reps[0].keyframed.seg_sphere[:, :3].mean(0)
            cen = st.position[gone] + sph - cam.position
            d = cen @ planes[:, :3].T + planes[:, 3]
            assert (d.min(1) < 2.0).all()
        seen.add((tuple(sorted({s.depth for s, *_ in draws})), bool(fl.any())))
    assert ((2,), False) in seen  # far: the root
    assert any(1 in d for d, _ in seen)  # middle: blocks
    assert any(f for _, f in seen)  # near: instances


def test_a_moved_agent_sends_its_group_to_the_per_instance_path(built):
    h, reps, sel, _ = built
    st = _state(h)
    cam = Camera.look_at((0.0, 200.0, 400.0), (0.0, 0.0, 0.0), fov_y=50.0, far=5000.0)
    st.position[17] += [0.5, 0.0, 0.0]
    dl = sel.select(st, cam, (640, 480))
    assert not any(b.rep.startswith("points:super") for b in dl.batches)
    assert dl.stats["instances"] == h.n_instances
    st = _state(h)
    st.anim_time[5] += 0.2  # out of phase with its block
    assert not sel.instancing.check(sel.instancing.groups[0], st)
    st = _state(h)
    st.anim_time[:] += 7 * 1.2  # whole periods later: still the tree
    assert sel.instancing.check(sel.instancing.groups[0], st)


def test_groups_that_cannot_share_a_super_hierarchy_are_skipped():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))
    from tiny_characters import tiny_keyframed

    h = Hierarchy(parse_levels(LEVELS[:1]), character=0, clip=0, period=1.5)
    reps, sel = pm.build([tiny_keyframed()], ["f"], [30], {}, progress=False, instancing=Instancing([(0, h)]))
    assert len(reps) == 1 and sel.instancing.skipped and not sel.instancing.groups
    st = h.flatten(copy=True)
    dl = sel.select(st, Camera.look_at((0.0, 5.0, 30.0), (0.0, 0.0, 0.0)), (320, 240))
    assert dl.stats["instances"] == 25
    # a period that is not a whole number of clip durations: skipped too
    h2 = Hierarchy(parse_levels(LEVELS[:1]), character=0, clip=0, period=1.7)
    _, sel2 = pm.build([walker_character()], ["w"], [30], {}, progress=False, instancing=Instancing([(0, h2)]))
    assert sel2.instancing.skipped
    # no instancing: no plan
    _, sel3 = pm.build([walker_character()], ["w"], [30], {}, progress=False, instancing=None)
    assert sel3.instancing is None


def test_check_kernel_agrees_with_the_numpy_reference(built):
    h, reps, sel, _ = built
    plan, g = sel.instancing, sel.instancing.groups[0]
    rng = np.random.default_rng(7)
    answers = []
    for case in range(12):
        st = _state(h)
        i = int(rng.integers(h.n_instances))
        if case == 1:
            st.position[i, 2] += 2e-3
        elif case == 2:
            st.position[i, 0] += 5e-4  # within the tolerance
        elif case == 3:
            st.heading[i] += 2 * np.pi  # a full turn is the same heading
        elif case == 4:
            st.heading[i] += 0.01
        elif case == 5:
            st.scale[i] *= 1.01
        elif case == 6:
            st.anim_time[:] += 3 * h.period  # whole periods: the same pattern
        elif case == 7:
            st.anim_time[i] += 0.05
        elif case == 8:
            st.clip[i] += 1
        elif case == 9:
            st.character[i] += 1
        elif case == 10:
            st.position[i, 1] = np.nan
        elif case == 11:
            st.anim_time[i] = np.inf
        want = plan.check_reference(g, st)
        assert plan.check(g, st) == want, case
        answers.append(want)
    assert answers == [True, False, True, True, False, False, True, False, False, False, False, False]


def test_auto_draws_far_groups_from_the_super_hierarchies_as_mode_points_does(built, tmp_path, monkeypatch):
    """Mode auto with the point candidate at a bound of 2 px (issue 7, "far groups ... chosen as a whole"):
    the super-hierarchy nodes it draws are those of mode points at splat size 2, their agents get no
    per-instance draw, every other visible agent is drawn once, and the far view is a few points."""
    from lod.auto import build as ab
    from lod.auto import mode as am
    from lod.auto import cost_model

    h, reps, sel, cache = built
    monkeypatch.setenv(pm_rep.CACHE_ENV, str(cache.folder))  # the fixture's hierarchies
    _, auto = ab.build([walker_character()], ["w"], [30], {"poe": 2.0, "points_error": "splat", "keyframes": 3,
                                                          "adapt": False, "candidates": "triangles,points"},
                       progress=False, model=cost_model.CostModel(), instancing=Instancing([(0, h)]),
                       points_params={"splat_size": 2})
    seen_super = seen_flat = False
    for pos, t in (((0.0, 200.0, 400.0), 0.45), ((0.0, 40.0, 80.0), 0.8), ((6.0, 10.0, 30.0), 0.3),
                   ((9.0, 2.0, 6.0), 0.6)):
        st = _state(h, t)
        cam = Camera.look_at(pos, (3.0, 0.0, -2.0), fov_y=50.0, far=5000.0)
        dl, ref = auto.select(st, cam, (640, 480)), sel.select(st, cam, (640, 480))
        sup = [b for b in dl.batches if b.rep.startswith("points:super")]
        sup_ref = [b for b in ref.batches if b.rep.startswith("points:super")]
        assert [(b.rep, b.part, tuple(b.instance_ids), b.points) for b in sup] == \
            [(b.rep, b.part, tuple(b.instance_ids), b.points) for b in sup_ref]
        drawn = np.zeros(h.n_instances, np.int64)
        for b in sup:  # a node's agents: its first agent id and the instances it stands for
            m = h.instances_per_node(int(b.rep.rsplit(":d", 1)[1]))
            for a in b.instance_ids.tolist():
                drawn[a:a + m] += 1
        for b in dl.batches:
            if not b.rep.startswith("points:super"):
                np.add.at(drawn, np.asarray(b.instance_ids, np.int64), 1)
        assert drawn.max() <= 1
        # every agent mode points draws (as a node member or on its own) auto draws too, and no other
        ref_drawn = np.zeros(h.n_instances, np.int64)
        for b in ref.batches:
            if b.rep.startswith("points:super"):
                m = h.instances_per_node(int(b.rep.rsplit(":d", 1)[1]))
                for a in b.instance_ids.tolist():
                    ref_drawn[a:a + m] += 1
            else:
                np.add.at(ref_drawn, np.asarray(b.instance_ids, np.int64), 1)
        np.testing.assert_array_equal(drawn, ref_drawn)
        n_sup = int(sum(b.represented for b in sup))
        assert dl.stats["auto"]["options"].get("points:super", 0) == n_sup
        seen_super |= n_sup > 0
        seen_flat |= n_sup < drawn.sum()
        if pos[1] == 200.0:  # far: the whole tree from the root node, a few points
            assert n_sup == h.n_instances and dl.stats.get("super_nodes") == 1
            assert 0 < dl.stats["points"] < h.n_instances * 5
            # every plan draws the same list then: one plan, whose measurements all of them share
            assert dl.stats["auto"]["plan"] == "points" and len(set(dl.stats["auto"]["plans_ms"].values())) == 1
    assert seen_super and seen_flat
