"""VDR-AM §4/§4.1: classical MDS and representative pose selection."""
import numpy as np
import pytest

from lod.clusters import poses
from lod.clusters.config import CLUSTERS_MDS_DIMS
from sim.procedural import humanoid


def _dist(X):
    return np.linalg.norm(X[:, None] - X[None], axis=-1)


def test_mds_preserves_distances_of_low_rank_data():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(30, 6)) @ rng.normal(size=(6, 60))  # rank 6 in 60-D
    Y = poses.classical_mds(X, 9)
    assert Y.shape == (30, 9)
    np.testing.assert_allclose(_dist(Y), _dist(X), atol=1e-8 * _dist(X).max())


def test_mds_degenerate_inputs():
    assert poses.classical_mds(np.zeros((0, 5))).shape == (0, CLUSTERS_MDS_DIMS)
    assert np.all(poses.classical_mds(np.ones((1, 5))) == 0)
    same = poses.classical_mds(np.ones((4, 5)))
    assert np.all(np.isfinite(same)) and np.allclose(same, 0)
    with pytest.raises(ValueError, match="NaN"):
        poses.classical_mds(np.array([[0.0, np.nan], [1.0, 2.0]]))
    with pytest.raises(ValueError, match="dims"):
        poses.classical_mds(np.ones((3, 2)), 0)


def test_select_clusters_close_points_and_partitions_long_groups():
    # two far clumps -> two groups, the representative of each is its central point
    a = np.array([[0.0, 0], [0.1, 0], [0.2, 0]])
    b = a + [10.0, 0]
    reps, group = poses.select_poses(np.vstack([a, b]), d=0.15)
    assert reps.tolist() == [1, 4]
    assert group.tolist() == [0, 0, 0, 1, 1, 1]
    # a chain of close points merges into one group whose diagonal (9) > 1.5 d: it is split
    chain = np.stack([np.arange(10.0), np.zeros(10)], 1)
    reps, group = poses.select_poses(chain, d=1.01)
    sizes = np.bincount(group)
    assert len(reps) > 1
    for g in range(len(reps)):
        m = chain[group == g]
        assert np.linalg.norm(m.max(0) - m.min(0)) <= 1.5 * 1.01 or sizes[g] == 1
        assert group[reps[g]] == g


def test_select_degenerate_inputs():
    r, g = poses.select_poses(np.zeros((0, 9)), 1.0)
    assert r.size == 0 and g.size == 0
    r, g = poses.select_poses(np.zeros((5, 9)), 1.0)  # identical poses: one representative
    assert r.tolist() == [0] and np.all(g == 0)
    with pytest.raises(ValueError, match="d must be"):
        poses.select_poses(np.zeros((3, 9)), 0.0)


def test_35_pose_walk_keeps_5_to_12_poses():
    for seed in (0, 1):
        c = humanoid(600, seed)
        clip = c.clip("walk")
        t = poses.sample_times(clip, 35)
        assert t.shape == (35,) and t[-1] < clip.duration
        Y = poses.classical_mds(poses.pose_features(c.skeleton, clip, t))
        reps, group = poses.select_poses(Y, poses.pose_distance(c))
        assert 5 <= len(reps) <= 12
        assert np.array_equal(np.unique(group), np.arange(len(reps)))


def test_representative_poses_of_a_character():
    c = humanoid(600, 0)
    mats, reps, owner = poses.representative_poses(c, ["walk", "run"], samples=20)
    assert mats.shape == (40, c.skeleton.n_joints, 4, 4)
    assert owner.tolist() == [0] * 20 + [1] * 20
    assert reps.min() >= 0 and reps.max() < 40 and np.all(np.diff(reps) > 0)
    assert {0, 1} <= set(owner[reps].tolist())  # both clips are represented
