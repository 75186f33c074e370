"""Morph targets of a skinned representation: sparse deltas and baked weights.

A skinned glTF mesh with morph targets (glTF 2.0 §3.7.2.2) is drawn as
``skin ∘ morph``: every vertex is first moved by the weighted deltas of the
targets, then linear-blend skinned (``sim.skinning.skin_morph`` is the CPU
reference). :func:`build_target_table` turns a character's
:class:`sim.mesh.MorphTargets` and its clips' ``weights`` channels into a
:class:`TargetTable` the renderer uploads (``render/poses/targets.py``,
``shaders/poses/targets.glsl``):

- Weights are baked like the joint matrices (:class:`lod.full.reps.SkinnedRep`):
  one row per baked frame of every clip, the same rows as ``joint_table``, so
  the instance's frame coordinate (``DrawBatch.instance_data[:, 12]``) indexes
  both and the vertex shader blends the two rows around it linearly. A row
  holds ``weight - default weight`` (the mesh's positions are at the default
  weights, :class:`sim.mesh.MorphTargets`).
- Only targets whose weight changes somewhere are kept: a target whose baked
  offset is the same constant in every frame of every clip is folded into the
  bind-pose positions and normals (so a mesh whose targets are not animated
  costs nothing per frame), and targets that move no vertex are dropped.
- Deltas are sparse: one entry per (vertex, kept target) whose position or
  normal delta is non-zero, grouped by vertex (``first``, ``count``), so a
  vertex reads only the targets that move it.

Bounds (:func:`morph_frame_aabbs`): per baked frame the box of the morphed and
skinned mesh. Between two frames the GPU blends matrices M and morphed
positions q linearly with the same factor a, so a vertex follows the quadratic
Bézier curve with control points ``M0 q0``, ``(M0 q1 + M1 q0) / 2`` and
``M1 q1``; its convex-hull property puts the curve inside the box of the three,
which is added to both frames' boxes. The gap between the continuous clip
(matrices and weights sampled at the middle of an interval) and the GPU's
blend there, times a pad factor, is added as in ``SkinnedRep``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: a target whose weight offset varies by at most this over all baked frames is constant (folded)
TARGETS_CONSTANT_TOL = 1e-9
#: bytes of GPU memory per sparse delta entry (2 RGBA32F texels), per vertex
#: (one RG32I texel: first entry, count) and per kept target and baked frame (R32F)
ENTRY_BYTES = 32
VERTEX_BYTES = 8
WEIGHT_BYTES = 4


@dataclass
class TargetTable:
    """The animated morph targets of a :class:`lod.full.reps.SkinnedRep`.

    Attributes
    ----------
    names : list of M str, the kept targets
    source : (M,) int64, their indices in the mesh's :class:`sim.mesh.MorphTargets`
    weights : (F_total, M) float32, ``weight - default weight`` of every kept
        target at every baked frame (rows as ``SkinnedRep.joint_table``)
    first : (V,) int32, first entry of each vertex
    count : (V,) int32, entries of each vertex (0: not moved by any kept target)
    column : (E,) int32, the kept target (column of ``weights``) of each entry
    dpos : (E, 3) float32, position delta of each entry (bind pose, model space)
    dnrm : (E, 3) float32, normal delta of each entry
    folded : list of str, targets at a constant non-default weight, folded into the bind pose
    """

    names: list
    source: np.ndarray
    weights: np.ndarray
    first: np.ndarray
    count: np.ndarray
    column: np.ndarray
    dpos: np.ndarray
    dnrm: np.ndarray
    folded: list = field(default_factory=list)

    @property
    def n_targets(self) -> int:
        return int(self.weights.shape[1])

    @property
    def n_entries(self) -> int:
        return int(self.column.shape[0])

    def gpu_bytes(self) -> int:
        """Bytes the renderer's textures of this table hold (before row padding)."""
        return (self.n_entries * ENTRY_BYTES + int(self.first.shape[0]) * VERTEX_BYTES
                + int(self.weights.size) * WEIGHT_BYTES)

    def morph(self, positions: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> tuple:
        """(positions, normals) (V, 3) float64 of the bind pose moved by the kept
        targets at weight offsets ``offsets`` (M,), normals not renormalised
        (the shader renormalises them before skinning)."""
        p = np.array(positions, np.float64)
        n = np.array(normals, np.float64)
        if self.n_entries:
            vert = np.repeat(np.arange(p.shape[0]), self.count)
            w = np.asarray(offsets, np.float64)[self.column][:, None]
            for k in range(3):
                p[:, k] += np.bincount(vert, weights=w[:, 0] * self.dpos[:, k], minlength=p.shape[0])
                n[:, k] += np.bincount(vert, weights=w[:, 0] * self.dnrm[:, k], minlength=p.shape[0])
        return p, n


def clip_offsets(character, times_per_clip) -> np.ndarray:
    """(F_total, M_all) float64 weight offsets of all targets at the baked times
    of every clip (clips one after another, as ``joint_table``)."""
    mt = character.mesh.morph
    rows = [mt.offsets(clip.morph_weights(mt, t)) for clip, t in zip(character.clips.values(), times_per_clip)]
    return np.concatenate(rows) if rows else np.zeros((0, mt.n_targets))


def build_target_table(morph, offsets: np.ndarray, positions: np.ndarray, normals: np.ndarray):
    """Keep the animated targets, fold the constant ones, make the deltas sparse.

    Parameters
    ----------
    morph : sim.mesh.MorphTargets
    offsets : (F_total, M_all) float64 weight offsets at every baked frame (:func:`clip_offsets`)
    positions, normals : (V, 3) bind pose of the representation

    Returns
    -------
    table : TargetTable, or None when no target changes its weight anywhere
    positions, normals : (V, 3) float32, with the constant targets folded in
    """
    dp_all = np.asarray(morph.positions, np.float64)
    dn_all = np.asarray(morph.normals, np.float64)
    off = np.asarray(offsets, np.float64)
    if not np.isfinite(off).all():
        raise ValueError("morph target weights: expected finite values, got NaN or Inf")
    moves = (dp_all != 0.0).any(axis=(1, 2)) | (dn_all != 0.0).any(axis=(1, 2))
    const = np.ptp(off, axis=0) <= TARGETS_CONSTANT_TOL if off.shape[0] else np.ones(off.shape[1], bool)
    p = np.asarray(positions, np.float64).copy()
    n = np.asarray(normals, np.float64).copy()
    folded = []
    for i in np.flatnonzero(const & moves & (off[0] != 0.0 if off.shape[0] else False)).tolist():
        p += off[0, i] * dp_all[i]
        n += off[0, i] * dn_all[i]
        folded.append(morph.names[i] if i < len(morph.names) else f"target{i}")
    keep = np.flatnonzero(moves & ~const)
    p32, n32 = p.astype(np.float32), n.astype(np.float32)
    if not (np.isfinite(p32).all() and np.isfinite(n32).all()):
        raise ValueError("morph targets: folded positions or normals are not finite")
    if keep.size == 0:
        return None, p32, n32
    dp, dn = dp_all[keep], dn_all[keep]  # (K, V, 3)
    nz = (dp != 0.0).any(axis=2) | (dn != 0.0).any(axis=2)  # (K, V)
    vert, col = np.nonzero(nz.T)  # entries ordered by vertex, then target
    V = p.shape[0]
    count = np.bincount(vert, minlength=V).astype(np.int32)
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int32)
    names = [morph.names[i] if i < len(morph.names) else f"target{i}" for i in keep.tolist()]
    dpos = dp[col, vert].astype(np.float32)
    dnrm = dn[col, vert].astype(np.float32)
    w = off[:, keep].astype(np.float32)
    for a, what in ((dpos, "position deltas"), (dnrm, "normal deltas"), (w, "weights")):
        if not np.isfinite(a).all():
            raise ValueError(f"morph targets: {what} are not finite")
    table = TargetTable(names=names, source=keep.astype(np.int64), weights=np.ascontiguousarray(w), first=first, count=count,
                        column=col.astype(np.int32), dpos=np.ascontiguousarray(dpos),
                        dnrm=np.ascontiguousarray(dnrm), folded=folded)
    return table, p32, n32


def _lbs(q: np.ndarray, joints: np.ndarray, weights: np.ndarray, m: np.ndarray) -> np.ndarray:
    """(V, 3) float64 linear blend skinning of points q with (J, 3, 4) matrices."""
    M = np.einsum("vk,vkab->vab", weights, m[joints])
    return np.einsum("vab,vb->va", M[:, :, :3], q) + M[:, :, 3]


def morph_frame_aabbs(table: TargetTable, positions, joints, weights, mats, offsets, mid_mats, mid_offsets,
                      pad_factor: float) -> np.ndarray:
    """Per-frame boxes (F, 2, 3) float64 of one clip of a morphed skinned mesh (module docstring).

    Parameters
    ----------
    table : TargetTable; positions : (V, 3) bind pose; joints (V, 4) int; weights (V, 4) float
    mats : (F, J, 3, 4) skinning matrices at the clip's baked frames; offsets : (F, M) their weight offsets
    mid_mats : (F-1, J, 3, 4), mid_offsets : (F-1, M): the continuous clip at the middle of every interval
    pad_factor : multiple of the largest mid-interval gap added to every box
    """
    pos = np.asarray(positions, np.float64)
    nrm = np.zeros_like(pos)
    jn = np.asarray(joints, np.int64)
    w = np.asarray(weights, np.float64)
    m = np.asarray(mats, np.float64)
    F = m.shape[0]
    out = np.zeros((F, 2, 3))
    if pos.shape[0] == 0 or F == 0:
        return out
    q = [table.morph(pos, nrm, offsets[f])[0] for f in range(F)]
    P = [_lbs(q[f], jn, w, m[f]) for f in range(F)]
    for f in range(F):
        out[f] = P[f].min(0), P[f].max(0)
    gap = np.zeros(3)
    for i in range(F - 1):
        c = 0.5 * (_lbs(q[i + 1], jn, w, m[i]) + _lbs(q[i], jn, w, m[i + 1]))  # the Bézier middle point
        for f in (i, i + 1):
            out[f, 0] = np.minimum(out[f, 0], c.min(0))
            out[f, 1] = np.maximum(out[f, 1], c.max(0))
        exact = _lbs(table.morph(pos, nrm, mid_offsets[i])[0], jn, w, np.asarray(mid_mats[i], np.float64))
        gap = np.maximum(gap, np.abs(exact - 0.5 * (0.5 * (P[i] + P[i + 1]) + c)).max(0))
    return out + np.array([-1.0, 1.0])[None, :, None] * (float(pad_factor) * gap)
