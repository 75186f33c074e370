"""Per frame, which agents the far tier draws, and their rows: one pass over the state's flat arrays, before any
other selection (issue 45).

An agent is *far* when its clip's whole bounding sphere (``FarTable.radius`` about ``centre``, times the agent's
scale) lies in front of the camera and projects to at most ``far_pixels`` across (its diameter times the
viewport scale over its depth along the view axis): Wand & Straßer 2002 §3.2's rule (stop where the samples'
spacing projects within the splat) for one sample standing for the whole agent. Far agents that the frustum
culls are dropped; the rest of the agents (near, or in no far table) go on to the mode's own selection.

Rows of a far agent (:class:`FarBatch`, one per character): camera-relative position (float64 subtraction first,
then float32) and scale, and one word ``heading (16 bits, turns) | clip << 16``. One numba kernel classifies
every agent in parallel (:func:`classify`, beside :func:`classify_numpy`), a second writes the rows of the far
ones (:func:`far_rows`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from lod.drawlist import DrawBatch

#: classes of :func:`classify`
CULLED, NEAR, FAR = 0, 1, 2
#: default largest projected diameter (pixels) of an agent drawn in the far tier
FAR_PIXELS = 2.0
#: heading quantisation of a row's word (steps per turn)
HEADING_STEPS = 65536


@dataclass
class FarBatch(DrawBatch):
    """The far agents of one character: ``instance_data`` (k, 4) float32 camera-relative position and scale
    (not the 16 floats of the other batches), ``words`` (k,) uint32 heading and clip."""

    words: np.ndarray | None = None


@njit(cache=True, inline="always")
def _class_one(px, py, pz, heading, scale, cx, cy, cz, r, planes, fwd, limit):  # pragma: no cover - compiled
    c, s = np.cos(heading), np.sin(heading)
    # sphere centre: the position plus the rotated, scaled model-space centre (pack.model_rows' rotation)
    x = px + (c * cx + s * cz) * scale
    y = py + cy * scale
    z = pz + (-s * cx + c * cz) * scale
    rad = r * abs(scale)
    for k in range(planes.shape[0]):
        if planes[k, 0] * x + planes[k, 1] * y + planes[k, 2] * z + planes[k, 3] < -rad:
            return CULLED
    depth = fwd[0] * x + fwd[1] * y + fwd[2] * z
    if depth > rad and 2.0 * rad <= limit * depth:
        return FAR
    return NEAR


@njit(cache=True, parallel=True)
def _classify_kernel(pos, origin, heading, scale, character, clip, radius, centre, planes, fwd, limit, out):  # pragma: no cover
    n = pos.shape[0]
    for i in prange(n):
        ch = character[i]
        cl = clip[i]
        if ch < 0 or ch >= radius.shape[0] or cl < 0 or cl >= radius.shape[1] or not radius[ch, cl] > 0.0:
            out[i] = NEAR  # no far table: the mode's own selection draws (or refuses) it
            continue
        h = heading[i] if np.isfinite(heading[i]) else 0.0
        out[i] = _class_one(pos[i, 0] - origin[0], pos[i, 1] - origin[1], pos[i, 2] - origin[2], h, scale[i],
                            centre[ch, cl, 0], centre[ch, cl, 1], centre[ch, cl, 2], radius[ch, cl], planes, fwd,
                            limit)


def classify(pos, origin, heading, scale, character, clip, radius, centre, planes, fwd, limit) -> np.ndarray:
    """(n,) uint8 class of every agent (CULLED, NEAR, FAR).

    pos (n, 3) float64 world; origin (3,) the camera position; heading, scale (n,); character, clip (n,) int;
    radius (C, K) float64 bounding radius of character C's clip K (0: no far table), centre (C, K, 3) its
    model-space centre; planes (6, 4) camera-relative frustum planes; fwd (3,) unit view direction; limit:
    the largest diameter over depth (``far_pixels / viewport_scale``).
    """
    out = np.empty(pos.shape[0], np.uint8)
    if pos.shape[0]:
        # the state's own dtypes (float32 scale, int32 character, int16 clip): no per-frame copies of them
        _classify_kernel(np.ascontiguousarray(pos, np.float64), np.asarray(origin, np.float64),
                         np.ascontiguousarray(heading), np.ascontiguousarray(scale),
                         np.ascontiguousarray(character), np.ascontiguousarray(clip),
                         np.ascontiguousarray(radius, np.float64), np.ascontiguousarray(centre, np.float64),
                         np.ascontiguousarray(planes, np.float64), np.asarray(fwd, np.float64), float(limit), out)
    return out


def classify_numpy(pos, origin, heading, scale, character, clip, radius, centre, planes, fwd, limit) -> np.ndarray:
    """Reference of :func:`classify` (plain numpy, same classes)."""
    n = pos.shape[0]
    ch = np.asarray(character, np.int64)
    cl = np.asarray(clip, np.int64)
    ok = (ch >= 0) & (ch < radius.shape[0]) & (cl >= 0) & (cl < radius.shape[1])
    r = np.where(ok, radius[np.clip(ch, 0, radius.shape[0] - 1), np.clip(cl, 0, radius.shape[1] - 1)], 0.0)
    ok &= r > 0.0
    cen = centre[np.clip(ch, 0, radius.shape[0] - 1), np.clip(cl, 0, radius.shape[1] - 1)]
    h = np.where(np.isfinite(heading), heading, 0.0)
    c, s = np.cos(h), np.sin(h)
    rel = np.asarray(pos, np.float64) - np.asarray(origin, np.float64)
    sc = np.asarray(scale, np.float64)
    x = rel[:, 0] + (c * cen[:, 0] + s * cen[:, 2]) * sc
    y = rel[:, 1] + cen[:, 1] * sc
    z = rel[:, 2] + (-s * cen[:, 0] + c * cen[:, 2]) * sc
    rad = r * np.abs(sc)
    p = np.stack([x, y, z], axis=1)
    inside = ~np.any(p @ planes[:, :3].T + planes[:, 3] < -rad[:, None], axis=1)
    depth = p @ np.asarray(fwd, np.float64)
    far = (depth > rad) & (2.0 * rad <= limit * depth)
    out = np.full(n, NEAR, np.uint8)
    out[ok & ~inside] = CULLED
    out[ok & inside & far] = FAR
    return out


@njit(cache=True, parallel=True)
def _rows_kernel(idx, pos, origin, heading, scale, clip, rows, words):  # pragma: no cover - compiled
    tau = 2.0 * np.pi
    for k in prange(idx.shape[0]):
        i = idx[k]
        for a in range(3):
            rows[k, a] = np.float32(pos[i, a] - origin[a])
        rows[k, 3] = np.float32(scale[i])
        h = heading[i] if np.isfinite(heading[i]) else 0.0
        q = int(np.floor((h / tau - np.floor(h / tau)) * HEADING_STEPS + 0.5)) % HEADING_STEPS
        words[k] = np.uint32(q) | (np.uint32(clip[i]) << np.uint32(16))


def far_rows(idx, pos, origin, heading, scale, clip) -> tuple[np.ndarray, np.ndarray]:
    """((k, 4) float32 rows, (k,) uint32 words) of the agents ``idx`` (see the module docstring)."""
    k = int(np.asarray(idx).shape[0])
    rows = np.empty((k, 4), np.float32)
    words = np.empty(k, np.uint32)
    if k:
        _rows_kernel(np.ascontiguousarray(idx, np.int64), np.ascontiguousarray(pos, np.float64),
                     np.asarray(origin, np.float64), np.ascontiguousarray(heading), np.ascontiguousarray(scale),
                     np.ascontiguousarray(clip), rows, words)
    return rows, words


class FarSplit:
    """The far tier's part of a frame's selection (see the module docstring).

    far_reps : list aligned with ``CrowdState.character``: each character's ``lod.far.rep.FarRep`` or None
        (that character is never drawn far)
    far_pixels : the largest projected diameter (pixels) drawn far; 0 turns the tier off
    """

    def __init__(self, far_reps, far_pixels: float = FAR_PIXELS):
        if not (np.isfinite(far_pixels) and far_pixels >= 0.0):
            raise ValueError(f"[lod] far_pixels: expected a number of pixels >= 0, got {far_pixels!r}")
        self.reps = list(far_reps)
        self.far_pixels = float(far_pixels)
        K = max([r.n_clips for r in self.reps if r is not None] or [0])
        self.radius = np.zeros((len(self.reps), max(K, 1)))
        self.centre = np.zeros((len(self.reps), max(K, 1), 3))
        for c, r in enumerate(self.reps):
            if r is None:
                continue
            for k, t in enumerate(r.tables):
                self.radius[c, k] = t.radius
                self.centre[c, k] = t.centre

    @property
    def uploads(self) -> list:
        """The far representations to upload (the characters that have one)."""
        return [r for r in self.reps if r is not None]

    @property
    def active(self) -> bool:
        return self.far_pixels > 0.0 and bool((self.radius > 0.0).any())

    def split(self, state, camera, size, vscale: float, planes) -> tuple[np.ndarray | None, list, int]:
        """(the agents the mode's own selection takes (None: all of them), the far batches, far agents
        culled). With the tier off or nothing far, every agent goes on."""
        n = int(state.n)
        if not self.active or not n:
            return None, [], 0
        origin = np.asarray(camera.position, np.float64)
        char, clip = state.character, state.clip
        cls = classify(state.position, origin, state.heading, state.scale, char, clip, self.radius, self.centre,
                       planes, np.asarray(camera.forward, np.float64), self.far_pixels / float(vscale))
        near = np.flatnonzero(cls == NEAR)
        if near.shape[0] == n:
            return None, [], 0
        far = np.flatnonzero(cls == FAR)
        culled = int(np.count_nonzero(cls == CULLED))
        batches = []
        if far.size:
            fc = np.asarray(char[far], np.int64) if len(self.reps) > 1 else None
            present = [0] if fc is None else np.flatnonzero(np.bincount(fc, minlength=len(self.reps))).tolist()
            for c in present:
                idx = far if fc is None else far[fc == c]
                rows, words = far_rows(idx, state.position, origin, state.heading, state.scale, clip)
                batches.append(FarBatch(self.reps[c].key, 0, idx.astype(np.int32), rows, points=int(idx.shape[0]),
                                        words=words))
        return near, batches, culled
