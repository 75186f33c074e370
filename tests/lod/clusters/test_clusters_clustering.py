"""VDR-AM §4.2: deformation levels, error-aware clustering, octree baseline."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))
from tiny_characters import tiny_skinned  # noqa: E402

from lod.clusters import poses  # noqa: E402
from lod.clusters import clustering
from lod.clusters import deformation
from lod.clusters.dag import skin_poses  # noqa: E402
from sim.procedural import humanoid  # noqa: E402


def test_least_common_ancestor():
    parents = np.array([-1, 0, 1, 1, 0, -1])
    assert deformation.least_common_ancestor(parents, 2, 3) == 1
    assert deformation.least_common_ancestor(parents, 2, 4) == 0
    assert deformation.least_common_ancestor(parents, 3, 3) == 3
    assert deformation.least_common_ancestor(parents, 2, 5) == -1
    lca = deformation.vertex_lca(parents, np.array([[2, 3, 0, 0], [4, 0, 0, 0], [2, 5, 0, 0]]),
                                 np.array([[0.5, 0.5, 0, 0], [1.0, 0, 0, 0], [0.5, 0.5, 0, 0]]))
    assert lca.tolist() == [1, 4, -1]


def test_rigid_vertices_have_zero_level_and_bent_ones_do_not():
    c = tiny_skinned()
    clip = c.clip("bend")
    mats = clip.skinning_matrices(c.skeleton, poses.sample_times(clip, 16))
    X = skin_poses(c.mesh, mats)
    lv = deformation.character_deformation(c, mats, X)
    assert lv.shape == (c.mesh.n_vertices,) and np.all(np.isfinite(lv)) and np.all(lv >= 0)
    w = np.asarray(c.mesh.weights)
    single = (w > 1e-4).sum(1) == 1
    assert single.any() and (~single).any()
    np.testing.assert_allclose(lv[single], 0.0, atol=1e-9)  # rigid in its own bone's frame
    assert lv[~single].max() > 1e-3


def test_deformation_single_pose_is_zero():
    c = tiny_skinned()
    clip = c.clip("bend")
    mats = clip.skinning_matrices(c.skeleton, np.array([0.3]))
    lv = deformation.character_deformation(c, mats, skin_poses(c.mesh, mats))
    np.testing.assert_allclose(lv, 0.0, atol=1e-9)


@pytest.fixture(scope="module")
def human():
    c = humanoid(3000, 0)
    clip = c.clip("walk")
    mats = clip.skinning_matrices(c.skeleton, poses.sample_times(clip, 12))
    lv = deformation.character_deformation(c, mats, skin_poses(c.mesh, mats))
    return c, lv


def test_growth_kernel_matches_reference_and_respects_tolerance(human):
    c, lv = human
    t = np.asarray(c.mesh.indices, np.int64)
    ptr, nbr = clustering.triangle_adjacency(t, c.mesh.n_vertices)
    tl = clustering.triangle_levels(t, lv)
    tol = 0.1 * tl.max()
    order = np.argsort(tl, kind="stable")
    a = clustering._grow(ptr, nbr, tl, tol, order)
    b = clustering.grow_clusters_numpy(ptr, nbr, tl, tol, order)
    assert np.array_equal(a, b)
    for k in range(a.max() + 1):
        m = tl[a == k]
        assert m.max() - m.min() <= tol + 1e-12


def test_error_aware_and_octree_clusters_are_partitions_of_at_most_s(human):
    c, lv = human
    for labels in (clustering.error_aware_clusters(c.mesh.positions, c.mesh.indices, lv, s=100),
                   clustering.octree_clusters(c.mesh.positions, c.mesh.indices, s=100)):
        assert labels.shape == (c.mesh.n_triangles,)
        sizes = np.bincount(labels)
        assert sizes.min() >= 1 and sizes.max() <= 100
        assert np.array_equal(np.unique(labels), np.arange(sizes.size))


def test_error_aware_clusters_are_more_uniform_in_level_than_octree(human):
    c, lv = human
    tl = clustering.triangle_levels(c.mesh.indices, lv)

    def mean_spread(labels):
        return np.mean([np.ptp(tl[labels == k]) for k in range(labels.max() + 1)])

    ea = clustering.error_aware_clusters(c.mesh.positions, c.mesh.indices, lv, s=100)
    oc = clustering.octree_clusters(c.mesh.positions, c.mesh.indices, s=100)
    assert mean_spread(ea) < mean_spread(oc)


def test_clustering_degenerate_inputs():
    P = np.zeros((3, 3))
    assert clustering.error_aware_clusters(P, np.zeros((0, 3), int), np.zeros(3)).size == 0
    assert clustering.octree_clusters(P, np.zeros((0, 3), int)).size == 0
    # coincident centroids (all triangles identical) still end within s
    tris = np.tile([[0, 1, 2]], (250, 1))
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    assert np.bincount(clustering.octree_clusters(P, tris, s=100)).max() <= 100
    assert np.bincount(clustering.error_aware_clusters(P, tris, np.zeros(3), s=100)).max() <= 100
    with pytest.raises(ValueError, match="s"):
        clustering.octree_clusters(P, tris, s=0)


def test_split_disconnected_gives_connected_clusters():
    # two separate triangles and a connected pair share label 0
    tris = np.array([[0, 1, 2], [3, 4, 5], [3, 5, 6], [7, 8, 9]])
    ptr, nbr = clustering.triangle_adjacency(tris, 10)
    lab = clustering.split_disconnected(np.zeros(4, np.int64), ptr, nbr)
    assert lab.tolist() == [0, 1, 1, 2]
    assert clustering.split_disconnected(np.zeros(0, np.int64), *clustering.triangle_adjacency(
        np.zeros((0, 3), int), 0)).size == 0


def test_error_aware_leaves_are_connected(human):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    c, lv = human
    tri = np.asarray(c.mesh.indices, np.int64).reshape(-1, 3)
    lab = clustering.error_aware_clusters(c.mesh.positions, tri, lv, s=100)
    ptr, nbr = clustering.triangle_adjacency(tri, c.mesh.n_vertices)
    src = np.repeat(np.arange(len(tri)), np.diff(ptr))
    k = lab[src] == lab[nbr]
    n, _ = connected_components(coo_matrix((np.ones(k.sum()), (src[k], nbr[k])), shape=(len(tri),) * 2),
                                directed=False)
    assert n == lab.max() + 1
    assert np.bincount(lab).max() <= 100


def test_compact_partition_kernel_matches_reference_and_bounds_size(human):
    c, lv = human
    tri = np.asarray(c.mesh.indices, np.int64).reshape(-1, 3)
    ptr, nbr = clustering.triangle_adjacency(tri, c.mesh.n_vertices)
    group = (clustering.triangle_levels(tri, lv) > np.median(lv)).astype(np.int64)  # two groups
    order = np.arange(len(tri))
    a = clustering.compact_partition(group, ptr, nbr, order, 50)
    b = clustering.compact_partition(group, ptr, nbr, order, 50, use_numba=False)
    assert np.array_equal(a, b)
    assert a.min() == 0 and np.bincount(a).max() <= 50
    for k in range(a.max() + 1):  # patches never cross groups
        assert np.unique(group[a == k]).size == 1
    # patches are connected
    assert np.array_equal(clustering.split_disconnected(a, ptr, nbr), a)


def test_compact_leaves_have_shorter_borders_than_median_splits(human):
    c, lv = human
    tri = np.asarray(c.mesh.indices, np.int64).reshape(-1, 3)

    def border(lab):
        inc = np.zeros((c.mesh.n_vertices, lab.max() + 1), bool)
        inc[tri.reshape(-1), np.repeat(lab, 3)] = True
        k = inc.sum(1)
        return int(k[k > 1].sum())

    grow = clustering.error_aware_clusters(c.mesh.positions, tri, lv, s=100)
    med = clustering.error_aware_clusters(c.mesh.positions, tri, lv, s=100, partition="median")
    assert np.bincount(med).max() <= 100 and np.bincount(grow).max() <= 100
    assert border(grow) < border(med)
    with pytest.raises(ValueError, match="partition"):
        clustering.error_aware_clusters(c.mesh.positions, tri, lv, partition="kmeans")


def test_unwelded_mesh_clusters_like_the_welded_one(human):
    """A mesh split at every vertex (glTF flat shading) has no shared edges; clustering welds by position
    for adjacency, so it still forms the same multi-triangle clusters instead of one per triangle."""
    c, lv = human
    tri = np.asarray(c.mesh.indices, np.int64).reshape(-1, 3)
    P = np.asarray(c.mesh.positions)
    split_P = P[tri.reshape(-1)]
    split_t = np.arange(3 * len(tri)).reshape(-1, 3)
    w = clustering.welded_indices(split_P, split_t)
    assert np.array_equal(split_P[w], split_P[split_t])  # same geometry
    assert np.unique(w).size == np.unique(tri).size
    a = clustering.error_aware_clusters(P, tri, lv, s=100)
    b = clustering.error_aware_clusters(split_P, split_t, lv[tri.reshape(-1)], s=100)
    assert np.array_equal(a, b)
    assert clustering.welded_indices(np.zeros((0, 3)), np.zeros((0, 3), int)).shape == (0, 3)
