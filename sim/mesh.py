"""Triangle meshes with optional skin attributes and morph targets.

Conventions (shared by every layer): metres, right-handed, Y up; colours are
linear RGBA in [0, 1].

Morph targets follow §3.7.2.2 of the glTF 2.0 specification (2.0.1): a target
is a displacement of every vertex's position and normal, and a mesh is drawn
at ``base + sum_i w_i * delta_i``. :class:`MorphTargets` stores the deltas and
the default weights the mesh's own ``positions``/``normals`` already include,
so code that ignores morph targets sees the mesh at its default weights.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Mesh:
    """An indexed triangle mesh.

    Attributes
    ----------
    positions : (V, 3) float32
    indices : (T, 3) uint32
    normals : (V, 3) float32 or None
        Unit normals; computed by :meth:`ensure_normals` when missing.
    colors : (V, 4) float32 or None
        Per-vertex linear RGBA. When None, ``base_color`` applies.
    joints : (V, 4) uint16 or None
        Indices into the skeleton's joints (skinned meshes only).
    weights : (V, 4) float32 or None
        Skin weights, rows summing to 1 (skinned meshes only).
    base_color : (4,) float32
    morph : MorphTargets or None
        Morph targets (skinned meshes of glTF files); ``positions`` and
        ``normals`` are the mesh at ``morph.default_weights``.
    double_sided : bool
        True (default): both faces of every triangle are seen, so a renderer
        must not cull back faces. False: a closed or one-sided surface wound
        counter-clockwise seen from the front (glTF ``material.doubleSided``
        false, §3.9.5; the procedural characters), whose back faces may be culled.
    """

    positions: np.ndarray
    indices: np.ndarray
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    joints: np.ndarray | None = None
    weights: np.ndarray | None = None
    base_color: np.ndarray = field(default_factory=lambda: np.array([0.8, 0.8, 0.8, 1.0], np.float32))
    morph: MorphTargets | None = None
    double_sided: bool = True

    @property
    def n_vertices(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.indices.shape[0])

    @property
    def is_skinned(self) -> bool:
        return self.joints is not None and self.weights is not None

    def vertex_colors(self) -> np.ndarray:
        """(V, 4) float32 colours, filled from ``base_color`` when absent."""
        if self.colors is not None:
            return np.asarray(self.colors, np.float32)
        return np.broadcast_to(np.asarray(self.base_color, np.float32), (self.n_vertices, 4)).copy()

    def ensure_normals(self) -> np.ndarray:
        """Return (V, 3) float32 normals, computing area-weighted ones if absent."""
        if self.normals is None:
            self.normals = vertex_normals(self.positions, self.indices)
        return self.normals


@dataclass
class MorphTargets:
    """Morph targets of a mesh (glTF 2.0 §3.7.2.2), dense.

    Attributes
    ----------
    positions : (M, V, 3) float32, position delta of every vertex per target
    normals : (M, V, 3) float32, normal delta (zero where the source gives none)
    default_weights : (M,) float64, the weights the mesh's ``positions`` and
        ``normals`` already include (glTF ``mesh.weights`` / ``node.weights``)
    names : list of M str

    Notes
    -----
    At weights w the mesh is ``positions + sum_i (w_i - default_i) * delta_i``
    (equal to the glTF base plus ``sum_i w_i * delta_i``); normals likewise,
    then renormalised (:func:`sim.skinning.morph`).
    """

    positions: np.ndarray
    normals: np.ndarray
    default_weights: np.ndarray
    names: list = field(default_factory=list)

    @property
    def n_targets(self) -> int:
        return int(self.positions.shape[0])

    def offsets(self, weights) -> np.ndarray:
        """``weights - default_weights`` as float64, (..., M); raises ValueError
        for a wrong last axis or non-finite weights."""
        w = np.asarray(weights, np.float64)
        if w.shape[-1:] != (self.n_targets,):
            raise ValueError(f"morph weights: expected {self.n_targets} per row, got shape {w.shape}")
        if not np.isfinite(w).all():
            raise ValueError("morph weights: expected finite values, got NaN or Inf")
        return w - np.asarray(self.default_weights, np.float64)


def vertex_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals, (V, 3) float32.

    Degenerate triangles contribute nothing; isolated or fully degenerate
    vertices get +Y (never NaN).
    """
    p = np.asarray(positions, np.float64)
    idx = np.asarray(indices, np.int64)
    n = np.zeros_like(p)
    if idx.size:
        a, b, c = p[idx[:, 0]], p[idx[:, 1]], p[idx[:, 2]]
        fn = np.cross(b - a, c - a)  # length = 2 * area: area weighting
        flat = idx.reshape(-1)
        for k in range(3):  # bincount is much faster than np.add.at
            n[:, k] = np.bincount(flat, weights=np.repeat(fn[:, k], 3), minlength=p.shape[0])
    ln = np.linalg.norm(n, axis=1)
    ok = ln > 1e-30
    out = np.zeros_like(p)
    out[ok] = n[ok] / ln[ok, None]
    out[~ok] = (0.0, 1.0, 0.0)
    return out.astype(np.float32)
