"""Checking and repairing the skin weights of a mesh built in code.

The same policy as the glTF importer (``sim.gltf.load``), for meshes that do not
come from a file (generators, tests, user code):

- NaN or infinite weights are refused: :class:`sim.errors.AssetError`, one
  sentence naming the asset and the number of vertices;
- negative weights are clipped to 0, with a warning naming the asset and the
  number of vertices;
- rows whose weights are all zero (after clipping) are bound with weight 1 to
  a fallback joint (joint 0 unless given), with a warning;
- every row is renormalised to sum to 1 (silently when it was within
  :data:`SUM_TOLERANCE` of 1 or the glTF importer's renormalisation applies,
  with a warning otherwise).
"""
from __future__ import annotations

import warnings

import numpy as np

from sim.errors import AssetError

#: rows whose sum differs from 1 by more than this are reported when renormalised
SUM_TOLERANCE = 1e-3


def repair_skin_weights(joints, weights, asset: str, n_joints: int | None = None, fallback: int = 0,
                        warn_sum: bool = True) -> tuple[np.ndarray, np.ndarray, dict]:
    """Return repaired (joints (V, 4) uint16, weights (V, 4) float32, counts).

    Parameters
    ----------
    joints : (V, 4) integer joint indices
    weights : (V, 4) float weights
    asset : name used in messages (file or character name)
    n_joints : skeleton size; joint indices must be below it (checked when given)
    fallback : joint that rows with all-zero weights are bound to
    warn_sum : warn when rows summing far from 1 are renormalised

    Returns
    -------
    joints, weights, counts : dict with "negative", "zero", "renormalised" vertex counts

    Raises
    ------
    AssetError
        NaN/Inf weights, mismatched shapes or joint indices out of range.
    """
    j = np.asarray(joints)
    w = np.asarray(weights, np.float64)
    if j.ndim != 2 or w.shape != j.shape:
        raise AssetError(f"{asset}: skin joints {j.shape} and weights {w.shape} must both be (V, k)")
    bad = ~np.isfinite(w).all(axis=1)
    if bad.any():
        raise AssetError(f"{asset}: {int(bad.sum())} vertices have NaN or infinite skin weights; "
                         "expected finite weights >= 0")
    if n_joints is not None and j.size and (int(j.min()) < 0 or int(j.max()) >= n_joints):
        raise AssetError(f"{asset}: skin joint indices reach {int(j.max())} (min {int(j.min())}), "
                         f"expected 0 ..= {n_joints - 1}")
    counts = {"negative": 0, "zero": 0, "renormalised": 0}
    neg = (w < 0.0).any(axis=1)
    if neg.any():
        counts["negative"] = int(neg.sum())
        warnings.warn(f"{asset}: {counts['negative']} vertices have negative skin weights; clipped to 0 and "
                      "renormalised", stacklevel=2)
        w = np.clip(w, 0.0, None)
    j = j.astype(np.int64).copy()
    s = w.sum(axis=1)
    zero = ~(s > 1e-12)
    if zero.any():
        counts["zero"] = int(zero.sum())
        warnings.warn(f"{asset}: {counts['zero']} vertices have all-zero skin weights; bound to joint {fallback}",
                      stacklevel=2)
        w[zero] = 0.0
        w[zero, 0] = 1.0
        j[zero] = 0
        j[zero, 0] = fallback
        s = w.sum(axis=1)
    off = np.abs(s - 1.0) > SUM_TOLERANCE
    counts["renormalised"] = int(off.sum())
    if off.any() and warn_sum:
        warnings.warn(f"{asset}: {counts['renormalised']} vertices have skin weights not summing to 1; "
                      "renormalised", stacklevel=2)
    w = w / s[:, None]
    return j.astype(np.uint16), w.astype(np.float32), counts


def repair_mesh_weights(mesh, asset: str, n_joints: int | None = None, fallback: int = 0):
    """:func:`repair_skin_weights` applied in place to a skinned ``sim.mesh.Mesh``; returns the counts
    (an unskinned mesh is left alone and gives None)."""
    if not mesh.is_skinned:
        return None
    mesh.joints, mesh.weights, counts = repair_skin_weights(mesh.joints, mesh.weights, asset, n_joints, fallback)
    return counts
