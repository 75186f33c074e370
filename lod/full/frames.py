"""The frames of a full-detail representation and its vertices posed at them: what the measurements of mode
points (``lod.points.deform``) and the far footprints (``lod.far``) read.

Frames (:class:`SkinnedFrames`, :class:`KeyframedFrames`): every baked row of a skinned representation
(``lod.full.reps.SkinnedRep``, each clip at the bake rate, what the GPU blends between), or the two ends of every
segment of a keyframed one (``lod.full.reps.KeyframedRep``, one triangle list for all segments). Posed vertex
positions of a frame (:meth:`SkinnedFrames.positions`; numba kernel beside :func:`pose_positions_numpy`): the
morph target weights of the row added to the rest positions, then linear blend skinning with the row's
matrices (``skin ∘ morph``, glTF 2.0 §3.7.2.2, the arithmetic of ``render/shaders/poses/targets.glsl`` and
``skinning.glsl``); keyframed, the segment's end positions. Measurements stream over the frames in chunks
(:func:`chunks`, :func:`row_chunks`), never a (frames, vertices) array.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

#: frames posed at once (bounds the scratch: frames x vertices x 3 float64; 12 MB for 31 K vertices)
FRAME_CHUNK = 16


# ---------------------------------------------------------------------------- frames
@dataclass
class SkinnedFrames:
    """The frames of a ``lod.full.reps.SkinnedRep``: its baked rows.

    rest (V, 3) float64 bind-pose positions (constant morph targets folded in), joints (V, 4) int64,
    weights (V, 4) float64, indices (T, 3) int64, jt (F, J, 3, 4) float32, targets: the rep's
    ``lod.full.targets.TargetTable`` or None."""

    rest: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    indices: np.ndarray
    jt: np.ndarray
    targets: object = None
    #: (F,) bool: row f and f + 1 belong to one clip (the GPU blends between them)
    paired: np.ndarray | None = None

    @classmethod
    def of(cls, rep) -> "SkinnedFrames":
        F = int(rep.joint_table.shape[0])
        paired = np.zeros(F, bool)
        for off, n in zip(np.asarray(rep.clip_offset, np.int64), np.asarray(rep.clip_frames, np.int64)):
            paired[int(off):int(off + n - 1)] = True
        return cls(np.asarray(rep.positions, np.float64), np.asarray(rep.joints, np.int64),
                   np.asarray(rep.weights, np.float64), np.asarray(rep.indices, np.int64).reshape(-1, 3),
                   np.ascontiguousarray(rep.joint_table, np.float32), getattr(rep, "targets", None), paired)

    @property
    def morphs(self) -> bool:
        return self.targets is not None and bool(self.targets.n_targets)

    @property
    def n_frames(self) -> int:
        return int(self.jt.shape[0])

    def _target_arrays(self):
        t = self.targets
        if t is None or not t.n_targets:
            V = self.rest.shape[0]
            return (np.zeros(V, np.int64), np.zeros(V, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)),
                    np.zeros((self.n_frames, 1)))
        return (np.asarray(t.first, np.int64), np.asarray(t.count, np.int64), np.asarray(t.column, np.int64),
                np.asarray(t.dpos, np.float64), np.asarray(t.weights, np.float64))

    def positions(self, rows, vertices=None, weight_rows=None) -> np.ndarray:
        """(n, m, 3) float64 posed positions of ``vertices`` (None: all) at baked ``rows`` (numba); the morph
        weights of ``weight_rows`` (default ``rows``)."""
        rows = np.ascontiguousarray(rows, np.int64).reshape(-1)
        wrows = rows if weight_rows is None else np.ascontiguousarray(weight_rows, np.int64).reshape(-1)
        v = np.arange(self.rest.shape[0]) if vertices is None else np.asarray(vertices, np.int64)
        out = np.empty((rows.shape[0], v.shape[0], 3))
        if rows.size and v.size:
            _pose_kernel(self.rest, self.joints, self.weights, self.jt, rows, wrows, np.ascontiguousarray(v),
                         *self._target_arrays(), out)
        return out

    def control_points(self, rows) -> np.ndarray:
        """(n, V, 3): between rows f and f + 1 the GPU blends the matrices M and the morphed positions q with
        one factor a, so a vertex follows the quadratic Bezier curve M0 q0 -> M1 q1 whose middle control point
        is (M0 q1 + M1 q0) / 2 (``lod.full.targets``); this is that point for each row f of ``rows``."""
        rows = np.asarray(rows, np.int64).reshape(-1)
        return 0.5 * (self.positions(rows, weight_rows=rows + 1) + self.positions(rows + 1, weight_rows=rows))

    def joint_inverses(self, rows) -> tuple[np.ndarray, np.ndarray]:
        """(inv (n, J, 3, 4) float64, ok (J,) bool): the inverse skinning matrices at ``rows`` and whether
        every one of them was invertible (a joint scaled to zero somewhere is not a usable frame)."""
        m = np.asarray(self.jt[np.asarray(rows, np.int64)], np.float64)
        A, t = m[..., :3], m[..., 3]
        det = np.linalg.det(A)
        scale = np.abs(A).max(axis=(-2, -1)) ** 3
        good = np.isfinite(det) & (np.abs(det) > 1e-9 * np.maximum(scale, 1e-30))
        Ai = np.linalg.inv(np.where(good[..., None, None], A, np.eye(3)))
        inv = np.concatenate([Ai, -np.einsum("...ij,...j->...i", Ai, t)[..., None]], axis=-1)
        return inv, good.all(axis=0)


@dataclass
class KeyframedFrames:
    """The frames of a keyframed character with one triangle list: frame ``2 s`` is segment s's start,
    ``2 s + 1`` its end. rest = frame 0; positions0 / positions1 the KeyframedRep's; vbase (S,) first
    vertex of each segment; V vertices per segment; indices (T, 3) local."""

    positions0: np.ndarray
    positions1: np.ndarray
    vbase: np.ndarray
    V: int
    indices: np.ndarray

    @property
    def n_frames(self) -> int:
        return 2 * int(self.vbase.shape[0])

    @property
    def rest(self) -> np.ndarray:
        return self.positions(np.array([0]))[0]

    def positions(self, rows, vertices=None) -> np.ndarray:
        rows = np.asarray(rows, np.int64).reshape(-1)
        v = np.arange(self.V) if vertices is None else np.asarray(vertices, np.int64)
        out = np.empty((rows.shape[0], v.shape[0], 3))
        for k, f in enumerate(rows.tolist()):
            src = self.positions0 if f % 2 == 0 else self.positions1
            out[k] = np.asarray(src[int(self.vbase[f // 2]) + v], np.float64)
        return out


def chunks(n: int, size: int = FRAME_CHUNK):
    """Row ranges [a, b) of ``n`` frames, ``size`` at a time."""
    for a in range(0, n, size):
        yield a, min(n, a + size)


def row_chunks(frames, rows=None, size: int = FRAME_CHUNK):
    """The frame rows ``rows`` (None: all of ``frames``), ``size`` at a time, as int64 arrays."""
    rows = np.arange(frames.n_frames) if rows is None else np.asarray(rows, np.int64).reshape(-1)
    for a in range(0, rows.shape[0], size):
        yield rows[a:a + size]


# ---------------------------------------------------------------------------- posing
@njit(cache=True, parallel=True)
def _pose_kernel(rest, jn, w, jt, rows, wrows, verts, tfirst, tcount, tcol, tdpos, tw, out):  # pragma: no cover
    for k in prange(rows.shape[0]):
        f = rows[k]
        fw = wrows[k]
        for q in range(verts.shape[0]):
            v = verts[q]
            x = rest[v, 0]
            y = rest[v, 1]
            z = rest[v, 2]
            for e in range(tfirst[v], tfirst[v] + tcount[v]):  # morph first (targets.glsl targets_apply)
                ww = tw[fw, tcol[e]]
                x += ww * tdpos[e, 0]
                y += ww * tdpos[e, 1]
                z += ww * tdpos[e, 2]
            for r in range(3):
                acc = 0.0
                for i in range(4):
                    wi = w[v, i]
                    if wi != 0.0:
                        j = jn[v, i]
                        acc += wi * (jt[f, j, r, 0] * x + jt[f, j, r, 1] * y + jt[f, j, r, 2] * z + jt[f, j, r, 3])
                out[k, q, r] = acc


def pose_positions_numpy(frames: SkinnedFrames, rows) -> np.ndarray:
    """Reference of :meth:`SkinnedFrames.positions` (every vertex)."""
    first, count, col, dpos, tw = frames._target_arrays()
    out = []
    for f in np.asarray(rows, np.int64).reshape(-1).tolist():
        q = frames.rest.copy()
        for v in np.flatnonzero(count):
            e = slice(first[v], first[v] + count[v])
            q[v] += (tw[f, col[e]][:, None] * dpos[e]).sum(0)
        m = np.einsum("vi,virc->vrc", frames.weights, np.asarray(frames.jt[f], np.float64)[frames.joints])
        out.append(np.einsum("vrc,vc->vr", m[:, :, :3], q) + m[:, :, 3])
    return np.array(out).reshape(-1, frames.rest.shape[0], 3)


__all__ = ["FRAME_CHUNK", "KeyframedFrames", "SkinnedFrames", "chunks", "pose_positions_numpy", "row_chunks"]
