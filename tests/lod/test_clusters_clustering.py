"""VDR-AM §4.2: deformation levels, error-aware clustering, octree baseline."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
from tiny_characters import tiny_skinned  # noqa: E402

from lod import clustering, deformation, poses  # noqa: E402
from lod.cluster_dag import skin_poses  # noqa: E402
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
