"""Poses that follow the clip: how many, and which, skinned poses a clip is baked to.

Mode "points" draws a skinned character as a keyframe animation (Wand & Straßer
2002, §3): poses baked at a few times per clip, linearly interpolated between
them. A fixed count per clip (the earlier ``keyframes = 9``) gives a 1 s walk a
pose every 0.1 s but a 35 s dance one every 4 s, between which the interpolated
mesh dances another dance. Here each clip gets the fewest poses whose
interpolation stays within a bound of the skinned animation.

Error measure (the *pose error*): the largest distance of any vertex between the
linear interpolation of the two baked poses around time t and the skinned mesh
at t (skin ∘ morph when the mesh has morph targets, as ``bake_skinned`` bakes), over dense sample times ``t`` (:data:`SAMPLE_FPS` per second, at least
:data:`MIN_SAMPLES` per clip).

Selection (greedy top-down refinement, the Douglas–Peucker scheme applied to a
pose curve): start from the first sample (and the last one for a clip that does
not loop), then repeatedly split the interval of largest error at its worst
sample until every interval is within the bound or ``max_poses`` is reached. Key
times are therefore not evenly spaced: a clip that holds still gets two poses, a
varied passage gets many. The search runs on at most :data:`SEARCH_VERTICES`
vertices (evenly strided); the result is then verified on every vertex, and
intervals that fail are split further.

The loop point: a looping clip that does not end where it starts (a humanoid's
run jumps 0.17 m there) jumps in full detail too, within the last baked frame.
The finest interval, from the last sample to the clip's end, is that jump: it is
drawn as full detail draws it and is not counted as pose error. Coarser intervals
that wrap through the loop point are measured on their samples before it.
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from lod.points.config import POINTS_MAX_POSES
from sim.errors import require_float32

#: dense sample times per second of clip at which the pose error is measured
SAMPLE_FPS = 30.0
#: fewest sample times per clip (a short clip is still sampled densely)
MIN_SAMPLES = 16
#: vertices the search measures (evenly strided); every vertex is verified after
SEARCH_VERTICES = 4096
#: samples whose interpolation error is evaluated at once (bounds the scratch memory)
CHUNK = 64


@dataclass
class ClipPoses:
    """The baked poses of one clip.

    times : (K,) float64 key times in [0, duration], increasing, times[0] = 0
    error : float, metres: the largest pose error over the clip's samples
        (the loop jump excluded, see the module docstring)
    bound : float, metres: the bound the selection aimed at (inf: fixed count)
    capped : True when ``max_poses`` stopped the refinement above the bound
    """

    times: np.ndarray
    error: float
    bound: float
    capped: bool = False


def character_extent(character) -> float:
    """Largest side of the rest-pose bounding box (metres), > 0."""
    p = np.asarray(character.mesh.positions, np.float64)
    if p.size == 0:
        return 1.0
    ext = float(np.max(p.max(axis=0) - p.min(axis=0)))
    return ext if np.isfinite(ext) and ext > 0.0 else 1.0


def sample_times(clip) -> np.ndarray:
    """The dense sample times of a clip: [0, d) for a looping clip (the interval
    from the last to d wraps to 0), [0, d] otherwise."""
    d = float(clip.duration)
    if not (d > 0.0) or not np.isfinite(d):
        return np.zeros(1)
    n = max(MIN_SAMPLES, int(math.ceil(d * SAMPLE_FPS)))
    if clip.loop:
        return d * np.arange(n, dtype=np.float64) / n
    return np.linspace(0.0, d, n + 1)


def _skin_positions(mats: np.ndarray, joints: np.ndarray, weights: np.ndarray, ph: np.ndarray) -> np.ndarray:
    """(N, m, 3) linear-blend-skinned positions of m vertices at N poses.

    mats (N, J, 4, 4); joints (m, 4) int; weights (m, 4); ph (m, 4) homogeneous rest positions."""
    out = np.empty((mats.shape[0], ph.shape[0], 3), np.float64)
    for i in range(mats.shape[0]):
        M = np.einsum("vk,vkij->vij", weights, mats[i][joints][:, :, :3, :])
        out[i] = np.einsum("vij,vj->vi", M, ph)
    return out


def _spacing(clip) -> float:
    """Seconds between two of the clip's dense samples (:func:`sample_times`)."""
    d = float(clip.duration)
    return d / max(1, sample_times(clip).shape[0] - (0 if clip.loop else 1)) if d > 0.0 and np.isfinite(d) else 0.0


def _loop_jump(curve, i: int, j: int) -> bool:
    """True for an interval that wraps through the loop point and is no longer
    than one sample spacing: the clip's own jump (module docstring)."""
    return curve.loop and j == curve.n and curve.d + curve.S[0] - curve.S[i] <= curve.spacing * (1 + 1e-9)


class _Curve:
    """Skinned positions of a vertex subset at the sample times, and the error
    of interpolating between two of them."""

    def __init__(self, character, clip, S: np.ndarray, vertices: np.ndarray | None):
        mesh = character.mesh
        idx = slice(None) if vertices is None else vertices
        p = np.asarray(mesh.positions, np.float64)[idx]
        self.ph = np.concatenate([p, np.ones((p.shape[0], 1))], axis=1)
        self.joints = np.asarray(mesh.joints, np.int64)[idx]
        self.weights = np.asarray(mesh.weights, np.float64)[idx]
        self.S, self.loop, self.d = S, bool(clip.loop), float(clip.duration)
        self.mats = clip.skinning_matrices(character.skeleton, S)
        self.spacing = _spacing(clip)
        morph = getattr(mesh, "morph", None)
        if morph is not None and morph.n_targets:
            dw = clip.morph_weights(morph, S) - np.asarray(morph.default_weights, np.float64)[None]  # (N, M)
            dp = np.asarray(morph.positions, np.float64)[:, idx]  # (M, m, 3)
        self.P = np.empty((S.shape[0], p.shape[0], 3), np.float32)
        for i in range(S.shape[0]):  # one sample at a time: no (samples, vertices) float64 array
            ph = self.ph
            if morph is not None and morph.n_targets:  # skin ∘ morph (glTF 2.0 §3.7.2.2): morph the bind pose first
                ph = np.concatenate([p + np.einsum("k,kvc->vc", dw[i], dp), np.ones((p.shape[0], 1))], axis=1)
            q = _skin_positions(self.mats[i:i + 1], self.joints, self.weights, ph)[0]
            # the same one-sentence error bake_skinned gives, before any float32 cast warns
            require_float32(character, f"clip {clip.name!r}: skinned positions", q)
            self.P[i] = q

    @property
    def n(self) -> int:
        return self.S.shape[0]

    def interval_error(self, i: int, j: int) -> tuple[float, int]:
        """(largest error, worst sample index) of interpolating samples i -> j
        (j > i; j == n means sample 0 after the loop point)."""
        if j - i < 2 or _loop_jump(self, i, j):
            return 0.0, -1
        a = self.P[i].astype(np.float64)
        b = self.P[j % self.n].astype(np.float64)
        t0 = self.S[i]
        t1 = self.S[j] if j < self.n else self.d + self.S[0]
        best, arg = -1.0, -1
        for c0 in range(i + 1, j, CHUNK):  # in chunks: a long first interval holds half the clip's samples
            ks = np.arange(c0, min(c0 + CHUNK, j))
            u = (self.S[ks] - t0) / (t1 - t0)
            lerp = (1.0 - u)[:, None, None] * a[None] + u[:, None, None] * b[None]
            err = np.linalg.norm(lerp - self.P[ks], axis=2).max(axis=1) if ks.size and a.size else np.zeros(ks.size)
            w = int(np.argmax(err))
            e = float(err[w]) if np.isfinite(err[w]) else math.inf
            if e > best:
                best, arg = e, int(ks[w])
        return best, arg


class _StreamCurve:
    """:class:`_Curve` of every vertex, skinned on demand (no (samples, vertices)
    array: a 60 s clip of a 60 K-vertex character would need 1.3 GB)."""

    def __init__(self, character, clip, S: np.ndarray):
        self.character, self.S, self.loop, self.d = character, S, bool(clip.loop), float(clip.duration)
        self.name, self.spacing = clip.name, _spacing(clip)
        self.mats = clip.skinning_matrices(character.skeleton, S)
        morph = getattr(character.mesh, "morph", None)
        self.weights = clip.morph_weights(morph, S) if morph is not None and morph.n_targets else None
        self._keys: dict = {}

    @property
    def n(self) -> int:
        return self.S.shape[0]

    def _pose(self, k: int) -> np.ndarray:
        from sim.skinning import skin, skin_morph

        if self.weights is not None:
            p = skin_morph(self.character.mesh, self.mats[k], self.weights[k])[0]
        else:
            p = skin(self.character.mesh, self.mats[k])[0]
        require_float32(self.character, f"clip {self.name!r}: skinned positions", p)
        return p

    def _key(self, k: int) -> np.ndarray:
        if k not in self._keys:
            self._keys[k] = self._pose(k)
        return self._keys[k]

    def interval_error(self, i: int, j: int) -> tuple[float, int]:
        if j - i < 2 or _loop_jump(self, i, j):
            return 0.0, -1
        a, b = self._key(i), self._key(j % self.n)
        t0 = self.S[i]
        t1 = self.S[j] if j < self.n else self.d + self.S[0]
        best, arg = -1.0, -1
        for k in range(i + 1, j):
            u = (self.S[k] - t0) / (t1 - t0)
            d = np.linalg.norm((1.0 - u) * a + u * b - self._pose(k), axis=1)
            e = float(d.max()) if d.size else 0.0
            e = e if np.isfinite(e) else math.inf
            if e > best:
                best, arg = e, k
        return best, arg


def _refine(curve, keys: list, bound: float, max_poses: int) -> tuple[list, bool, float]:
    """Split the worst interval at its worst sample until all are within
    ``bound`` or ``max_poses`` keys exist. keys: sorted sample indices.
    Returns (sorted keys, capped, the largest interval error left)."""
    ends = keys[1:] + ([curve.n] if curve.loop else [])
    heap = []
    for i, j in zip(keys, ends):
        e, k = curve.interval_error(i, j)
        heapq.heappush(heap, (-e, i, j, k))
    keys = set(keys)
    while heap and -heap[0][0] > bound:
        if len(keys) >= max_poses:
            return sorted(keys), True, -heap[0][0]
        _, i, j, k = heapq.heappop(heap)
        keys.add(k)
        for a, b in ((i, k), (k, j)):
            e, w = curve.interval_error(a, b)
            heapq.heappush(heap, (-e, a, b, w))
    return sorted(keys), False, (-heap[0][0] if heap else 0.0)


def clip_error(character, clip, times: np.ndarray) -> tuple[float, list]:
    """Largest pose error (every vertex) of poses baked at ``times`` over the
    clip's dense samples, and per key interval (index of the key it starts at)
    the worst sample time whose error exceeds 0, as [(error, interval, t)].

    The samples are :func:`sample_times` plus the keys themselves."""
    S = np.union1d(sample_times(clip), np.asarray(times, np.float64))
    keys = np.searchsorted(S, np.asarray(times, np.float64))
    V = int(np.asarray(character.mesh.positions).shape[0])
    curve = _Curve(character, clip, S, None) if V <= SEARCH_VERTICES else _StreamCurve(character, clip, S)
    ends = list(keys[1:]) + ([curve.n] if curve.loop else [])
    out, worst = [], 0.0
    for q, (i, j) in enumerate(zip(keys, ends)):
        e, k = curve.interval_error(int(i), int(j))
        worst = max(worst, e)
        if k >= 0:
            out.append((e, q, float(S[k])))
    return worst, out


def choose_poses(character, clip, bound: float, max_poses: int = POINTS_MAX_POSES) -> ClipPoses:
    """The fewest poses (greedy) keeping the pose error of ``clip`` within ``bound`` metres.

    Parameters
    ----------
    character : sim.character.SkinnedCharacter
    clip : sim.clip.Clip of that character
    bound : float > 0, metres
    max_poses : int >= 2, the cap per clip

    Returns
    -------
    ClipPoses (at least 2 poses for a clip of positive duration; at most ``max_poses``)
    """
    if not (math.isfinite(float(bound)) and float(bound) > 0.0):
        raise ValueError(f"pose error bound: expected a positive number of metres, got {bound!r}")
    max_poses = max(2, int(max_poses))
    S = sample_times(clip)
    if S.shape[0] < 2 or np.asarray(character.mesh.positions).shape[0] == 0:
        return ClipPoses(np.zeros(1), 0.0, float(bound))
    V = int(np.asarray(character.mesh.positions).shape[0])
    sub = None if V <= SEARCH_VERTICES else np.unique(np.linspace(0, V - 1, SEARCH_VERTICES).astype(np.int64))
    curve = _Curve(character, clip, S, sub)
    n = curve.n
    start = [0, n // 2] if clip.loop else [0, n - 1]
    keys, capped, err = _refine(curve, start, float(bound), max_poses)
    if sub is not None:  # verify on every vertex; split what the subset missed
        keys, capped, err = _refine(_StreamCurve(character, clip, S), keys, float(bound), max_poses)
    return ClipPoses(S[np.asarray(keys, np.int64)], float(err), float(bound), bool(capped and err > bound))


def uniform_poses(character, clip, count: int) -> ClipPoses:
    """``count`` evenly spaced poses (the explicit ``keyframes = N``), with their measured error."""
    d = float(clip.duration)
    n = max(int(count), 1)
    if not (d > 0.0) or n == 1:
        return ClipPoses(np.zeros(1), 0.0, math.inf)
    times = np.linspace(0.0, d, n, endpoint=not clip.loop)
    err, _ = clip_error(character, clip, times)
    return ClipPoses(times, float(err), math.inf)


def clip_poses(character, keyframes: int, pose_error: float, max_poses: int = POINTS_MAX_POSES) -> dict:
    """Clip name -> :class:`ClipPoses` for every clip of a skinned character:
    ``keyframes`` evenly spaced poses when > 0, else the fewest within
    ``pose_error`` times the character's extent (:func:`character_extent`).

    The result is kept on the character (keyed by the parameters, its mesh and
    clip objects): the memory guard and the build of one run ask for the same
    poses, and the search is the costly part for long clips."""
    key = (int(keyframes), float(pose_error), int(max_poses), id(character.mesh),
           tuple((n, id(c)) for n, c in character.clips.items()))
    memo = character.__dict__.setdefault("_clip_poses", {})
    if key not in memo:
        bound = float(pose_error) * character_extent(character)
        out = {}
        for name in character.clips:
            clip = character.clip(name)
            out[name] = (uniform_poses(character, clip, keyframes) if int(keyframes) > 0
                         else choose_poses(character, clip, bound, max_poses))
        memo.clear()  # one entry: the parameters of the run at hand
        memo[key] = out
    return dict(memo[key])


__all__ = ["ClipPoses", "MIN_SAMPLES", "SAMPLE_FPS", "SEARCH_VERTICES", "character_extent", "choose_poses",
           "clip_error", "clip_poses", "sample_times", "uniform_poses"]
