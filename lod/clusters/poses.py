"""Pose-space reduction and representative pose selection (VDR-AM §4, §4.1).

Claudio, Kim, Kim, Yoon, *VDR-AM: View-Dependent Representation of Articulated
Models*. §4 maps every pose of an animation to a point of a 9-dimensional space
by classical multidimensional scaling; §4.1 groups those points by clustering
(single linkage at distance d, found with a k-d tree) and partitioning (median
splits of groups whose box diagonal exceeds 1.5 d) and keeps the pose nearest
each group's centre. Only the kept poses feed the multi-pose quadrics of §4.3.

Pose space (our choice; the paper only says "joint transforms"): a pose is the
vector of its model-space joint positions, (J*3,) metres. The global joint
matrices' translations already carry every rotation above them, distances are in
metres, and d can therefore be measured, as §6 asks, as a fraction of the model's
box diagonal: d lives in the MDS space of these vectors (metres). What this
leaves out is the rotation of end joints about themselves (a hand or head
turning without moving a child joint). Flattened global matrices with the
rotation part scaled by the mean bone length were tried too: on the procedural
35-pose walk they keep 12-13 poses at d = 20 % against 11 for joint positions
and the paper's 8, for no measurable gain in simplification error.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from lod.clusters.config import (
    CLUSTERS_MDS_DIMS,
    CLUSTERS_POSE_D_FRACTION,
    CLUSTERS_POSE_SAMPLES,
    CLUSTERS_POSE_SPLIT_FACTOR,
)


def sample_times(clip, n: int = CLUSTERS_POSE_SAMPLES) -> np.ndarray:
    """(n,) float64 times spread uniformly over ``clip`` ([0, duration) for a
    looping clip, [0, duration] otherwise); ``[0.]`` for a zero-length clip."""
    n = max(int(n), 1)
    d = float(clip.duration)
    if not (d > 0.0) or not np.isfinite(d):
        return np.zeros(1)
    if clip.loop:
        return np.arange(n, dtype=np.float64) * (d / n)
    return np.linspace(0.0, d, n)


def pose_features(skeleton, clip, times) -> np.ndarray:
    """Pose vectors of ``clip`` at ``times``: model-space joint positions.

    Parameters
    ----------
    skeleton : sim.skeleton.Skeleton
    clip : sim.clip.Clip
    times : (N,) float seconds

    Returns
    -------
    (N, J*3) float64, metres; the Euclidean distance of two rows is the
    root-sum-square displacement of the joints between the two poses.
    """
    G = skeleton.global_matrices(*clip.sample_times(skeleton, np.asarray(times, np.float64)))
    return np.ascontiguousarray(G[..., :3, 3].reshape(G.shape[0], -1))


def classical_mds(features: np.ndarray, dims: int = CLUSTERS_MDS_DIMS) -> np.ndarray:
    """Classical (Torgerson) multidimensional scaling (§4, [McG68]).

    Parameters
    ----------
    features : (N, D) float, one pose per row
    dims : int >= 1, target dimension (the paper uses 9)

    Returns
    -------
    (N, dims) float64 coordinates whose Euclidean distances approximate those of
    ``features`` (exactly when the rank is <= dims). Axes beyond the rank of the
    data are zero. Double-centres the squared distance matrix ``B = -1/2 J D² J``
    and keeps the eigenvectors of the largest eigenvalues scaled by their roots.
    """
    X = np.asarray(features, np.float64)
    if X.ndim != 2:
        raise ValueError(f"classical_mds: features must be (N, D), got shape {X.shape}")
    if int(dims) < 1:
        raise ValueError(f"classical_mds: dims must be >= 1, got {dims}")
    n = X.shape[0]
    out = np.zeros((n, int(dims)))
    if n <= 1:
        return out
    if not np.all(np.isfinite(X)):
        raise ValueError("classical_mds: features contain NaN or Inf")
    sq = np.sum(X * X, axis=1)
    D2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * X @ X.T, 0.0)
    Jc = np.eye(n) - 1.0 / n
    B = -0.5 * Jc @ D2 @ Jc
    w, V = np.linalg.eigh(0.5 * (B + B.T))
    order = np.argsort(w)[::-1][: int(dims)]
    w = np.maximum(w[order], 0.0)
    out[:, : order.size] = V[:, order] * np.sqrt(w)[None, :]
    return out


def _split(points: np.ndarray, members: np.ndarray, limit: float, out: list) -> None:
    """§4.1 partitioning: median split along the longest box side until the box
    diagonal is at most ``limit``."""
    stack = [members]
    while stack:
        m = stack.pop()
        p = points[m]
        ext = p.max(0) - p.min(0)
        if m.size <= 1 or np.linalg.norm(ext) <= limit:
            out.append(m)
            continue
        axis = int(np.argmax(ext))
        order = m[np.argsort(p[:, axis], kind="stable")]
        half = order.size // 2
        stack.append(order[half:])
        stack.append(order[:half])


def select_poses(points: np.ndarray, d: float, split_factor: float = CLUSTERS_POSE_SPLIT_FACTOR):
    """Representative poses by clustering and partitioning (§4.1).

    Parameters
    ----------
    points : (N, k) float64 reduced poses (output of :func:`classical_mds`)
    d : float > 0, clustering distance in the units of ``points``
    split_factor : groups whose box diagonal exceeds ``split_factor * d`` are
        split at the median of their longest side (1.5 in the paper)

    Returns
    -------
    representatives : (G,) int64 sorted indices of the chosen poses
    group : (N,) int64 group index of every pose (``representatives[group[i]]``
        represents pose i)

    Notes
    -----
    Clustering merges two groups when any two of their members are closer than
    d: the connected components of the graph of pairs closer than d (pairs from a
    ``cKDTree``), i.e. single linkage cut at d. The representative is the member
    nearest the group's mean.
    """
    P = np.asarray(points, np.float64)
    n = P.shape[0]
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    if not (float(d) > 0.0) or not np.isfinite(d):
        raise ValueError(f"select_poses: d must be a finite distance > 0, got {d}")
    pairs = cKDTree(P).query_pairs(float(d), output_type="ndarray")
    A = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)) if len(pairs) else \
        coo_matrix((n, n))
    ncomp, label = connected_components(A, directed=False)
    groups: list = []
    for c in range(ncomp):
        _split(P, np.nonzero(label == c)[0], split_factor * float(d), groups)
    reps = []
    for g in groups:
        c = P[g].mean(0)
        reps.append(int(g[np.argmin(np.sum((P[g] - c) ** 2, axis=1))]))
    order = np.argsort(reps)
    group = np.empty(n, np.int64)
    for gi, k in enumerate(order):
        group[groups[k]] = gi
    return np.asarray(reps, np.int64)[order], group


def pose_distance(character, fraction: float = CLUSTERS_POSE_D_FRACTION) -> float:
    """The §4.1 distance d: ``fraction`` of the rest-pose box diagonal (metres)."""
    lo, hi = character.rest_bounds()
    diag = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    return max(fraction * diag, 1e-9)


def representative_poses(character, clips=None, samples: int = CLUSTERS_POSE_SAMPLES,
                         d_fraction: float = CLUSTERS_POSE_D_FRACTION, dims: int = CLUSTERS_MDS_DIMS):
    """Sample a character's clips and choose representative poses (§4, §4.1).

    Parameters
    ----------
    character : sim.character.SkinnedCharacter
    clips : list of clip names, or None for all clips
    samples : poses sampled per clip (:func:`sample_times`)
    d_fraction : d as a fraction of the rest box diagonal

    Returns
    -------
    skin_mats : (N, J, 4, 4) float64 skinning matrices of all N sampled poses
        (clips concatenated in order)
    representatives : (G,) int64 indices into the N poses
    clip_of_pose : (N,) int64 index (in ``clips`` order) of each pose's clip

    A character without clips yields its rest pose as the only pose.
    """
    sk = character.skeleton
    names = list(character.clips) if clips is None else list(clips)
    feats, mats, owner = [], [], []
    for ci, name in enumerate(names):
        clip = character.clip(name)
        t = sample_times(clip, samples)
        feats.append(pose_features(sk, clip, t))
        mats.append(clip.skinning_matrices(sk, t))
        owner.append(np.full(t.shape[0], ci, np.int64))
    if not feats:
        G = sk.rest_global_matrices()[None]
        mats = [sk.skinning_matrices(*sk.rest_pose())[None]]
        feats = [G[..., :3, 3].reshape(1, -1)]
        owner = [np.zeros(1, np.int64)]
    F = np.concatenate(feats)
    reps, _ = select_poses(classical_mds(F, dims), pose_distance(character, d_fraction))
    return np.concatenate(mats), reps, np.concatenate(owner)
