"""``FarRep``: the far footprints (``lod.far.footprint``) of a character's clips, representation kind ``"far"``,
and the poses they are measured in.

A far rep is built from the character's full-detail representation (``lod.full.reps``: a ``SkinnedRep``'s
baked rows, a ``KeyframedRep``'s keyframes), so the footprint is the surface mode ``none`` draws. Only the clips
a scene plays are measured; the others get an empty table (an agent switched to one is drawn covering nothing
until the scene is rebuilt, which a scene that plays it never meets).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lod.far.cache import measured
from lod.far.footprint import POSES, FarTable, measure
from lod.full.frames import SkinnedFrames


def _blend_normals(rep, rows: np.ndarray) -> np.ndarray:
    """(len(rows), V, 3) rest normals through each vertex's blended skinning matrix at baked ``rows``
    (the rotation the renderer applies; morph-target normal deltas left out)."""
    jt = np.asarray(rep.joint_table, np.float64)
    j = np.asarray(rep.joints, np.int64)
    w = np.asarray(rep.weights, np.float64)
    n0 = np.asarray(rep.normals, np.float64)
    out = np.empty((rows.shape[0], n0.shape[0], 3))
    for k, r in enumerate(rows.tolist()):
        A = np.einsum("vi,vijk->vjk", w, jt[r][j][..., :3])  # (V, 3, 3)
        out[k] = np.einsum("vjk,vk->vj", A, n0)
    return out


def rest_positions(rep):
    """The rest-pose positions the renderer places a blob shadow by (``render.world.shadows.footprint``'s
    first: ``positions``, else ``positions0``)."""
    p = getattr(rep, "positions", None)
    return p if p is not None else getattr(rep, "positions0", None)


def clip_surfaces(rep, clip: int, count: int = POSES) -> list:
    """``count`` poses spread evenly over clip ``clip`` of a full-detail rep, as ``measure`` takes them:
    [(positions, normals, colours, indices)]. A clip with fewer frames (or keyframes) gives each once."""
    if rep.kind == "skinned":
        off, n = int(rep.clip_offset[clip]), int(rep.clip_frames[clip])
        last = n - 1 if (bool(rep.clip_loop[clip]) and n > 1) else n  # a loop's last row is its first
        rows = np.unique(off + (np.arange(count) * last) // max(count, 1)).astype(np.int64)
        P = SkinnedFrames.of(rep).positions(rows)
        N = _blend_normals(rep, rows)
        idx = np.asarray(rep.indices, np.int64).reshape(-1, 3)
        return [(P[k], N[k], rep.colors, idx) for k in range(rows.shape[0])]
    if rep.kind == "keyframed":
        a0, n = int(rep.anim_first_seg[clip]), int(rep.anim_n_segs[clip])
        segs = np.unique(a0 + (np.arange(count) * n) // max(count, 1))
        out = []
        for s in segs.tolist():
            a, b = int(rep.seg_first[s]) // 3, int(rep.seg_first[s] + rep.seg_count[s]) // 3
            idx = np.asarray(rep.indices[a:b], np.int64).reshape(-1, 3)
            if idx.size == 0:
                continue
            lo, hi = int(idx.min()), int(idx.max()) + 1
            out.append((rep.positions0[lo:hi], rep.normals0[lo:hi], rep.colors0[lo:hi], idx - lo))
        return out
    if rep.kind == "static":
        return [(rep.positions, rep.normals, rep.colors, np.asarray(rep.indices, np.int64).reshape(-1, 3))]
    raise TypeError(f"far footprint: cannot measure a representation of kind {rep.kind!r}")


def n_clips(rep) -> int:
    return int(rep.anim_first_seg.shape[0]) if rep.kind == "keyframed" else (
        1 if rep.kind == "static" else int(rep.clip_offset.shape[0]))


@dataclass
class FarRep:
    """The far footprint of every clip of one character (kind ``"far"``; the renderer's ``render.far``
    drawer uploads it).

    key : str, ``"far:<character>"``
    tables : list of FarTable, one per clip (CrowdState.clip indexes it)
    """

    key: str
    tables: list = field(default_factory=list)
    kind: str = "far"

    @property
    def n_clips(self) -> int:
        return len(self.tables)

    def radius(self) -> np.ndarray:
        """(clips,) bounding radius (m at scale 1) of each clip's poses."""
        return np.array([t.radius for t in self.tables], np.float64)


def empty_table() -> FarTable:
    return measure([])


def build_far_rep(full_rep, name: str, clips=None, count: int = POSES, cache: bool = True) -> FarRep:
    """The far rep of a character from its full-detail rep; ``clips``: None (all) or the clip indices a scene
    plays (the others get an empty table); ``cache``: read and write measured tables in ``lod.far.cache``."""
    n = n_clips(full_rep)
    played = set(range(n)) if clips is None else {int(c) for c in clips}
    rest = rest_positions(full_rep)
    tables = [measured(clip_surfaces(full_rep, c, count), cache, rest) if c in played else empty_table()
              for c in range(n)]
    return FarRep(f"far:{name}", tables)
