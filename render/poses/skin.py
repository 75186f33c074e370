"""CPU side of the pose cache (``render/poses/cache.py``): numba kernels beside plain numpy references.

- :func:`blend_palettes`: the joint palette of each distinct pose, blended once per pose between the two
  baked rows around its frame coordinate (the blend ``shaders/poses/palette.vert`` does per copy; for a pose on
  a key, a copy of the row);
- :func:`blend_weights`: the morph-target weight offsets of each pose, the same blend over
  ``TargetTable.weights`` (``shaders/poses/targets.glsl``);
- :func:`skin_poses`: the vertices of every pose, morphed then linear-blend skinned, normals through the
  inverse transpose of the blended matrix (cofactor times the sign of the determinant; ``sim/skinning.py``
  is the reference of both). The numba alternative to the compute pass ``shaders/poses/pose_skin.comp``
  (``PoseCache.skinning = "numba"``; scripts/bench_full_detail.md measures both).

A frame coordinate ``f`` reads rows ``f0 = clamp(floor(f), 0, F - 1)`` and ``f1 = min(f0 + 1, F - 1)`` with
weight ``a = f - floor(f)`` (``skinning.glsl frame_pair``), blended as GLSL's ``mix`` in float32.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

#: floats per posed vertex: position, 1, unit normal, 0 (``shaders/poses/posed.glsl``)
POSED_FLOATS = 8
#: floats of blended palettes from which the blend runs in parallel (below: serial, no thread wake-up;
#: a frame's poses at the key rate are typically a few hundred x 30 joints x 12 floats)
BLEND_PARALLEL_MIN = 1 << 20


def _pairs(frames: np.ndarray, n_rows: int):
    f = np.asarray(frames, np.float64)
    fl = np.floor(f)
    f0 = np.clip(fl, 0, n_rows - 1).astype(np.int64)
    f1 = np.minimum(f0 + 1, n_rows - 1)
    return f0, f1, (f - fl).astype(np.float32)


def blend_palettes_numpy(table: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Reference of :func:`blend_palettes`."""
    t = np.asarray(table, np.float32)
    f0, f1, a = _pairs(frames, t.shape[0])
    a = a[:, None, None, None]
    return (t[f0] * (np.float32(1.0) - a) + t[f1] * a).astype(np.float32)


@njit(cache=True, inline="always")
def _blend_row(p, table, f0, f1, a, out):  # pragma: no cover - compiled
    x = a[p]
    y = np.float32(1.0) - x
    r0 = table[f0[p]]
    r1 = table[f1[p]]
    for i in range(out.shape[1]):
        out[p, i] = r0[i] * y + r1[i] * x


@njit(cache=True)
def _blend_serial(table, f0, f1, a, out):  # pragma: no cover - compiled
    for p in range(out.shape[0]):
        _blend_row(p, table, f0, f1, a, out)


@njit(cache=True, parallel=True)
def _blend_parallel(table, f0, f1, a, out):  # pragma: no cover - compiled
    for p in prange(out.shape[0]):  # each pose writes only its own row
        _blend_row(p, table, f0, f1, a, out)


def _blend_rows(table, f0, f1, a, out) -> None:
    (_blend_parallel if out.size >= BLEND_PARALLEL_MIN else _blend_serial)(table, f0, f1, a, out)


def blend_palettes(table: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(P, J, 3, 4) float32 palettes of the poses at frame coordinates ``frames`` (P,) from the baked
    joint table (F, J, 3, 4) (numba, parallel over poses)."""
    t = np.ascontiguousarray(table, np.float32)
    F, J = t.shape[0], t.shape[1]
    f0, f1, a = _pairs(frames, F)
    out = np.empty((f0.shape[0], J * 12), np.float32)
    if out.shape[0]:
        _blend_rows(t.reshape(F, J * 12), f0, f1, a, out)
    return out.reshape(-1, J, 3, 4)


def blend_weights(weights: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(P, M) float32 morph-target weight offsets of the poses (rows of ``TargetTable.weights`` (F, M) blended
    like the joint matrices)."""
    w = np.ascontiguousarray(weights, np.float32)
    f0, f1, a = _pairs(frames, w.shape[0])
    out = np.empty((f0.shape[0], w.shape[1]), np.float32)
    if out.size:
        _blend_rows(w, f0, f1, a, out)
    return out


@njit(cache=True, inline="always")
def _skin_one(p, v, pos, nrm, joints, weights, n_inf, pal, t_first, t_count, t_col, t_dpos, t_dnrm, pw,
              out):  # pragma: no cover - compiled
    x, y, z = pos[v, 0], pos[v, 1], pos[v, 2]
    nx, ny, nz = nrm[v, 0], nrm[v, 1], nrm[v, 2]
    if t_count.shape[0]:  # morph targets first (targets.glsl targets_apply)
        mx, my, mz = nx, ny, nz
        for e in range(t_first[v], t_first[v] + t_count[v]):
            w = pw[p, t_col[e]]
            if w == 0.0:
                continue
            x += w * t_dpos[e, 0]
            y += w * t_dpos[e, 1]
            z += w * t_dpos[e, 2]
            mx += w * t_dnrm[e, 0]
            my += w * t_dnrm[e, 1]
            mz += w * t_dnrm[e, 2]
        lm = mx * mx + my * my + mz * mz
        if lm > 1e-30:
            s = 1.0 / np.sqrt(lm)
            nx, ny, nz = mx * s, my * s, mz * s
    m = np.zeros(12, np.float32)
    for k in range(n_inf):
        w = weights[v, k]
        if w == 0.0:
            continue
        j = joints[v, k]
        for i in range(12):
            m[i] += w * pal[p, j, i]
    out[p, v, 0] = m[0] * x + m[1] * y + m[2] * z + m[3]
    out[p, v, 1] = m[4] * x + m[5] * y + m[6] * z + m[7]
    out[p, v, 2] = m[8] * x + m[9] * y + m[10] * z + m[11]
    out[p, v, 3] = 1.0
    # cofactor of the linear part: columns a0 = (m0, m4, m8), a1 = (m1, m5, m9), a2 = (m2, m6, m10)
    a0x, a0y, a0z = m[0], m[4], m[8]
    a1x, a1y, a1z = m[1], m[5], m[9]
    a2x, a2y, a2z = m[2], m[6], m[10]
    c0x, c0y, c0z = a1y * a2z - a1z * a2y, a1z * a2x - a1x * a2z, a1x * a2y - a1y * a2x
    c1x, c1y, c1z = a2y * a0z - a2z * a0y, a2z * a0x - a2x * a0z, a2x * a0y - a2y * a0x
    c2x, c2y, c2z = a0y * a1z - a0z * a1y, a0z * a1x - a0x * a1z, a0x * a1y - a0y * a1x
    det = a0x * c0x + a0y * c0y + a0z * c0z
    sg = 1.0 if det > 0.0 else (-1.0 if det < 0.0 else 0.0)
    ox = sg * (c0x * nx + c1x * ny + c2x * nz)
    oy = sg * (c0y * nx + c1y * ny + c2y * nz)
    oz = sg * (c0z * nx + c1z * ny + c2z * nz)
    lo = ox * ox + oy * oy + oz * oz
    if not (lo > 1e-30):
        ox, oy, oz = nx, ny, nz
        lo = ox * ox + oy * oy + oz * oz
        if not (lo > 1e-30):
            ox, oy, oz, lo = 0.0, 1.0, 0.0, 1.0
    s = 1.0 / np.sqrt(lo)
    out[p, v, 4] = ox * s
    out[p, v, 5] = oy * s
    out[p, v, 6] = oz * s
    out[p, v, 7] = 0.0


@njit(cache=True, parallel=True)
def _skin_kernel(pos, nrm, joints, weights, n_inf, pal, t_first, t_count, t_col, t_dpos, t_dnrm, pw,
                 out):  # pragma: no cover - compiled
    P, V = out.shape[0], out.shape[1]
    for q in prange(P * V):  # each (pose, vertex) writes only its own row
        _skin_one(q // V, q % V, pos, nrm, joints, weights, n_inf, pal, t_first, t_count, t_col, t_dpos, t_dnrm,
                  pw, out)


def _target_arrays(targets, frames):
    if targets is None:
        z = np.zeros(0, np.int32)
        return z, z, z, np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), np.zeros((1, 1), np.float32)
    return (np.ascontiguousarray(targets.first, np.int32), np.ascontiguousarray(targets.count, np.int32),
            np.ascontiguousarray(targets.column, np.int32), np.ascontiguousarray(targets.dpos, np.float32),
            np.ascontiguousarray(targets.dnrm, np.float32), blend_weights(targets.weights, frames))


def skin_poses(positions, normals, joints, weights, palettes, targets=None, frames=None) -> np.ndarray:
    """(P, V, 8) float32 posed vertices (position, 1, unit normal, 0) of every pose (numba, parallel).

    Parameters
    ----------
    positions, normals : (V, 3) bind pose; joints : (V, K) int; weights : (V, K) float (zeros skipped)
    palettes : (P, J, 3, 4) float32 (:func:`blend_palettes`)
    targets : lod.full.targets.TargetTable or None; frames : (P,) frame coordinates of the poses (their
        morph weights, :func:`blend_weights`; needed with targets)
    """
    pal = np.ascontiguousarray(palettes, np.float32)
    P, J = pal.shape[0], pal.shape[1]
    jn = np.ascontiguousarray(joints, np.int32)
    V = jn.shape[0]
    out = np.empty((P, V, POSED_FLOATS), np.float32)
    if P and V:
        tf, tc, tcol, tdp, tdn, pw = _target_arrays(targets, frames)
        _skin_kernel(np.ascontiguousarray(positions, np.float32), np.ascontiguousarray(normals, np.float32), jn,
                     np.ascontiguousarray(weights, np.float32), int(jn.shape[1]), pal.reshape(P, J, 12), tf, tc,
                     tcol, tdp, tdn, pw, out)
    return out


def skin_poses_numpy(positions, normals, joints, weights, palettes, targets=None, frames=None) -> np.ndarray:
    """Reference of :func:`skin_poses` (float64 numpy through ``sim.skinning``'s convention)."""
    pal = np.asarray(palettes, np.float64)
    P = pal.shape[0]
    V = np.asarray(positions).shape[0]
    out = np.zeros((P, V, POSED_FLOATS), np.float32)
    jn = np.asarray(joints, np.int64)
    w = np.asarray(weights, np.float64)
    for p in range(P):
        pos = np.asarray(positions, np.float64)
        n0 = np.asarray(normals, np.float64)
        if targets is not None:
            pos, m = targets.morph(pos, n0, blend_weights(targets.weights, np.asarray(frames)[p:p + 1])[0])
            lm = (m * m).sum(1, keepdims=True)
            n0 = np.where(lm > 1e-30, m / np.sqrt(np.where(lm > 1e-30, lm, 1.0)), n0)
        M = np.einsum("vk,vkab->vab", w, pal[p][jn])
        out[p, :, :3] = np.einsum("vab,vb->va", M[:, :, :3], pos) + M[:, :, 3]
        out[p, :, 3] = 1.0
        A = M[:, :, :3]
        C = np.stack([np.cross(A[:, :, 1], A[:, :, 2]), np.cross(A[:, :, 2], A[:, :, 0]),
                      np.cross(A[:, :, 0], A[:, :, 1])], axis=2)  # columns: the cofactor matrix
        n = np.sign(np.linalg.det(A))[:, None] * np.einsum("vab,vb->va", C, n0)
        ln = (n * n).sum(1)
        bad = ~(ln > 1e-30)
        n[bad] = n0[bad]
        ln = (n * n).sum(1)
        n[~(ln > 1e-30)] = (0.0, 1.0, 0.0)
        out[p, :, 4:7] = n / np.linalg.norm(n, axis=1, keepdims=True)
    return out
