"""Per-vertex deformation levels (VDR-AM §4.2).

Claudio, Kim, Kim, Yoon, *VDR-AM*, §4.2: the deformation level of a vertex is
the diagonal of the tightest axis-aligned box holding its trajectory over the
animation, measured in the frame of the least common ancestor (LCA) of the bones
that influence it. A vertex moved rigidly by one bone (or by bones that move
rigidly with their LCA) has level 0; a vertex at a bending joint has a large one.
The level stands in for the simplification error when clustering (§4.2) and when
pairing clusters (§4.3).

Departure: the box is over the *sampled* poses (the same samples the hierarchy
is built from), not a continuous trajectory.
"""
from __future__ import annotations

import numpy as np

from lod.clusters.config import CLUSTERS_WEIGHT_EPS


def least_common_ancestor(parents: np.ndarray, a: int, b: int) -> int:
    """LCA of joints ``a`` and ``b`` in a forest given by ``parents`` (J,) int
    (-1 for roots, ``parents[j] < j``); -1 when they lie in different trees."""
    while a != b:
        if a < 0 or b < 0:
            return -1
        if a > b:
            a = int(parents[a])
        else:
            b = int(parents[b])
    return a


def vertex_lca(parents: np.ndarray, joints: np.ndarray, weights: np.ndarray,
               eps: float = CLUSTERS_WEIGHT_EPS) -> np.ndarray:
    """Least common ancestor of the influencing bones of every vertex.

    Parameters
    ----------
    parents : (J,) int joint parents (-1 roots), topologically ordered
    joints : (V, K) int joint indices
    weights : (V, K) float skin weights; a bone influences a vertex when its
        weight exceeds ``eps``

    Returns
    -------
    (V,) int64 joint index, -1 when the bones lie in different trees (the model
    frame is then used) or when no weight exceeds ``eps``.
    """
    parents = np.asarray(parents, np.int64)
    joints = np.asarray(joints, np.int64)
    w = np.asarray(weights, np.float64)
    V = joints.shape[0]
    out = np.full(V, -1, np.int64)
    # vertices with the same influence set share the answer: solve per unique set
    masked = np.where(w > eps, joints, -1)
    masked = np.sort(masked, axis=1)
    uniq, inv = np.unique(masked, axis=0, return_inverse=True)
    ans = np.full(uniq.shape[0], -1, np.int64)
    for i, row in enumerate(uniq):
        bones = [int(j) for j in row if j >= 0]
        if not bones:
            continue
        a = bones[0]
        for b in bones[1:]:
            a = least_common_ancestor(parents, a, b)
            if a < 0:
                break
        ans[i] = a
    out[:] = ans[np.asarray(inv).reshape(-1)]
    return out


def deformation_levels(positions_per_pose: np.ndarray, global_mats: np.ndarray, lca: np.ndarray) -> np.ndarray:
    """Deformation level of every vertex (§4.2).

    Parameters
    ----------
    positions_per_pose : (N, V, 3) float64 skinned model-space positions
    global_mats : (N, J, 4, 4) float64 global joint matrices of the same poses
    lca : (V,) int joint frame of each vertex (-1: model frame), from :func:`vertex_lca`

    Returns
    -------
    (V,) float64 metres: diagonal of the box of the vertex trajectory expressed in
    its LCA bone's frame. Finite; 0 for a single pose.
    """
    X = np.asarray(positions_per_pose, np.float64)
    G = np.asarray(global_mats, np.float64)
    lca = np.asarray(lca, np.int64)
    N, V = X.shape[0], X.shape[1]
    if N == 0 or V == 0:
        return np.zeros(V)
    # inverse of rigid-ish global matrices; general inverse for safety (scale allowed)
    Ginv = np.linalg.inv(G)  # (N, J, 4, 4)
    eye = np.broadcast_to(np.eye(4), (N, 1, 4, 4))
    Ginv = np.concatenate([Ginv, eye], axis=1)  # index J = model frame
    idx = np.where(lca < 0, G.shape[1], lca)
    lo = np.full((V, 3), np.inf)
    hi = np.full((V, 3), -np.inf)
    for n in range(N):
        M = Ginv[n][idx]  # (V, 4, 4)
        q = np.einsum("vij,vj->vi", M[:, :3, :3], X[n]) + M[:, :3, 3]
        np.minimum(lo, q, out=lo)
        np.maximum(hi, q, out=hi)
    out = np.linalg.norm(hi - lo, axis=1)
    return np.where(np.isfinite(out), out, 0.0)


def character_deformation(character, skin_mats: np.ndarray, positions_per_pose: np.ndarray) -> np.ndarray:
    """Deformation levels (V,) float64 of a skinned character over given poses.

    ``skin_mats`` (N, J, 4, 4) are skinning matrices (global @ inverse bind);
    the global matrices are recovered as ``skin_mats @ inv(inverse_bind)``.
    """
    sk = character.skeleton
    bind = np.linalg.inv(np.asarray(sk.inverse_bind, np.float64))
    G = np.asarray(skin_mats, np.float64) @ bind
    m = character.mesh
    lca = vertex_lca(sk.parents, m.joints, m.weights)
    return deformation_levels(positions_per_pose, G, lca)
