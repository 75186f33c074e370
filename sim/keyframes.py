"""Keyframe animations of triangle meshes (Wand & Straßer 2002, §3).

A keyframe animation is a sequence of triangle meshes of arbitrary topology.
Between consecutive keyframes k and k+1, every vertex is matched with a vertex
of the other keyframe and all vertex attributes move linearly. Triangles can
appear or vanish at a keyframe: a vertex of one keyframe blends to three
positions of the next (Fig. 1), so a new triangle grows out of a point.

The canonical form used by every later layer is the *segment*: for one pair of
keyframes, a vertex list where each vertex is a (source vertex in k,
destination vertex in k+1) pair, and one index buffer over those vertices.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Keyframe:
    """One keyframe mesh.

    positions : (V_k, 3) float32; normals : (V_k, 3) float32;
    colors : (V_k, 4) float32; indices : (T_k, 3) uint32.
    """

    positions: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    indices: np.ndarray


@dataclass
class Segment:
    """Vertex correspondences between keyframe k and k+1.

    src : (S,) int32, vertex of keyframe k for each segment vertex
    dst : (S,) int32, vertex of keyframe k+1 for each segment vertex
    indices : (T_s, 3) uint32 into the segment vertices (union of both
        keyframes' triangles; a triangle that exists only at one end collapses
        to a point at the other end).
    """

    src: np.ndarray
    dst: np.ndarray
    indices: np.ndarray


@dataclass
class KeyframeAnimation:
    """Keyframe meshes at times ``times`` with a segment per consecutive pair.

    times : (K,) float64 strictly increasing, seconds.
    keyframes : list of K Keyframe
    segments : list of K-1 Segment (K segments when ``loop``: the last pairs
        keyframe K-1 with keyframe 0, ending at ``duration``).
    duration : float; loop period when ``loop``.
    """

    name: str
    times: np.ndarray
    keyframes: list
    segments: list
    duration: float
    loop: bool = True

    @property
    def n_keyframes(self) -> int:
        return len(self.keyframes)

    def segment_edges(self) -> np.ndarray:
        """Start/end times of the segments, (n_segments + 1,) float64.

        When ``loop``, the last segment runs from ``times[-1]`` to
        ``times[0] + duration`` and pairs keyframe K-1 with keyframe 0.
        """
        times = np.asarray(self.times, np.float64)
        if self.loop:
            return np.append(times, times[0] + max(float(self.duration), float(times[-1] - times[0])))
        return times

    def locate(self, t: float) -> tuple[int, float]:
        """Segment index and local parameter u in [0, 1] at time t (seconds).

        Looping animations wrap t modulo ``duration`` (measured from
        ``times[0]``); others clamp to [times[0], times[-1]]. A non-looping
        single keyframe gives (0, 0.0) and has no segment.
        """
        edges = self.segment_edges()
        nseg = edges.shape[0] - 1
        t = float(t) if np.isfinite(t) else float(edges[0])
        if nseg <= 0:
            return 0, 0.0
        period = edges[-1] - edges[0]
        if self.loop and period > 0:
            t = edges[0] + np.mod(t - edges[0], period)
        t = min(max(t, edges[0]), edges[-1])
        k = int(np.clip(np.searchsorted(edges, t, side="right") - 1, 0, nseg - 1))
        span = edges[k + 1] - edges[k]
        u = float(np.clip((t - edges[k]) / span, 0.0, 1.0)) if span > 0 else 0.0
        return k, u

    def segment_keyframes(self, k: int) -> tuple[Keyframe, Keyframe]:
        """The (start, end) keyframes of segment k."""
        K = len(self.keyframes)
        return self.keyframes[k % K], self.keyframes[(k + 1) % K]

    def interpolate_segment(self, k: int, u: float):
        """Attributes of segment k at local parameter u (Wand & Straßer §3).

        Returns
        -------
        positions (S, 3) float32, normals (S, 3) float32 (unit; the start
        normal, else +Y, where the blend cancels), colors (S, 4) float32,
        indices (T_s, 3) uint32. At u = 0 (u = 1) the attributes equal the
        start (end) keyframe's values at each segment vertex's src (dst).
        """
        seg = self.segments[k]
        a, b = self.segment_keyframes(k)
        src = np.asarray(seg.src, np.int64)
        dst = np.asarray(seg.dst, np.int64)
        u = float(np.clip(u, 0.0, 1.0))
        lerp = lambda x, y: (1.0 - u) * np.asarray(x, np.float64)[src] + u * np.asarray(y, np.float64)[dst]  # noqa: E731
        pos = lerp(a.positions, b.positions)
        col = lerp(a.colors, b.colors)
        n = lerp(a.normals, b.normals)
        ln = np.linalg.norm(n, axis=1, keepdims=True)
        ok = ln > 1e-12
        n0 = np.asarray(a.normals, np.float64)[src]
        n = np.where(ok, n / np.where(ok, ln, 1.0), n0)
        ln0 = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.where(ln0 > 1e-12, n / np.where(ln0 > 1e-12, ln0, 1.0), (0.0, 1.0, 0.0))
        return (pos.astype(np.float32), n.astype(np.float32), col.astype(np.float32),
                np.asarray(seg.indices, np.uint32))

    def interpolate(self, t: float):
        """(positions (S,3), normals (S,3), colors (S,4), indices) of the segment active at t.

        float32 arrays, see :meth:`interpolate_segment`. A non-looping single
        keyframe returns that keyframe.
        """
        if not self.segments:
            kf = self.keyframes[0]
            return (np.asarray(kf.positions, np.float32), np.asarray(kf.normals, np.float32),
                    np.asarray(kf.colors, np.float32), np.asarray(kf.indices, np.uint32))
        k, u = self.locate(t)
        return self.interpolate_segment(k, u)


# --------------------------------------------------------------------------- builders

@dataclass
class Correspondence:
    """Vertex correspondences between keyframe k and k+1 (Wand & Straßer Fig. 1).

    pairs : (P, 2) int, (vertex of k, vertex of k+1) for surviving vertices;
        every vertex of a surviving triangle of k must appear exactly once as a
        source.
    appear : list of (triangle of k+1, vertex of k): the triangle grows out of
        that single vertex (its three segment vertices all start there).
    vanish : list of (triangle of k, vertex of k+1): the triangle shrinks into
        that vertex.

    The surviving triangles of k are all triangles not listed in ``vanish``;
    every triangle of k+1 not listed in ``appear`` must be the image of one of
    them under ``pairs``.
    """

    pairs: np.ndarray
    appear: list = field(default_factory=list)
    vanish: list = field(default_factory=list)


def _as_keyframe(m) -> Keyframe:
    if isinstance(m, Keyframe):
        return Keyframe(np.asarray(m.positions, np.float32), np.asarray(m.normals, np.float32),
                        np.asarray(m.colors, np.float32), np.asarray(m.indices, np.uint32))
    return Keyframe(np.asarray(m.positions, np.float32), np.asarray(m.ensure_normals(), np.float32),
                    np.asarray(m.vertex_colors(), np.float32), np.asarray(m.indices, np.uint32).reshape(-1, 3))


def identity_segment(kf: Keyframe) -> Segment:
    """Segment of two keyframes with the same vertices and triangles."""
    v = np.arange(kf.positions.shape[0], dtype=np.int32)
    return Segment(v, v.copy(), np.asarray(kf.indices, np.uint32))


def _segment(k: int, a: Keyframe, b: Keyframe, corr, where: str) -> Segment:
    if isinstance(corr, Segment):
        seg = Segment(np.asarray(corr.src, np.int32), np.asarray(corr.dst, np.int32), np.asarray(corr.indices, np.uint32))
    elif corr is None:
        if a.positions.shape[0] != b.positions.shape[0] or not np.array_equal(a.indices, b.indices):
            raise ValueError(f"{where}: keyframes {k} and {k + 1} differ in vertices or triangles; "
                             "give explicit correspondences (Correspondence or Segment) for this pair")
        return identity_segment(a)
    else:
        if isinstance(corr, dict):
            corr = Correspondence(**corr)
        pairs = np.asarray(corr.pairs, np.int64).reshape(-1, 2)
        ta = np.asarray(a.indices, np.int64)
        tb = np.asarray(b.indices, np.int64)
        Va, Vb = a.positions.shape[0], b.positions.shape[0]
        if pairs.size and (pairs[:, 0].min() < 0 or pairs[:, 0].max() >= Va or pairs[:, 1].min() < 0 or pairs[:, 1].max() >= Vb):
            raise ValueError(f"{where}: pairs must index vertices 0..{Va - 1} of keyframe {k} and 0..{Vb - 1} of keyframe {k + 1}")
        row = np.full(Va, -1, np.int64)
        counts = np.bincount(pairs[:, 0], minlength=Va) if pairs.size else np.zeros(Va, np.int64)
        row[pairs[:, 0]] = np.arange(pairs.shape[0])
        vanish = {int(t): int(v) for t, v in corr.vanish}
        appear = {int(t): int(v) for t, v in corr.appear}
        for t in vanish:
            if not 0 <= t < ta.shape[0]:
                raise ValueError(f"{where}: vanishing triangle {t} is not a triangle of keyframe {k}")
        for t in appear:
            if not 0 <= t < tb.shape[0]:
                raise ValueError(f"{where}: appearing triangle {t} is not a triangle of keyframe {k + 1}")
        keep = np.array([i for i in range(ta.shape[0]) if i not in vanish], np.int64)
        kept = ta[keep] if keep.size else np.zeros((0, 3), np.int64)
        if kept.size and (counts[kept] != 1).any():
            bad = int(kept[counts[kept] != 1][0])
            raise ValueError(f"{where}: vertex {bad} of keyframe {k} lies on a surviving triangle but has "
                             f"{int(counts[bad])} pairs (expected exactly 1)")
        tri_s = row[kept]
        # every triangle of k+1 that does not appear must be the image of a surviving triangle
        images = {tuple(sorted(x)) for x in pairs[tri_s, 1].tolist()} if tri_s.size else set()
        for i in range(tb.shape[0]):
            if i not in appear and tuple(sorted(tb[i].tolist())) not in images:
                raise ValueError(f"{where}: triangle {i} of keyframe {k + 1} is neither the image of a triangle "
                                 f"of keyframe {k} nor listed in appear")
        src, dst, tris = [pairs[:, 0]], [pairs[:, 1]], [tri_s]
        n = pairs.shape[0]
        for t, v in vanish.items():  # three vertices of k collapse into one vertex of k+1
            if not 0 <= v < Vb:
                raise ValueError(f"{where}: vanish target {v} is not a vertex of keyframe {k + 1}")
            src.append(ta[t]), dst.append(np.full(3, v)), tris.append(n + np.arange(3)[None])
            n += 3
        for t, v in appear.items():  # one vertex of k grows into a triangle of k+1
            if not 0 <= v < Va:
                raise ValueError(f"{where}: appear source {v} is not a vertex of keyframe {k}")
            src.append(np.full(3, v)), dst.append(tb[t]), tris.append(n + np.arange(3)[None])
            n += 3
        seg = Segment(np.concatenate(src).astype(np.int32), np.concatenate(dst).astype(np.int32),
                      np.concatenate(tris).astype(np.uint32).reshape(-1, 3))
    if seg.src.shape != seg.dst.shape or (seg.indices.size and seg.indices.max() >= seg.src.shape[0]):
        raise ValueError(f"{where}: segment src/dst lengths differ or indices exceed the segment vertices")
    if seg.src.size and (seg.src.max() >= a.positions.shape[0] or seg.dst.max() >= b.positions.shape[0]
                         or seg.src.min() < 0 or seg.dst.min() < 0):
        raise ValueError(f"{where}: segment src/dst outside the keyframes' vertices")
    return seg


def from_meshes(name: str, times, meshes, correspondences=None, loop: bool = True,
                duration: float | None = None) -> KeyframeAnimation:
    """Build a keyframe animation from meshes (Wand & Straßer 2002, §3, Fig. 1).

    Parameters
    ----------
    name : str
    times : (K,) strictly increasing seconds
    meshes : K sim.mesh.Mesh (or Keyframe); normals and colours are filled in
        when missing.
    correspondences : None, or a list with one entry per pair (K-1, or K when
        ``loop``; the last pairs keyframe K-1 with 0). None (globally or per
        pair) means identical vertices and triangles (identity mapping);
        otherwise a :class:`Correspondence` (or a dict with its fields) or a
        ready :class:`Segment`.
    loop : bool
    duration : float or None. None: ``times[-1] - times[0]`` plus, when
        looping, the mean key interval (or 1 s for a single keyframe).

    Raises
    ------
    ValueError naming the pair and what is inconsistent.
    """
    times = np.asarray(times, np.float64).reshape(-1)
    kfs = [_as_keyframe(m) for m in meshes]
    K = len(kfs)
    if K == 0 or times.shape[0] != K:
        raise ValueError(f"keyframe animation {name!r}: expected one time per mesh, got {times.shape[0]} times for {K} meshes")
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise ValueError(f"keyframe animation {name!r}: times must be finite and strictly increasing")
    if duration is None:
        span = float(times[-1] - times[0])
        duration = span + (span / (K - 1) if K > 1 else 1.0) if loop else span
    duration = float(duration)
    if loop and duration < times[-1] - times[0]:
        raise ValueError(f"keyframe animation {name!r}: duration {duration} is shorter than the keys' span")
    npairs = K if loop else K - 1
    if correspondences is None:
        correspondences = [None] * npairs
    correspondences = list(correspondences)
    if len(correspondences) != npairs:
        raise ValueError(f"keyframe animation {name!r}: expected {npairs} correspondences (one per keyframe pair), "
                         f"got {len(correspondences)}")
    segs = [_segment(k, kfs[k], kfs[(k + 1) % K], correspondences[k], f"keyframe animation {name!r}, pair {k}")
            for k in range(npairs)]
    return KeyframeAnimation(name, times, kfs, segs, duration, loop)


def bake_skinned(character, clip_name, times) -> KeyframeAnimation:
    """Bake a skinned clip into a constant-topology keyframe animation.

    Parameters
    ----------
    character : sim.character.SkinnedCharacter
    clip_name : str or int (clip index)
    times : (K,) seconds, or an int K for K evenly spaced keyframes over the
        clip (a looping clip does not repeat its first pose at ``duration``).

    Returns
    -------
    KeyframeAnimation with identity segments sharing the mesh's index buffer;
    its duration and loop flag are the clip's. A mesh with morph targets is
    morphed at the clip's weights before skinning (``sim.skinning.skin_morph``,
    glTF 2.0 §3.7.2.2), so every keyframe is the pose ``skin ∘ morph`` at its time.
    """
    from sim.errors import require_float32
    from sim.skinning import skin, skin_morph  # local: keyframes must not pull numba in by default

    clip = character.clip(clip_name) if hasattr(character, "clip") else character.clips[clip_name]
    d = float(clip.duration)
    if isinstance(times, (int, np.integer)):
        n = max(int(times), 1)
        times = np.linspace(0.0, d, n, endpoint=not clip.loop) if n > 1 else np.zeros(1)
    times = np.asarray(times, np.float64).reshape(-1)
    mats = clip.skinning_matrices(character.skeleton, times)
    colors = character.mesh.vertex_colors()
    idx = np.asarray(character.mesh.indices, np.uint32)
    mt = character.mesh.morph
    mw = clip.morph_weights(mt, times) if mt is not None else None
    kfs = []
    for i in range(times.shape[0]):
        p, n = skin(character.mesh, mats[i]) if mw is None else skin_morph(character.mesh, mats[i], mw[i])
        require_float32(character, f"clip {clip.name!r}: skinned positions", p)  # before the float32 cast
        kfs.append(Keyframe(p.astype(np.float32), n.astype(np.float32), colors, idx))
    duration = d if clip.loop else float(times[-1] - times[0])
    if clip.loop and d <= times[-1] - times[0]:
        duration = float(times[-1] - times[0]) + (float(np.mean(np.diff(times))) if times.shape[0] > 1 else 1.0)
    return from_meshes(clip.name, times, kfs, None, loop=clip.loop, duration=duration)
