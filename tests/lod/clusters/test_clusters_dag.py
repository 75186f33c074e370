"""VDR-AM §4.3 cluster hierarchy and §5.1 cut: coverage, cracks, errors, bounds."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))
from tiny_characters import tiny_skinned  # noqa: E402

from lod.clusters import dag as cluster_dag  # noqa: E402
from lod.clusters import cut as cluster_cut
from lod.view import Camera  # noqa: E402
from sim.character import SkinnedCharacter  # noqa: E402
from sim.procedural import humanoid, quadruped  # noqa: E402


@pytest.fixture(scope="module")
def human():
    c = humanoid(2500, 0)
    return c, cluster_dag.build_cluster_hierarchy(c, ["walk"], samples=16, s=60, progress=False)


@pytest.fixture(scope="module")
def octree(human):
    c, _ = human
    return cluster_dag.build_cluster_hierarchy(c, ["walk"], samples=16, s=60, clustering_method="octree",
                                               progress=False)


def _edges(t):
    t = np.asarray(t, np.int64)
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), 1)
    u, cnt = np.unique(e, axis=0, return_counts=True)
    return u, cnt


def _rows(t):
    return {tuple(sorted(r)) for r in np.asarray(t, np.int64).tolist()}


def _instances(n, rng, spread=30.0):
    M = np.tile(np.eye(4), (n, 1, 1))
    ang = rng.uniform(0, 2 * np.pi, n)
    s = rng.uniform(0.8, 1.2, n)
    M[:, 0, 0] = M[:, 2, 2] = np.cos(ang) * s
    M[:, 0, 2] = np.sin(ang) * s
    M[:, 2, 0] = -np.sin(ang) * s
    M[:, 1, 1] = s
    M[:, 0, 3] = rng.uniform(-spread, spread, n)
    M[:, 2, 3] = rng.uniform(-spread, spread, n)
    return M


def test_structure(human):
    c, h = human
    cluster_dag.validate(h)
    N, L = h.n_clusters, h.n_leaves
    assert h.roots.tolist() == [N - 1]
    assert np.all(h.children[:L] == -1) and np.all(h.children[L:] >= 0)
    assert np.all(h.children[L:] < np.arange(L, N)[:, None])  # children before parents
    for i in range(L, N):
        a, b = h.children[i]
        assert h.parent[a] == i and h.parent[b] == i
        assert h.leaf_lo[i] == min(h.leaf_lo[a], h.leaf_lo[b]) and h.leaf_hi[i] == max(h.leaf_hi[a], h.leaf_hi[b])
        assert h.leaf_hi[i] - h.leaf_lo[i] == (h.leaf_hi[a] - h.leaf_lo[a]) + (h.leaf_hi[b] - h.leaf_lo[b])
    assert h.leaf_lo[N - 1] == 0 and h.leaf_hi[N - 1] == L
    assert h.triangle_counts()[:L].max() <= 60
    assert h.indices.dtype == np.uint16 and int(h.indices.max()) < c.mesh.n_vertices
    # the leaves are the original triangles, each exactly once
    leaves = np.concatenate([h.cluster_triangles(i) for i in range(L)]).astype(np.int64)
    assert leaves.shape[0] == c.mesh.n_triangles
    assert _rows(leaves) == _rows(c.mesh.indices)
    # every level simplifies: the whole hierarchy holds well under 3x the original triangles
    assert h.indices.shape[0] < 3 * c.mesh.n_triangles
    assert 5 <= len(h.representatives) <= 12


def test_errors_are_monotone_and_spheres_hold_every_sampled_pose(human):
    c, h = human
    L = h.n_leaves
    assert np.all(h.error[:L] == 0) and np.all(h.error[L:] >= 0) and np.all(np.isfinite(h.error))
    for i in range(L, h.n_clusters):
        assert h.error[i] >= h.error[h.children[i]].max()
    assert h.error[h.roots[0]] > 0
    clip = c.clip("walk")
    X = cluster_dag.skin_poses(c.mesh, clip.skinning_matrices(c.skeleton, h.pose_times))
    for i in range(h.n_clusters):
        v = np.unique(h.cluster_triangles(i).astype(np.int64))
        d = np.linalg.norm(X[:, v] - h.sphere[i, :3].astype(np.float64), axis=2)
        assert d.max() <= h.sphere[i, 3] * (1 + 1e-6) + 1e-7
        assert np.all(X[:, v] >= h.aabb[i, 0] - 1e-6) and np.all(X[:, v] <= h.aabb[i, 1] + 1e-6)
    # parents' bounds hold their children's (a bounding volume hierarchy)
    for i in range(L, h.n_clusters):
        for ch in h.children[i]:
            assert np.all(h.aabb[ch, 0] >= h.aabb[i, 0] - 1e-6) and np.all(h.aabb[ch, 1] <= h.aabb[i, 1] + 1e-6)


def _check_cut(h, c, cut):
    """The cut covers every leaf once and, the original mesh being closed, has no open edge."""
    cover = np.zeros(h.n_leaves, np.int64)
    for i in cut:
        cover[h.leaf_lo[i]:h.leaf_hi[i]] += 1
    assert np.all(cover == 1)
    _, cnt = _edges(h.cut_triangles(cut))
    # no boundary edge (used once) and no odd use: each cluster meets its neighbours along identical edges.
    # (Count 4 can occur where two simplified clusters both link the same two locked border vertices:
    # a pinch of a watertight surface, not a crack.)
    assert not np.any(cnt == 1), "the cut has open (cracked) edges"
    assert np.all(cnt % 2 == 0), "the cut has edges used an odd number of times"


def test_original_mesh_is_closed(human):
    c, _ = human
    _, cnt = _edges(c.mesh.indices)
    assert np.all(cnt == 2)


def test_poe_zero_is_the_original_mesh(human):
    c, h = human
    M = _instances(5, np.random.default_rng(0))
    off, cl = cluster_cut.cut(h, M, [0, 1.6, 0], cluster_cut.viewport_scale(720, 50), 0.0)
    for i in range(5):
        cut = cl[off[i]:off[i + 1]]
        assert sorted(cut.tolist()) == list(range(h.n_leaves))
        assert _rows(h.cut_triangles(cut)) == _rows(c.mesh.indices)


@pytest.fixture(scope="module")
def big_leaves(human):
    """The same humanoid with leaves of up to 800 triangles (``[lod] leaf_triangles``: few, large leaves)."""
    c, _ = human
    return cluster_dag.build_cluster_hierarchy(c, ["walk"], samples=16, s=800, progress=False)


@pytest.mark.parametrize("poe", [0.25, 0.5, 1.0, 2.0, 8.0, 1e9])
def test_every_cut_covers_once_without_cracks(human, octree, big_leaves, poe):
    c, h = human
    rng = np.random.default_rng(int(poe * 7) % 1000)
    M = _instances(12, rng, spread=12.0)
    assert big_leaves.n_leaves < h.n_leaves // 2
    for hh in (h, octree, big_leaves):
        off, cl = cluster_cut.cut(hh, M, [0, 1.6, 0], cluster_cut.viewport_scale(720, 50), poe)
        for i in range(12):
            _check_cut(hh, c, cl[off[i]:off[i + 1]])
    if poe >= 1e9:
        assert np.all(cl == h.roots[0]) or np.all(np.diff(off) >= 1)


def test_numba_cut_matches_numpy_reference(human):
    c, h = human
    rng = np.random.default_rng(3)
    M = _instances(200, rng, spread=25.0)
    eye = np.array([0.0, 1.7, -3.0])
    for poe in (0.0, 0.5, 1.0, 4.0):
        scale = cluster_cut.viewport_scale(720, 60)
        off, cl = cluster_cut.cut(h, M, eye, scale, poe)
        ref = cluster_cut.cut_numpy(h, M, eye, scale, poe)
        assert off[-1] == sum(len(r) for r in ref)
        for i in range(200):
            assert np.array_equal(cl[off[i]:off[i + 1]], ref[i])
        tc = cluster_cut.cut_triangle_count(h, off, cl)
        assert tc.tolist() == [int(h.triangle_counts()[r].sum()) for r in ref]


def test_cut_refines_near_and_coarsens_far(human):
    c, h = human
    M = np.tile(np.eye(4), (3, 1, 1))
    M[:, 2, 3] = [3.0, 30.0, 3000.0]
    cam = Camera.look_at([0, 1.0, 0], [0, 1.0, 10])
    off, cl = cluster_cut.cut_for_camera(h, M, cam, (1280, 720), 0.5)
    tris = cluster_cut.cut_triangle_count(h, off, cl)
    assert tris[0] > tris[1] > tris[2]
    assert cl[off[2]:off[3]].tolist() == [h.roots[0]]
    # camera inside a cluster's sphere always refines it (here: inside the root's)
    off, cl = cluster_cut.cut(h, np.eye(4)[None], [0, 1.0, 0], 1000.0, 1e12)
    assert h.roots[0] not in cl.tolist()


def test_cut_degenerate_inputs(human):
    c, h = human
    off, cl = cluster_cut.cut(h, np.zeros((0, 4, 4)), [0, 0, 0], 100.0, 1.0)
    assert off.tolist() == [0] and cl.size == 0
    with pytest.raises(ValueError, match="poe"):
        cluster_cut.cut(h, np.eye(4)[None], [0, 0, 0], 100.0, -1.0)
    with pytest.raises(ValueError, match="viewport_scale"):
        cluster_cut.cut(h, np.eye(4)[None], [0, 0, 0], 0.0, 1.0)
    with pytest.raises(ValueError, match="finite"):
        cluster_cut.cut(h, np.full((1, 4, 4), np.nan), [0, 0, 0], 100.0, 1.0)
    with pytest.raises(ValueError, match="singular"):
        cluster_cut.cut(h, np.zeros((2, 4, 4)), [0, 0, 0], 100.0, 1.0)
    with pytest.raises(ValueError, match="model matrices"):
        cluster_cut.cut(h, np.eye(3)[None], [0, 0, 0], 100.0, 1.0)


def test_error_aware_draws_fewer_triangles_than_octree(human, octree):
    c, h = human
    M = np.tile(np.eye(4), (4, 1, 1))
    M[:, 2, 3] = [4.0, 8.0, 16.0, 32.0]
    cam = Camera.look_at([0, 1.0, 0], [0, 1.0, 10])
    t_ea = cluster_cut.cut_triangle_count(h, *cluster_cut.cut_for_camera(h, M, cam, (1280, 720), 0.5)).sum()
    t_oc = cluster_cut.cut_triangle_count(octree, *cluster_cut.cut_for_camera(octree, M, cam, (1280, 720), 0.5)).sum()
    assert t_ea < t_oc


def test_save_load_roundtrip_and_corrupt_file(human, tmp_path):
    c, h = human
    p = tmp_path / "h.npz"
    h.save(p)
    g = cluster_dag.ClusterHierarchy.load(p)
    for k, a in h.arrays().items():
        assert np.array_equal(a, getattr(g, k)) and a.dtype == getattr(g, k).dtype
    assert g.params == h.params and g.pose_clips == h.pose_clips
    p.write_bytes(p.read_bytes()[:200])
    with pytest.raises(ValueError, match="h.npz"):
        cluster_dag.ClusterHierarchy.load(p)


def test_bytes_per_triangle_is_compact(human):
    c, h = human
    assert cluster_dag.bytes_per_triangle(h, c.mesh) < 40.0
    pv = cluster_dag.pack_vertices(c.mesh)
    assert np.all(pv["weights"].astype(int).sum(1) == 255)
    assert pv["joints"].dtype == np.uint8 and pv["normals"].dtype == np.int16


def test_other_characters_and_bad_input():
    h = cluster_dag.build_cluster_hierarchy(tiny_skinned(), samples=8, s=20, progress=False)
    cluster_dag.validate(h)
    assert h.roots.size == 1 and h.n_leaves >= 2
    q = quadruped(1500, 1)
    hq = cluster_dag.build_cluster_hierarchy(q, ["gallop"], samples=12, progress=False)
    off, cl = cluster_cut.cut(hq, np.eye(4)[None], [0, 1, 6], 600.0, 1.0)
    _check_cut(hq, q, cl)
    bare = SkinnedCharacter("bare", q.mesh.__class__(q.mesh.positions, q.mesh.indices), q.skeleton, q.clips)
    with pytest.raises(ValueError, match="bare"):
        cluster_dag.build_cluster_hierarchy(bare)
    with pytest.raises(ValueError, match="pose_indices"):
        cluster_dag.build_cluster_hierarchy(q, ["gallop"], samples=4, pose_indices=[7])
    with pytest.raises(KeyError, match="trot"):
        cluster_dag.build_cluster_hierarchy(q, ["trot"])
    with pytest.raises(ValueError, match="clustering_method"):
        cluster_dag.build_cluster_hierarchy(q, clustering_method="kmeans")


def test_empty_mesh_and_character_without_clips():
    t = tiny_skinned()
    m = t.mesh
    empty = SkinnedCharacter("empty", m.__class__(m.positions, np.zeros((0, 3), np.uint32), joints=m.joints,
                                                  weights=m.weights), t.skeleton, t.clips)
    h = cluster_dag.build_cluster_hierarchy(empty, progress=False)
    assert h.n_clusters == 0 and h.indices.shape == (0, 3)
    off, cl = cluster_cut.cut(h, np.eye(4)[None], [0, 0, 5], 500.0, 1.0)
    assert off.tolist() == [0, 0] and cl.size == 0
    still = SkinnedCharacter("still", m, t.skeleton, {})
    h = cluster_dag.build_cluster_hierarchy(still, s=30, progress=False)  # rest pose only
    cluster_dag.validate(h)
    assert h.representatives.tolist() == [0] and h.roots.size == 1
    off, cl = cluster_cut.cut(h, np.eye(4)[None], [0, 1, 20], 500.0, 0.0)
    assert sorted(cl.tolist()) == list(range(h.n_leaves))


def test_geomorph_targets(human):
    """Every vertex an internal cluster removed came from its children's geometry, is gone from the
    cluster and collapsed onto a vertex the cluster still draws; leaves carry none; they survive save/load."""
    _, h = human
    assert h.morph_ptr.shape == (h.n_clusters + 1,) and h.morph_ptr[-1] == h.morph_vertex.size
    n_morph = 0
    for i in range(h.n_clusters):
        v = h.morph_vertex[h.morph_ptr[i]:h.morph_ptr[i + 1]]
        t = h.morph_target[h.morph_ptr[i]:h.morph_ptr[i + 1]]
        if h.children[i, 0] < 0:
            assert v.size == 0
            continue
        kids = np.unique(np.concatenate([h.cluster_triangles(int(c)).reshape(-1) for c in h.children[i]]))
        own = np.unique(h.cluster_triangles(i))
        assert np.isin(v, kids).all() and not np.isin(v, own).any()
        assert np.isin(t, own).all()
        n_morph += v.size
    assert n_morph > 0


def test_geomorph_targets_saved(human, tmp_path):
    _, h = human
    h.save(tmp_path / "h.npz")
    g = cluster_dag.ClusterHierarchy.load(tmp_path / "h.npz")
    assert np.array_equal(g.morph_ptr, h.morph_ptr) and np.array_equal(g.morph_target, h.morph_target)


def test_errors_are_measured_against_the_original_surface(human):
    """Each internal cluster's error bounds the distance of the original vertices of its region to its
    simplified triangles (forward Hausdorff, exact) in the quadric poses, and the errors are not
    compounded: they stay within a small factor of that distance for most clusters."""
    from lod.simplify import distance as qem_distance
    c, h = human
    from lod.clusters import poses as lp
    mats, _, _ = lp.representative_poses(c, ["walk"], 16, h.params["d_fraction"])
    X = cluster_dag.skin_poses(c.mesh, mats[h.representatives])
    L = h.n_leaves
    ratios = []
    for i in range(L, h.n_clusters, 7):
        orig = h.cut_triangles(np.arange(h.leaf_lo[i], h.leaf_hi[i]))
        d = float(qem_distance.vertex_surface_distance(X, orig, h.cluster_triangles(i)).max())
        assert h.error[i] >= d - 1e-5, (i, h.error[i], d)
        if d > 1e-4:
            ratios.append(h.error[i] / d)
    assert np.median(ratios) < 1.5


class _Stream:
    """A text stream that says whether it is a terminal (tqdm writes to it)."""

    def __init__(self, tty: bool):
        self.tty, self.text = tty, ""

    def isatty(self):
        return self.tty

    def write(self, s):
        self.text += s

    def flush(self):
        pass


@pytest.mark.parametrize("tty", [True, False])
def test_the_build_bar_is_cleared_when_the_build_ends_and_absent_off_a_terminal(human, monkeypatch, tty):
    """On a terminal the bar shows and is cleared at the end: the line after it starts clean (issue 48: a bar left
    behind at "3% | 4/129" with the next line's text over its start); off a terminal (a pipe, a log) nothing."""
    c, _ = human
    err = _Stream(tty)
    monkeypatch.setattr(sys, "stderr", err)
    cluster_dag.build_cluster_hierarchy(c, ["walk"], samples=4, s=60, progress=True)
    if not tty:
        assert err.text == ""
        return
    assert f"clusters {c.name}" in err.text
    last = err.text.rsplit("\r", 2)  # the close: "\r" + blanks over the bar + "\r"
    assert err.text.endswith("\r") and last[-2].strip() == "" and len(last[-2]) > 0
