"""Geomorphs between two cluster cuts (lod/clusters/morph.py): the collapse chains, the
union of two cuts (kernel against its reference), exact ends (t = 0 draws cut A's
triangles, t = 1 cut B's), no crack at any t, and the keyframed selector using them."""
import numpy as np
import pytest

from lod.clusters import cut as cluster_cut
from lod.clusters import dag as cluster_dag
from lod.clusters import mode as clusters_mode
from lod.clusters import morph as cm
from lod.temporal import selection as ks
from lod.view import Camera
from sim.procedural import humanoid
from sim.skinning import skin
from sim.state import CrowdState


@pytest.fixture(scope="module")
def human():
    c = humanoid(2500, 0)
    return c, cluster_dag.build_cluster_hierarchy(c, ["walk"], samples=16, s=60, progress=False)


def _models(n, rng):
    M = np.tile(np.eye(4), (n, 1, 1))
    M[:, 0, 3] = rng.uniform(-1, 1, n)
    M[:, 2, 3] = -rng.uniform(1.5, 40.0, n)
    return M


def _cut_pairs(h, n, seed, cull=False):
    """Cuts A and B of n instances at random distances and PoE (independent per cut), optionally
    frustum-culled (a camera looking sideways clips instances)."""
    rng = np.random.default_rng(seed)
    M = _models(n, rng)
    cuts = []
    for _ in range(2):
        poe = float(rng.choice([0.3, 1.0, 3.0, 10.0]))
        off, cl = cluster_cut.cut(h, M, [0, 1, 0], 600.0, poe)
        if cull:
            cam = Camera.look_at((0.0, 1.0, 0.0), (rng.uniform(-8, 8), 1.0, -20.0), fov_y=12.0)
            rows = M[:, :3, :].copy()
            rows[:, :, 3] -= cam.position  # the planes are camera-relative
            off, cl = clusters_mode.cull_clusters(np.ascontiguousarray(h.sphere, np.float64), rows, off, cl,
                                                  cam.frustum_planes(4 / 3))
        cuts.append((off, cl))
        M[:, 2, 3] *= rng.uniform(0.5, 2.0, n)  # the second keyframe sees them at other distances
    return cuts


def _tri_set(T, tol=1e-9):
    """Canonical multiset of non-degenerate triangles (corner coordinates rounded)."""
    out = []
    for t in np.round(np.asarray(T, np.float64) / tol).astype(np.int64):
        if np.array_equal(t[0], t[1]) or np.array_equal(t[1], t[2]) or np.array_equal(t[0], t[2]):
            continue
        k = min(range(3), key=lambda i: tuple(t[i]))
        out.append(tuple(map(tuple, np.roll(t, -k, axis=0))))
    return sorted(out)


def test_collapse_chains(human):
    """A vertex is removed once; its target survives that cluster and is removed strictly
    higher; every chain ends in a vertex the root draws."""
    _, h = human
    nxt, rem = cm.collapse_table(h)
    V = h.n_vertices
    moved = np.flatnonzero(nxt != np.arange(V))
    assert moved.size > 0.8 * V  # nearly every vertex collapses somewhere below the root
    assert np.all(rem[moved] < cm.NEVER_REMOVED) and np.all(rem[nxt[moved]] > rem[moved])
    ends = cm.chain_targets(nxt, rem, np.arange(V), int(h.height.max()))
    root = np.unique(h.cluster_triangles(int(h.roots[0])))
    used = np.unique(h.indices[: h.tri_start[h.n_leaves]])  # vertices the leaves draw
    assert np.isin(ends[used], root).all()
    # height below every removal: nothing moves
    assert np.array_equal(cm.chain_targets(nxt, rem, np.arange(V), -1), np.arange(V))


def test_corrupt_chain_rejected(human):
    _, h = human
    bad = cluster_dag.ClusterHierarchy(**{k: getattr(h, k) for k in (
        "indices", "tri_start", "children", "parent", "roots", "height", "leaf_lo", "leaf_hi", "error", "sphere",
        "aabb", "deformation", "n_vertices", "n_triangles")})
    bad.morph_ptr = h.morph_ptr.copy()
    bad.morph_vertex = h.morph_vertex.copy()
    bad.morph_target = h.morph_vertex.copy()[::-1].copy()  # targets that point back down the tree
    with pytest.raises(ValueError, match="geomorph"):
        cm.collapse_table(bad)


@pytest.mark.parametrize("cull", [False, True])
def test_union_kernel_equals_reference(human, cull):
    _, h = human
    partial = morphs = 0
    for seed in range(4):
        (oa, ca), (ob, cb) = _cut_pairs(h, 40, seed, cull)
        got = cm.morph_union(h, oa, ca, ob, cb)
        ref = cm.morph_union_numpy(h, oa, ca, ob, cb)
        for g, r in zip(got, ref):
            np.testing.assert_array_equal(g, r)
        if not cull:
            assert got[4].all()  # whole cuts always cover each other
        else:
            partial += int((~got[4]).sum())
            morphs += int((got[2] >= 0).sum())
    if cull:
        assert partial > 0 and morphs > 0  # the clipped cases occur, and others still morph


def test_union_covers_every_leaf_once_with_the_finer_cluster(human):
    _, h = human
    (oa, ca), (ob, cb) = _cut_pairs(h, 30, 7)
    off, cl, hs, sd, ok = cm.morph_union(h, oa, ca, ob, cb)
    assert ok.all()
    for i in range(30):
        e = slice(off[i], off[i + 1])
        cov = np.zeros(h.n_leaves, np.int64)
        for c in cl[e]:
            cov[h.leaf_lo[c]:h.leaf_hi[c]] += 1
        assert np.all(cov == 1)
        A, B = set(ca[oa[i]:oa[i + 1]].tolist()), set(cb[ob[i]:ob[i + 1]].tolist())
        for c, hh, s in zip(cl[e], hs[e], sd[e]):
            if hh < 0:
                assert c in A and c in B  # unmoved: both cuts draw it
                continue
            assert c in (A if s == cm.SIDE_A else B)
            other = B if s == cm.SIDE_A else A
            anc = [a for a in other if h.leaf_lo[a] <= h.leaf_lo[c] and h.leaf_hi[c] <= h.leaf_hi[a]]
            assert len(anc) == 1 and h.height[anc[0]] == hh > h.height[c]


@pytest.mark.parametrize("pose_time", [None, 0.37])
def test_ends_are_the_two_cuts_exactly(human, pose_time):
    """t = 0 draws exactly cut A's triangles, t = 1 exactly cut B's (as position triples:
    the morph moves vertices onto their collapse targets, leaving degenerate triangles)."""
    c, h = human
    X = np.asarray(c.mesh.positions, np.float64) if pose_time is None else \
        skin(c.mesh, c.skeleton.skinning_matrices(*c.clips["walk"].sample(c.skeleton, pose_time)))[0]
    (oa, ca), (ob, cb) = _cut_pairs(h, 12, 3)
    off, cl, hs, sd, ok = cm.morph_union(h, oa, ca, ob, cb)
    n_morph = 0
    for i in range(12):
        e = slice(off[i], off[i + 1])
        n_morph += int((hs[e] >= 0).sum())
        for t, (o, cc) in ((0.0, (oa, ca)), (1.0, (ob, cb))):
            P = cm.morphed_triangle_positions(h, X, cl[e], hs[e], cm.entry_weights(sd[e], hs[e], t))
            R = X[h.cut_triangles(cc[o[i]:o[i + 1]]).astype(np.int64)]
            assert _tri_set(P) == _tri_set(R)
    assert n_morph > 0  # the pairs do differ


def test_no_crack_at_any_weight(human):
    """Every vertex drawn by two entries of one union lands on the same position at every t:
    neighbouring regions morphing towards different ancestors (or not at all) share their border."""
    c, h = human
    X = skin(c.mesh, c.skeleton.skinning_matrices(*c.clips["walk"].sample(c.skeleton, 0.61)))[0]
    nxt, rem = cm.collapse_table(h)
    (oa, ca), (ob, cb) = _cut_pairs(h, 20, 11)
    off, cl, hs, sd, _ = cm.morph_union(h, oa, ca, ob, cb)
    checked = 0
    for t in (0.25, 0.5, 0.9):
        for i in range(20):
            e = slice(off[i], off[i + 1])
            w = cm.entry_weights(sd[e], hs[e], t)
            pos: dict = {}
            for cc, hh, ww in zip(cl[e], hs[e], w):
                v = np.unique(h.cluster_triangles(int(cc))).astype(np.int64)
                x = cm.chain_targets(nxt, rem, v, int(hh)) if hh >= 0 else v
                p = (1 - ww) * X[v] + ww * X[x]
                for vi, pi in zip(v.tolist(), p):
                    if vi in pos:
                        np.testing.assert_allclose(pi, pos[vi], atol=1e-12)
                        checked += 1
                    pos[vi] = pi
    assert checked > 100


def test_partly_culled_coarse_cluster_is_not_morphable(human):
    _, h = human
    root = int(h.roots[0])
    kids = [int(k) for k in h.children[root]]
    off = np.array([0, 1], np.int64)
    got = cm.morph_union(h, off, np.array([root], np.int32), off, np.array([kids[0]], np.int32))
    assert not got[4][0]
    got = cm.morph_union(h, off, np.array([root], np.int32), np.array([0, 2]), np.array(kids, np.int32))
    assert got[4][0] and got[2].tolist() == [int(h.height[root])] * 2 and got[3].tolist() == [cm.SIDE_B] * 2


def test_morph_batch_weights_and_counts(human):
    _, h = human
    (oa, ca), (ob, cb) = _cut_pairs(h, 10, 5)
    k = 10
    data = np.zeros((k, 16), np.float32)
    ids = np.arange(k, dtype=np.int32)
    a = clusters_mode.ClusterDrawBatch("clusters:h", 0, ids, data, offsets=oa, clusters=ca)
    b = clusters_mode.ClusterDrawBatch("clusters:h", 0, ids, data, offsets=ob, clusters=cb)
    mb, ok = cm.morph_batch(h, a, b, 0.25)
    assert ok.all() and mb.fade is None
    w, hs = mb.morph_weight, mb.morph_height
    assert set(np.unique(w[hs >= 0]).tolist()) <= {0.25, 0.75} and np.all(w[hs < 0] == 0)
    assert mb.triangles == int(np.diff(h.tri_start)[mb.clusters].sum())


# ---------------------------------------------------------------------------- keyframed selection
def _crowd(n=24, seed=0):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:] = np.c_[rng.uniform(-6, 6, n), np.zeros(n), rng.uniform(-60, -2, n)]
    st.heading[:] = rng.uniform(0, 6.28, n)
    st.scale[:] = 1.0
    st.anim_time[:] = rng.uniform(0, 1, n)
    st.anim_rate[:] = 1.0
    return st


@pytest.fixture(scope="module")
def clusters_selector(human):
    c, _ = human
    reps, sel = clusters_mode.build([c], ["h"], [30], {"poe": 1.0}, cache=False)
    return reps, sel


@pytest.mark.parametrize("geomorph", [True, False])
def test_keyframed_cluster_transitions_geomorph(clusters_selector, geomorph):
    """Between keyframes, instances whose cut changed are drawn once, geomorphed (no fade),
    and every visible instance is drawn exactly once; with geomorph off they fade."""
    reps, sel = clusters_selector
    w = ks.KeyframedSelector(sel, n=4, mode="current", geomorph=geomorph)
    st = _crowd()
    seen_morph = 0
    for f in range(12):
        cam = Camera.from_yaw_pitch(np.array([0.0, 1.7, 8.0 - 2.5 * f]), 0.0, -0.05, 50.0, 0.1, 500.0)
        dl = w.select(st, cam, (320, 240))
        ids = []
        morph_ids = []
        for b in dl.batches:
            if getattr(b, "morph_height", None) is not None:
                assert b.fade is None and b.morph_height.shape == b.clusters.shape == b.morph_weight.shape
                assert np.all((b.morph_weight >= 0) & (b.morph_weight <= 1))
                morph_ids.append(np.asarray(b.instance_ids))
            if b.fade is None:
                ids.append(np.asarray(b.instance_ids))
        ids = np.concatenate(ids) if ids else np.zeros(0)
        assert np.unique(ids).size == ids.size  # nobody drawn twice unfaded
        n_m = sum(x.size for x in morph_ids)
        assert dl.stats["geomorphs"] == n_m
        seen_morph += n_m
        if geomorph:
            assert not any(b.fade is not None for b in dl.batches if b.rep.startswith("clusters:"))
        st.anim_time[:] += 1 / 30
    assert (seen_morph > 0) == geomorph


def test_take_rows_keeps_morph_entries_aligned(human):
    _, h = human
    (oa, ca), (ob, cb) = _cut_pairs(h, 8, 2)
    data = np.zeros((8, 16), np.float32)
    ids = np.arange(8, dtype=np.int32)
    a = clusters_mode.ClusterDrawBatch("clusters:h", 0, ids, data, offsets=oa, clusters=ca)
    b = clusters_mode.ClusterDrawBatch("clusters:h", 0, ids, data, offsets=ob, clusters=cb)
    mb, _ = cm.morph_batch(h, a, b, 0.4)
    rows = np.array([5, 1, 6])
    sub = ks.take_rows(mb, rows, ids[rows], data[rows])
    for j, r in enumerate(rows):
        e, f = slice(mb.offsets[r], mb.offsets[r + 1]), slice(sub.offsets[j], sub.offsets[j + 1])
        np.testing.assert_array_equal(sub.clusters[f], mb.clusters[e])
        np.testing.assert_array_equal(sub.morph_height[f], mb.morph_height[e])
        np.testing.assert_array_equal(sub.morph_weight[f], mb.morph_weight[e])


def test_hierarchy_too_tall_for_the_shader_is_not_morphed(human):
    """A hierarchy taller than the shader's chain bound (MAX_CHAIN) falls back to fades."""
    import copy

    _, h = human
    tall = copy.copy(h)
    tall.height = h.height.copy()
    tall.height[-1] = cm.MAX_CHAIN
    (oa, ca), (ob, cb) = _cut_pairs(h, 4, 1)
    a = clusters_mode.ClusterDrawBatch("clusters:h", 0, np.arange(4, dtype=np.int32), np.zeros((4, 16), np.float32),
                                       offsets=oa, clusters=ca)
    b = clusters_mode.ClusterDrawBatch("clusters:h", 0, np.arange(4, dtype=np.int32), np.zeros((4, 16), np.float32),
                                       offsets=ob, clusters=cb)
    assert cm.morph_batch(h, a, b, 0.5)[0] is not None
    mb, ok = cm.morph_batch(tall, a, b, 0.5)
    assert mb is None and not ok.any()
