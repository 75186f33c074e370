"""CPU linear-blend skinning: the reference the GPU path is checked against.

Linear blend skinning (LBS): every vertex is moved by the weighted sum of its
joints' skinning matrices, ``M_v = sum_i w_i S[j_i]`` and ``p' = M_v p``.
Normals go through the inverse-transpose of ``M_v``'s linear part (computed as
its cofactor matrix times sign(det), which stays finite when ``M_v`` is
singular) and are renormalised.

Two implementations share this contract: :func:`skin_reference` (plain numpy,
obviously correct) and a numba kernel used by :func:`skin` for large meshes;
``tests/sim/test_skinning.py`` compares them.

Morph targets (glTF 2.0 §3.7.2.2) act before skinning: :func:`morph` moves the
bind-pose vertices by the weighted target deltas and :func:`skin_morph` skins
the result (``skin ∘ morph``, the order glTF prescribes). This is the CPU
reference of the GPU path (``render/shaders/poses/targets.glsl``).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit, prange

from sim import math3d


def _check(mesh, skin_mats) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not mesh.is_skinned:
        raise ValueError("skin: the mesh has no joints/weights (not a skinned mesh)")
    S = np.ascontiguousarray(skin_mats, np.float64)
    if S.ndim != 3 or S.shape[1:] != (4, 4):
        raise ValueError(f"skin: skin_mats must be (J, 4, 4), got {S.shape}")
    joints = np.ascontiguousarray(mesh.joints, np.int64)
    if joints.size and (joints.min() < 0 or joints.max() >= S.shape[0]):
        raise ValueError(f"skin: joint indices reach {int(joints.max())} but only {S.shape[0]} matrices were given")
    w = np.ascontiguousarray(mesh.weights, np.float64)
    return S, joints, w


def blend_matrices(mesh, skin_mats) -> np.ndarray:
    """Per-vertex blended matrices ``sum_i w_i S[j_i]``, (V, 4, 4) float64."""
    S, joints, w = _check(mesh, skin_mats)
    return np.einsum("vi,vijk->vjk", w, S[joints])


def skin_reference(mesh, skin_mats) -> tuple[np.ndarray, np.ndarray]:
    """Numpy reference of :func:`skin` (same arguments and results)."""
    M = blend_matrices(mesh, skin_mats)
    p = np.asarray(mesh.positions, np.float64)
    pos = np.einsum("vij,vj->vi", M[:, :3, :3], p) + M[:, :3, 3]
    n0 = np.asarray(mesh.ensure_normals(), np.float64)
    A = M[:, :3, :3]
    C = math3d.cofactor3(A) * np.sign(np.linalg.det(A))[:, None, None]
    n = np.einsum("vij,vj->vi", C, n0)
    # A singular blend (e.g. all-zero weights) has a zero cofactor: keep the rest normal.
    n = math3d.normalize_vectors(n, (0.0, 0.0, 0.0))
    bad = ~np.any(n != 0.0, axis=1)
    n[bad] = math3d.normalize_vectors(n0[bad])
    return pos, n


@njit(cache=True, parallel=True)
def _skin_kernel(S, joints, w, p, n0, pos_out, nrm_out):
    V = p.shape[0]
    nj = joints.shape[1]
    for v in prange(V):
        m = np.zeros((3, 4))
        for i in range(nj):
            wi = w[v, i]
            if wi != 0.0:
                j = joints[v, i]
                for r in range(3):
                    for c in range(4):
                        m[r, c] += wi * S[j, r, c]
        for r in range(3):
            pos_out[v, r] = m[r, 0] * p[v, 0] + m[r, 1] * p[v, 1] + m[r, 2] * p[v, 2] + m[r, 3]
        # cofactor matrix columns: cross products of the linear part's columns
        a0x, a0y, a0z = m[0, 0], m[1, 0], m[2, 0]
        a1x, a1y, a1z = m[0, 1], m[1, 1], m[2, 1]
        a2x, a2y, a2z = m[0, 2], m[1, 2], m[2, 2]
        c0x, c0y, c0z = a1y * a2z - a1z * a2y, a1z * a2x - a1x * a2z, a1x * a2y - a1y * a2x
        c1x, c1y, c1z = a2y * a0z - a2z * a0y, a2z * a0x - a2x * a0z, a2x * a0y - a2y * a0x
        c2x, c2y, c2z = a0y * a1z - a0z * a1y, a0z * a1x - a0x * a1z, a0x * a1y - a0y * a1x
        det = a0x * c0x + a0y * c0y + a0z * c0z
        sg = 1.0 if det > 0.0 else (-1.0 if det < 0.0 else 0.0)
        nx, ny, nz = n0[v, 0], n0[v, 1], n0[v, 2]
        ox = sg * (c0x * nx + c1x * ny + c2x * nz)
        oy = sg * (c0y * nx + c1y * ny + c2y * nz)
        oz = sg * (c0z * nx + c1z * ny + c2z * nz)
        ln = np.sqrt(ox * ox + oy * oy + oz * oz)
        if not (ln > 1e-30) or not np.isfinite(ln):
            ox, oy, oz = nx, ny, nz
            ln = np.sqrt(ox * ox + oy * oy + oz * oz)
            if not (ln > 1e-30) or not np.isfinite(ln):
                ox, oy, oz, ln = 0.0, 1.0, 0.0, 1.0
        nrm_out[v, 0] = ox / ln
        nrm_out[v, 1] = oy / ln
        nrm_out[v, 2] = oz / ln


def skin(mesh, skin_mats) -> tuple[np.ndarray, np.ndarray]:
    """Linear-blend-skin a mesh on the CPU.

    Parameters
    ----------
    mesh : sim.mesh.Mesh with ``joints`` (V, 4) and ``weights`` (V, 4)
    skin_mats : (J, 4, 4) float, ``Skeleton.skinning_matrices(...)``

    Returns
    -------
    positions : (V, 3) float64
    normals : (V, 3) float64, unit; the rest normal (or +Y) where the blended
        matrix is singular, never NaN.
    """
    S, joints, w = _check(mesh, skin_mats)
    p = np.ascontiguousarray(mesh.positions, np.float64)
    n0 = np.ascontiguousarray(mesh.ensure_normals(), np.float64)
    pos = np.empty_like(p)
    nrm = np.empty_like(p)
    _skin_kernel(S, joints, w, p, n0, pos, nrm)
    return pos, nrm


def bind_pose_matrices(skeleton) -> np.ndarray:
    """Skinning matrices at the rest pose, (J, 4, 4) float64 (identity when
    ``inverse_bind`` is consistent with the rest pose)."""
    return skeleton.skinning_matrices(*skeleton.rest_pose())


def morph(mesh, weights) -> tuple[np.ndarray, np.ndarray]:
    """Bind-pose vertices moved by morph targets at ``weights`` (glTF 2.0 §3.7.2.2).

    Parameters
    ----------
    mesh : sim.mesh.Mesh; without ``morph`` its own positions and normals
    weights : (M,) float, absolute target weights (``Clip.morph_weights``)

    Returns
    -------
    positions : (V, 3) float64, ``positions + sum_i (w_i - default_i) dp_i``
    normals : (V, 3) float64, likewise with the normal deltas, renormalised
        (the unmorphed normal where the sum vanishes; never NaN)
    """
    p = np.asarray(mesh.positions, np.float64).copy()
    n0 = np.asarray(mesh.ensure_normals(), np.float64)
    mt = mesh.morph
    if mt is None:
        return p, n0.copy()
    off = mt.offsets(np.asarray(weights, np.float64).reshape(-1))
    live = np.flatnonzero(off != 0.0)
    n = n0.copy()
    for i in live.tolist():
        p += off[i] * np.asarray(mt.positions[i], np.float64)
        n += off[i] * np.asarray(mt.normals[i], np.float64)
    return p, math3d.normalize_vectors(n, n0) if live.size else n


def _morphed_mesh(mesh, weights):
    p, n = morph(mesh, weights)
    return dataclasses.replace(mesh, positions=p, normals=n, morph=None)


def skin_morph(mesh, skin_mats, weights) -> tuple[np.ndarray, np.ndarray]:
    """``skin ∘ morph``: the mesh morphed at ``weights`` (:func:`morph`), then
    linear-blend skinned with ``skin_mats`` (:func:`skin`); same results as
    :func:`skin` when the mesh has no morph targets. (V, 3) float64 each."""
    return skin(_morphed_mesh(mesh, weights), skin_mats)


def skin_morph_reference(mesh, skin_mats, weights) -> tuple[np.ndarray, np.ndarray]:
    """Numpy reference of :func:`skin_morph` (through :func:`skin_reference`)."""
    return skin_reference(_morphed_mesh(mesh, weights), skin_mats)


def pose_positions(character, clip_name, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Skinned (positions, normals) of ``character`` playing ``clip_name`` at time ``t``,
    its morph targets (if any) at the clip's weights applied first (:func:`skin_morph`).

    ``clip_name`` may also be a clip index. Returns (V, 3) float64 arrays.
    """
    clip = character.clip(clip_name)
    mats = character.skeleton.skinning_matrices(*clip.sample(character.skeleton, t))
    mt = character.mesh.morph
    if mt is None:
        return skin(character.mesh, mats)
    return skin_morph(character.mesh, mats, clip.morph_weights(mt, np.array([t]))[0])
