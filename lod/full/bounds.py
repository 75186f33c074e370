"""Bounds that hold over a whole animation: per baked frame the skinned mesh's
axis-aligned box (a numba kernel beside a numpy reference, in bounded scratch
memory) and the sphere around all of them, used to cull an instance whatever
its animation time.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

#: bytes of float64 scratch the bounds computation may hold at once
BOUNDS_SCRATCH_BYTES = 48 * 1024 * 1024

# ---------------------------------------------------------------------------- bounds
def _sphere_from_aabb(aabb: np.ndarray) -> np.ndarray:
    """Sphere (cx, cy, cz, r) float64 around an AABB (2, 3)."""
    lo, hi = np.asarray(aabb, np.float64)
    c = 0.5 * (lo + hi)
    return np.concatenate([c, [0.5 * float(np.linalg.norm(hi - lo))]])


def _sphere_of_points(points: np.ndarray) -> np.ndarray:
    """Sphere centred on the AABB centre of ``points`` (N, 3) with the exact max distance."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros(4)
    c = 0.5 * (p.min(0) + p.max(0))
    r = float(np.sqrt(((p - c) ** 2).sum(1).max()))
    return np.concatenate([c, [r]])


def skinned_frame_aabbs(positions, joints, weights, mats, scratch_bytes: int = BOUNDS_SCRATCH_BYTES) -> np.ndarray:
    """Model-space AABB of the LBS-skinned mesh at every frame.

    Parameters
    ----------
    positions : (V, 3) float bind-pose positions
    joints : (V, 4) int joint indices; weights : (V, 4) float
    mats : (F, J, 3, 4) float skinning matrices (top three rows)
    scratch_bytes : bound on the float64 scratch held at once; frames are
        processed in chunks of ``scratch_bytes / (24 V)``.

    Returns
    -------
    (F, 2, 3) float64 (min, max) per frame.

    Notes
    -----
    Per-joint batching: for each influence slot and each joint, the vertices
    influenced by that joint are transformed by the joint's matrices of the
    whole frame chunk in one einsum and accumulated, so the work is
    O(F * V * 4) and memory O(chunk * V) regardless of the joint count.
    """
    p = np.asarray(positions, np.float64)
    jn = np.asarray(joints, np.int64)
    w = np.asarray(weights, np.float64)
    m = np.asarray(mats, np.float64)
    F = m.shape[0]
    V = p.shape[0]
    out = np.zeros((F, 2, 3))
    if V == 0 or F == 0:
        return out
    # group (slot, joint) -> vertices once
    groups = []
    for k in range(jn.shape[1]):
        sel = np.flatnonzero(w[:, k] != 0.0)
        if sel.size == 0:
            continue
        order = np.argsort(jn[sel, k], kind="stable")
        sel = sel[order]
        js = jn[sel, k]
        cut = np.flatnonzero(np.diff(js)) + 1
        for part in np.split(np.arange(sel.size), cut):
            vs = sel[part]
            groups.append((int(js[part[0]]), vs, p[vs], w[vs, k][None, :, None]))
    chunk = max(1, int(scratch_bytes // max(1, 24 * V)))
    for f0 in range(0, F, chunk):
        f1 = min(F, f0 + chunk)
        acc = np.zeros((f1 - f0, V, 3))
        for j, vs, pv, wv in groups:
            mj = m[f0:f1, j]  # (f, 3, 4)
            acc[:, vs] += wv * (np.einsum("fab,vb->fva", mj[:, :, :3], pv) + mj[:, None, :, 3])
        out[f0:f1, 0] = acc.min(axis=1)
        out[f0:f1, 1] = acc.max(axis=1)
    return out


@njit(cache=True, parallel=True)
def _frame_aabbs_kernel(p, jn, w, m, out):  # pragma: no cover - compiled
    F = m.shape[0]
    V = p.shape[0]
    K = jn.shape[1]
    for f in prange(F):
        lo0 = lo1 = lo2 = np.inf
        hi0 = hi1 = hi2 = -np.inf
        for v in range(V):
            x = p[v, 0]
            y = p[v, 1]
            z = p[v, 2]
            q0 = 0.0
            q1 = 0.0
            q2 = 0.0
            for k in range(K):
                wk = w[v, k]
                if wk != 0.0:
                    j = jn[v, k]
                    q0 += wk * (m[f, j, 0, 0] * x + m[f, j, 0, 1] * y + m[f, j, 0, 2] * z + m[f, j, 0, 3])
                    q1 += wk * (m[f, j, 1, 0] * x + m[f, j, 1, 1] * y + m[f, j, 1, 2] * z + m[f, j, 1, 3])
                    q2 += wk * (m[f, j, 2, 0] * x + m[f, j, 2, 1] * y + m[f, j, 2, 2] * z + m[f, j, 2, 3])
            lo0 = min(lo0, q0)
            lo1 = min(lo1, q1)
            lo2 = min(lo2, q2)
            hi0 = max(hi0, q0)
            hi1 = max(hi1, q1)
            hi2 = max(hi2, q2)
        out[f, 0, 0] = lo0
        out[f, 0, 1] = lo1
        out[f, 0, 2] = lo2
        out[f, 1, 0] = hi0
        out[f, 1, 1] = hi1
        out[f, 1, 2] = hi2
    return out


def frame_aabbs(positions, joints, weights, mats) -> np.ndarray:
    """Per-frame AABBs of the LBS-skinned mesh, (F, 2, 3) float64 (numba kernel,
    parallel over frames); same contract as :func:`skinned_frame_aabbs`, the
    vectorised numpy reference it is tested against."""
    p = np.ascontiguousarray(positions, np.float64)
    jn = np.ascontiguousarray(joints, np.int64)
    w = np.ascontiguousarray(weights, np.float64)
    m = np.ascontiguousarray(mats, np.float64)
    out = np.zeros((m.shape[0], 2, 3))
    if p.shape[0] == 0 or m.shape[0] == 0:
        return out
    return _frame_aabbs_kernel(p, jn, w, m, out)


def _skin_all_frames_sphere(frame_aabb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Clip AABB (2,3) and sphere (4,) from per-frame AABBs (F, 2, 3).

    The sphere is centred on the union box; its radius is the largest distance
    to the farthest corner of any frame's box, which contains every vertex of
    that frame and is never larger than the union box's half diagonal.
    """
    lo = frame_aabb[:, 0].min(0)
    hi = frame_aabb[:, 1].max(0)
    c = 0.5 * (lo + hi)
    far = np.maximum(np.abs(frame_aabb[:, 0] - c), np.abs(frame_aabb[:, 1] - c))
    r = float(np.sqrt((far ** 2).sum(1)).max())
    return np.stack([lo, hi]), np.concatenate([c, [r]])
