"""Full-detail representations (LOD mode ``"none"``) and their per-frame selection.

This is the fair baseline every LOD speed-up is measured against: every
instance in the view frustum is drawn with its complete mesh, skinned on the
GPU from joint matrices baked once per clip.

Representations hold plain numpy arrays only, so ``render`` can upload them
without knowing any ``sim`` type:

- :class:`SkinnedRep`: bind-pose mesh + skin + the skinning matrices of all
  clips baked at a fixed rate into one table (linear blend skinning, LBS).
- :class:`KeyframedRep`: the segments of keyframe animations (Wand & Straßer
  2002, §3): per segment vertex a start and an end position/normal/colour,
  interpolated linearly by a per-instance parameter ``u``.
- :class:`StaticRep`: an unanimated mesh (terrain, reference meshes).

:class:`NoLodSelector` turns a ``CrowdState`` and a ``Camera`` into a
``DrawList``: camera-relative model matrices, animation coordinates, frustum
culling with whole-animation bounds, and grouping into instanced batches. The
per-instance work is two numba passes (:func:`instance_batches`: cull + count,
then a stable counting sort that packs instance data) beside a plain numpy
reference (:func:`instance_batches_numpy`); no per-instance Python loops, a
few milliseconds for 100K instances.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from numba import njit, prange

from lod.cull import cull_spheres, cull_spheres_numpy
from lod.drawlist import INSTANCE_FLOATS, DrawBatch, DrawList

#: default rate (frames per second) at which skinned clips are baked
BAKE_FPS = 30.0
#: the sampling margin added to skinned bounds is this multiple of the largest
#: mid-interval gap between the continuous clip and the baked interpolation
SAMPLING_PAD_FACTOR = 2.0
#: bytes of float64 scratch the bounds computation may hold at once
BOUNDS_SCRATCH_BYTES = 48 * 1024 * 1024


# ---------------------------------------------------------------------------- reps
@dataclass
class SkinnedRep:
    """A skinned mesh with the skinning matrices of all its clips baked.

    Attributes
    ----------
    key : str, e.g. ``"none:walker"``
    positions : (V, 3) float32, bind pose, model space
    normals : (V, 3) float32
    colors : (V, 4) float32, linear RGBA
    joints : (V, 4) uint16, joint indices
    weights : (V, 4) float32, rows sum to 1 (normalised at build time)
    indices : (T, 3) uint32
    joint_table : (F_total, J, 3, 4) float32
        Top three rows of every skinning matrix (``global @ inverse_bind``) of
        every baked frame of every clip, clips one after another.
    clip_names : list[str], C clips in character order
    clip_offset : (C,) int32, first row of each clip in ``joint_table``
    clip_frames : (C,) int32, frames baked per clip, *including* the frame at
        ``t = duration`` (for looping clips it equals frame 0, so the
        interpolation between the last two frames wraps seamlessly)
    clip_fps : (C,) float64, effective bake rate ``(clip_frames - 1) / duration``
        (the requested rate rounded so that frames fall exactly on 0 and duration)
    clip_duration : (C,) float64, seconds
    clip_loop : (C,) bool
    clip_aabb : (C, 2, 3) float32, model-space (min, max) over all baked frames
    clip_sphere : (C, 4) float64, model-space bounding sphere (cx, cy, cz, r)
    frame_aabb : (F_total, 2, 3) float32, model-space (min, max) per baked frame

    Notes
    -----
    The GPU interpolates the skinning matrices linearly between neighbouring
    baked frames, and LBS is linear in the matrices, so every rendered vertex
    position is a convex combination of that vertex's positions at two baked
    frames. Bounds taken over the baked frames therefore contain the rendered
    mesh at *every* time exactly.

    The continuously sampled clip (what ``sim.skinning.skin`` gives at an
    arbitrary time) can bulge slightly outside the chord between two baked
    frames (a rotating joint moves on an arc). The same linearity gives that
    gap at the middle of every interval as the LBS of the matrix difference
    ``M(t_mid) - (M_i + M_i+1) / 2``; its per-axis maximum, times
    ``SAMPLING_PAD_FACTOR``, is added to ``frame_aabb`` (and so to the clip
    boxes and spheres), so bounds also contain the CPU-skinned mesh at any
    time, not only at baked frames. Bounds come from a numba kernel parallel
    over frames (:func:`frame_aabbs`) beside a vectorised numpy reference with
    per-joint batching and bounded memory (:func:`skinned_frame_aabbs`).
    """

    key: str
    positions: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    indices: np.ndarray
    joint_table: np.ndarray
    clip_names: list
    clip_offset: np.ndarray
    clip_frames: np.ndarray
    clip_fps: np.ndarray
    clip_duration: np.ndarray
    clip_loop: np.ndarray
    clip_aabb: np.ndarray
    clip_sphere: np.ndarray
    frame_aabb: np.ndarray

    kind = "skinned"

    @property
    def n_triangles(self) -> int:
        return int(self.indices.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.joint_table.shape[1])

    @property
    def n_parts(self) -> int:
        return len(self.clip_names)

    def part_sphere(self) -> np.ndarray:
        """(n_parts, 4) float64 model-space bounding sphere per part."""
        return self.clip_sphere

    def part_triangles(self) -> np.ndarray:
        """(n_parts,) int64 triangles drawn per instance of each part."""
        return np.full(self.n_parts, self.n_triangles, np.int64)

    def frame_coordinate(self, clip: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Frame coordinate in ``joint_table`` for clip indices and times (seconds).

        ``offset + local_time * fps`` computed in float64 and returned as
        float64 (callers cast): local time wraps modulo the duration for
        looping clips and is clamped to [0, duration] otherwise; the result is
        clamped to the clip's last frame. Non-finite times map to frame 0.
        """
        clip = np.asarray(clip, np.int64)
        t = np.asarray(t, np.float64)
        t = np.where(np.isfinite(t), t, 0.0)
        dur = self.clip_duration[clip]
        safe = np.where(dur > 0.0, dur, 1.0)
        tl = np.where(self.clip_loop[clip], np.mod(t, safe), np.clip(t, 0.0, dur))
        tl = np.where(dur > 0.0, tl, 0.0)
        off = self.clip_offset[clip].astype(np.float64)
        f = off + tl * self.clip_fps[clip]
        return np.clip(f, off, off + self.clip_frames[clip] - 1)


@dataclass
class KeyframedRep:
    """Keyframe animations as concatenated segments (Wand & Straßer 2002, §3).

    Every segment pairs keyframe k with keyframe k+1; each segment vertex has
    a start (``*0``) and an end (``*1``) attribute, and a draw mixes them with
    the instance's ``u`` in [0, 1]. Parts are segments, numbered globally over
    all animations of the character.

    Attributes
    ----------
    key : str
    positions0, positions1 : (S, 3) float32, segment vertices at start / end
    normals0, normals1 : (S, 3) float32
    colors0, colors1 : (S, 4) float32
    indices : (T, 3) uint32, already offset by each segment's first vertex
    seg_first : (P,) int64, first index (in index elements, i.e. 3 per
        triangle) of each segment in ``indices``
    seg_count : (P,) int64, index elements of each segment
    seg_start, seg_end : (P,) float64, animation-local start / end time
    seg_aabb : (P, 2, 3) float32; seg_sphere : (P, 4) float64 (model space;
        exact, because interpolation is a convex combination of the ends)
    anim_names : list[str]; anim_first_seg, anim_n_segs : (A,) int64;
    anim_duration : (A,) float64; anim_loop : (A,) bool; anim_t0 : (A,) float64
        (time of the first keyframe)
    """

    key: str
    positions0: np.ndarray
    positions1: np.ndarray
    normals0: np.ndarray
    normals1: np.ndarray
    colors0: np.ndarray
    colors1: np.ndarray
    indices: np.ndarray
    seg_first: np.ndarray
    seg_count: np.ndarray
    seg_start: np.ndarray
    seg_end: np.ndarray
    seg_aabb: np.ndarray
    seg_sphere: np.ndarray
    anim_names: list
    anim_first_seg: np.ndarray
    anim_n_segs: np.ndarray
    anim_duration: np.ndarray
    anim_loop: np.ndarray
    anim_t0: np.ndarray

    kind = "keyframed"

    @property
    def n_parts(self) -> int:
        return int(self.seg_first.shape[0])

    @property
    def n_clips(self) -> int:
        return len(self.anim_names)

    def part_sphere(self) -> np.ndarray:
        return self.seg_sphere

    def part_triangles(self) -> np.ndarray:
        return (self.seg_count // 3).astype(np.int64)

    def locate(self, anim: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Global segment index (N,) int64 and u (N,) float64 in [0, 1] at times t.

        Looping animations wrap ``t`` into [t0, t0 + duration); others clamp.
        Non-finite times map to the start. One numba pass (every frame locates
        every keyframed instance); :meth:`locate_numpy` is the vectorised
        reference, tested against ``sim.keyframes.KeyframeAnimation.locate``.
        """
        a0 = int(self.anim_first_seg[anim])
        ns = int(self.anim_n_segs[anim])
        if ns == 0 or np.ndim(t) != 1:  # no segment (the reference's error) or another shape: the reference
            return self.locate_numpy(anim, t)
        t = np.ascontiguousarray(t, np.float64)
        seg = np.empty(t.shape[0], np.int64)
        u = np.empty(t.shape[0], np.float64)
        _locate_kernel(t, np.ascontiguousarray(self.seg_start[a0:a0 + ns], np.float64),
                       np.ascontiguousarray(self.seg_end[a0:a0 + ns], np.float64), float(self.anim_t0[anim]),
                       float(self.anim_duration[anim]), bool(self.anim_loop[anim]), a0, seg, u)
        return seg, u

    def locate_numpy(self, anim: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference of :meth:`locate` (plain numpy)."""
        t = np.asarray(t, np.float64)
        t = np.where(np.isfinite(t), t, self.anim_t0[anim])
        a0 = int(self.anim_first_seg[anim])
        ns = int(self.anim_n_segs[anim])
        starts = self.seg_start[a0:a0 + ns]
        ends = self.seg_end[a0:a0 + ns]
        t0 = float(self.anim_t0[anim])
        dur = float(self.anim_duration[anim])
        if self.anim_loop[anim] and dur > 0.0:
            t = t0 + np.mod(t - t0, dur)
        t = np.clip(t, starts[0], ends[-1])
        s = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, ns - 1)
        span = ends[s] - starts[s]
        u = np.clip((t - starts[s]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
        return s + a0, u


@njit(cache=True)
def _locate_kernel(t, starts, ends, t0, dur, loop, a0, seg, u):  # pragma: no cover - compiled
    ns = starts.shape[0]
    for i in range(t.shape[0]):
        x = t[i]
        if not np.isfinite(x):
            x = t0
        if loop and dur > 0.0:
            x = t0 + (x - t0) % dur  # Python's float modulo: the sign of dur, as np.mod
        x = min(max(x, starts[0]), ends[ns - 1])
        lo, hi = 0, ns  # searchsorted(starts, x, side="right") - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if starts[mid] <= x:
                lo = mid + 1
            else:
                hi = mid
        s = min(max(lo - 1, 0), ns - 1)
        span = ends[s] - starts[s]
        v = (x - starts[s]) / (span if span > 0.0 else 1.0)
        seg[i] = s + a0
        u[i] = min(max(v, 0.0), 1.0)


@dataclass
class StaticRep:
    """An unanimated mesh drawn through the instancing path.

    positions : (V, 3) float32; normals : (V, 3) float32; colors : (V, 4)
    float32; indices : (T, 3) uint32; aabb : (2, 3) float32; sphere : (4,)
    float64 (model space).
    """

    key: str
    positions: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    indices: np.ndarray
    aabb: np.ndarray
    sphere: np.ndarray

    kind = "static"

    @property
    def n_triangles(self) -> int:
        return int(self.indices.shape[0])

    @property
    def n_parts(self) -> int:
        return 1

    def part_sphere(self) -> np.ndarray:
        return self.sphere.reshape(1, 4)

    def part_triangles(self) -> np.ndarray:
        return np.array([self.n_triangles], np.int64)


Rep = SkinnedRep | KeyframedRep | StaticRep


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


# ---------------------------------------------------------------------------- build
def _finite(name: str, a: np.ndarray) -> np.ndarray:
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: expected finite values, got NaN or Inf")
    return a


def _bake_clip_matrices(clip, skeleton, times: np.ndarray) -> np.ndarray:
    if hasattr(clip, "skinning_matrices"):
        m = clip.skinning_matrices(skeleton, times)
    else:  # pragma: no cover - older sim.clip without the batched helper
        m = np.stack([skeleton.skinning_matrices(*clip.sample(skeleton, float(t))) for t in times])
    return np.asarray(m, np.float64)


def build_skinned_rep(character, fps: float = BAKE_FPS, key: str | None = None) -> SkinnedRep:
    """Bake a ``sim.character.SkinnedCharacter`` into a :class:`SkinnedRep`.

    Every clip is sampled at ``round(duration * fps) + 1`` evenly spaced
    times from 0 to ``duration`` inclusive (at least 2), the skinning matrices
    are stored as float32 3x4 rows, and exact whole-animation bounds are
    computed (see the class Notes).
    """
    fps = float(fps)
    if not fps > 0.0:
        raise ValueError(f"build_rep: fps: expected > 0, got {fps}")
    mesh = character.mesh
    skel = character.skeleton
    name = getattr(character, "name", "character")
    if not mesh.is_skinned:
        raise ValueError(f"character {name!r}: mesh has no joints/weights; expected a skinned mesh")
    if not character.clips:
        raise ValueError(f"character {name!r}: expected at least one clip, got none")
    pos = _finite(f"character {name!r}: mesh.positions", np.ascontiguousarray(mesh.positions, np.float32))
    nrm = _finite(f"character {name!r}: mesh.normals", np.ascontiguousarray(mesh.ensure_normals(), np.float32))
    col = np.ascontiguousarray(np.clip(mesh.vertex_colors(), 0.0, 1.0), np.float32)
    jn = np.asarray(mesh.joints)
    if jn.size and (jn.min() < 0 or jn.max() >= skel.n_joints):
        raise ValueError(f"character {name!r}: mesh.joints: expected indices in 0..{skel.n_joints - 1}")
    jn = np.ascontiguousarray(jn, np.uint16)
    w = np.asarray(mesh.weights, np.float64)
    w = np.where(np.isfinite(w) & (w > 0.0), w, 0.0)
    s = w.sum(1, keepdims=True)
    w = np.where(s > 0.0, w / np.where(s > 0.0, s, 1.0), w)
    w = np.ascontiguousarray(w, np.float32)
    idx = np.ascontiguousarray(mesh.indices, np.uint32).reshape(-1, 3)
    if idx.size and idx.max() >= pos.shape[0]:
        raise ValueError(f"character {name!r}: mesh.indices: expected values < {pos.shape[0]}")

    tables, offsets, frames, rates, durs, loops, caabb, csph, faabb = [], [], [], [], [], [], [], [], []
    off = 0
    for cname, clip in character.clips.items():
        dur = float(clip.duration)
        if not np.isfinite(dur) or dur < 0.0:
            raise ValueError(f"character {name!r}: clip {cname!r}: duration: expected >= 0 seconds, got {dur}")
        n_int = max(1, int(round(dur * fps)))
        times = np.linspace(0.0, dur, n_int + 1)
        m = _bake_clip_matrices(clip, skel, times)[:, :, :3, :]
        _finite(f"character {name!r}: clip {cname!r} skinning matrices", m)
        fa = frame_aabbs(pos, jn, w, m)
        # continuous-pose margin: LBS is linear in the matrices, so the gap
        # between the clip sampled mid-way and the GPU's interpolation is the
        # LBS of the matrix differences D (see the class Notes)
        mid = _bake_clip_matrices(clip, skel, 0.5 * (times[:-1] + times[1:]))[:, :, :3, :]
        dev = frame_aabbs(pos, jn, w, mid - 0.5 * (m[:-1] + m[1:]))
        pad = SAMPLING_PAD_FACTOR * np.abs(dev).max(axis=(0, 1)) if dev.size else np.zeros(3)
        fa = fa + np.array([-1.0, 1.0])[None, :, None] * pad
        box, sph = _skin_all_frames_sphere(fa)
        tables.append(m.astype(np.float32))
        offsets.append(off)
        frames.append(n_int + 1)
        rates.append(n_int / dur if dur > 0.0 else 0.0)
        durs.append(dur)
        loops.append(bool(getattr(clip, "loop", True)))
        caabb.append(box)
        csph.append(sph)
        faabb.append(fa)
        off += n_int + 1
    return SkinnedRep(
        key=key or f"none:{name}",
        positions=pos, normals=nrm, colors=col, joints=jn, weights=w, indices=idx,
        joint_table=np.ascontiguousarray(np.concatenate(tables)),
        clip_names=list(character.clips),
        clip_offset=np.asarray(offsets, np.int32),
        clip_frames=np.asarray(frames, np.int32),
        clip_fps=np.asarray(rates, np.float64),
        clip_duration=np.asarray(durs, np.float64),
        clip_loop=np.asarray(loops, bool),
        clip_aabb=np.asarray(caabb, np.float32),
        clip_sphere=np.asarray(csph, np.float64),
        frame_aabb=np.concatenate(faabb).astype(np.float32),
    )


def build_keyframed_rep(character, key: str | None = None) -> KeyframedRep:
    """Concatenate the segments of every animation of a ``KeyframedCharacter``."""
    name = getattr(character, "name", "character")
    if not character.animations:
        raise ValueError(f"character {name!r}: expected at least one animation, got none")
    cols = {k: [] for k in ("p0", "p1", "n0", "n1", "c0", "c1", "idx")}
    seg_first, seg_count, seg_start, seg_end, seg_aabb, seg_sph = [], [], [], [], [], []
    a_first, a_n, a_dur, a_loop, a_t0 = [], [], [], [], []
    vbase = 0
    ibase = 0
    for aname, anim in character.animations.items():
        K = len(anim.keyframes)
        times = np.asarray(anim.times, np.float64)
        segs = list(anim.segments)
        if K == 0:
            raise ValueError(f"character {name!r}: animation {aname!r}: expected keyframes, got none")
        if hasattr(anim, "segment_edges"):
            edges = np.asarray(anim.segment_edges(), np.float64)
        else:  # pragma: no cover - older sim.keyframes
            edges = np.append(times, times[0] + float(anim.duration)) if anim.loop else times
        if not segs:
            # a single still keyframe: one zero-length segment pairing it with itself
            kf = anim.keyframes[0]
            ident = np.arange(np.asarray(kf.positions).shape[0], dtype=np.int32)
            segs = [type("_Still", (), {"src": ident, "dst": ident, "indices": np.asarray(kf.indices)})()]
            edges = np.array([times[0], times[0]])
        if len(edges) != len(segs) + 1:
            raise ValueError(f"character {name!r}: animation {aname!r}: expected {len(edges) - 1} segments for "
                             f"{K} keyframes (loop={anim.loop}), got {len(segs)}")
        a_first.append(len(seg_first))
        a_n.append(len(segs))
        a_dur.append(float(edges[-1] - edges[0]))
        a_loop.append(bool(anim.loop))
        a_t0.append(float(edges[0]))
        for si, seg in enumerate(segs):
            k0, k1 = si % K, (si + 1) % K
            kf0, kf1 = anim.keyframes[k0], anim.keyframes[k1]
            src = np.asarray(seg.src, np.int64)
            dst = np.asarray(seg.dst, np.int64)
            t_start, t_end = float(edges[si]), float(edges[si + 1])
            if not t_end >= t_start:
                raise ValueError(
                    f"character {name!r}: animation {aname!r}: segment {si}: expected end time >= start, "
                    f"got {t_start}..{t_end}")
            p0 = np.asarray(kf0.positions, np.float32)[src]
            p1 = np.asarray(kf1.positions, np.float32)[dst]
            _finite(f"character {name!r}: animation {aname!r} positions", p0)
            _finite(f"character {name!r}: animation {aname!r} positions", p1)
            cols["p0"].append(p0)
            cols["p1"].append(p1)
            cols["n0"].append(np.asarray(kf0.normals, np.float32)[src])
            cols["n1"].append(np.asarray(kf1.normals, np.float32)[dst])
            cols["c0"].append(np.asarray(kf0.colors, np.float32)[src])
            cols["c1"].append(np.asarray(kf1.colors, np.float32)[dst])
            ix = np.asarray(seg.indices, np.int64).reshape(-1, 3)
            cols["idx"].append((ix + vbase).astype(np.uint32))
            seg_first.append(ibase * 3)
            seg_count.append(ix.shape[0] * 3)
            seg_start.append(t_start)
            seg_end.append(t_end)
            both = np.concatenate([p0, p1]) if p0.size else np.zeros((1, 3), np.float32)
            seg_aabb.append(np.stack([both.min(0), both.max(0)]))
            seg_sph.append(_sphere_of_points(both))
            vbase += src.shape[0]
            ibase += ix.shape[0]
    cat = {k: np.ascontiguousarray(np.concatenate(v)) for k, v in cols.items()}
    return KeyframedRep(
        key=key or f"none:{name}",
        positions0=cat["p0"], positions1=cat["p1"], normals0=cat["n0"], normals1=cat["n1"],
        colors0=np.clip(cat["c0"], 0, 1), colors1=np.clip(cat["c1"], 0, 1), indices=cat["idx"],
        seg_first=np.asarray(seg_first, np.int64), seg_count=np.asarray(seg_count, np.int64),
        seg_start=np.asarray(seg_start, np.float64), seg_end=np.asarray(seg_end, np.float64),
        seg_aabb=np.asarray(seg_aabb, np.float32), seg_sphere=np.asarray(seg_sph, np.float64),
        anim_names=list(character.animations), anim_first_seg=np.asarray(a_first, np.int64),
        anim_n_segs=np.asarray(a_n, np.int64), anim_duration=np.asarray(a_dur, np.float64),
        anim_loop=np.asarray(a_loop, bool), anim_t0=np.asarray(a_t0, np.float64),
    )


def build_static_rep(mesh, key: str = "static") -> StaticRep:
    """Wrap a ``sim.mesh.Mesh`` (skin ignored) as a :class:`StaticRep`."""
    pos = _finite(f"static mesh {key!r}: positions", np.ascontiguousarray(mesh.positions, np.float32))
    nrm = np.ascontiguousarray(mesh.ensure_normals(), np.float32)
    col = np.ascontiguousarray(np.clip(mesh.vertex_colors(), 0.0, 1.0), np.float32)
    idx = np.ascontiguousarray(mesh.indices, np.uint32).reshape(-1, 3)
    if pos.shape[0]:
        box = np.stack([pos.min(0), pos.max(0)])
    else:
        box = np.zeros((2, 3), np.float32)
    return StaticRep(key, pos, nrm, col, idx, box.astype(np.float32), _sphere_of_points(pos))


def build_rep(character, fps: float = BAKE_FPS, key: str | None = None) -> Rep:
    """Full-detail representation of a character (or a plain ``Mesh``).

    Parameters
    ----------
    character : sim.character.SkinnedCharacter | KeyframedCharacter | sim.mesh.Mesh
    fps : bake rate for skinned clips (frames per second)
    key : representation key; default ``"none:<name>"`` (``"none:static"`` for meshes)
    """
    kind = getattr(character, "kind", None)
    if kind == "skinned":
        return build_skinned_rep(character, fps, key)
    if kind == "keyframed":
        return build_keyframed_rep(character, key)
    if hasattr(character, "positions") and hasattr(character, "indices"):
        return build_static_rep(character, key or "none:static")
    raise TypeError(f"build_rep: expected a SkinnedCharacter, KeyframedCharacter or Mesh, got {type(character).__name__}")


# ---------------------------------------------------------------------------- selection
def model_rows(rel: np.ndarray, heading: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(n, 12) float32 rows 0..2 of camera-relative model matrices.

    rel : (n, 3) float64 position minus camera position; heading : (n,) yaw
    about +Y (0 faces +Z); scale : (n,) uniform scale.
    """
    n = rel.shape[0]
    c = np.cos(heading) * scale
    s = np.sin(heading) * scale
    out = np.zeros((n, 12), np.float32)
    out[:, 0] = c
    out[:, 2] = s
    out[:, 3] = rel[:, 0]
    out[:, 5] = scale
    out[:, 7] = rel[:, 1]
    out[:, 8] = -s
    out[:, 10] = c
    out[:, 11] = rel[:, 2]
    return out


def instance_batches_numpy(pos, origin, heading, scale, gid, t, anim, g_sphere, g_skinned, g_off, g_fps, g_dur,
                           g_loop, g_last, planes, cull):
    """Reference of :func:`instance_batches` (plain numpy, same results)."""
    n = pos.shape[0]
    G = g_sphere.shape[0]
    rel = pos - origin
    heading = np.where(np.isfinite(heading), heading, 0.0)
    anim = anim.astype(np.float64).copy()
    sk = g_skinned[gid] if n else np.zeros(0, bool)
    if sk.any():
        gs = gid[sk]
        ts = np.where(np.isfinite(t[sk]), t[sk], 0.0)
        dur = g_dur[gs]
        safe = np.where(dur > 0.0, dur, 1.0)
        tl = np.where(g_loop[gs], np.mod(ts, safe), np.clip(ts, 0.0, dur))
        tl = np.where(dur > 0.0, tl, 0.0)
        anim[sk] = np.clip(g_off[gs] + tl * g_fps[gs], g_off[gs], g_last[gs])
    if cull and n:
        sph = g_sphere[gid]
        c, s = np.cos(heading), np.sin(heading)
        cx = (c * sph[:, 0] + s * sph[:, 2]) * scale
        cz = (-s * sph[:, 0] + c * sph[:, 2]) * scale
        centers = rel + np.stack([cx, sph[:, 1] * scale, cz], axis=1)
        idx = np.flatnonzero(cull_spheres_numpy(centers, sph[:, 3] * np.abs(scale), planes))
    else:
        idx = np.arange(n)
    order = idx[np.argsort(gid[idx], kind="stable")]
    data = np.zeros((order.size, INSTANCE_FLOATS), np.float32)
    data[:, :12] = model_rows(rel[order], heading[order], scale[order])
    data[:, 12] = anim[order]
    counts = np.bincount(gid[order], minlength=G).astype(np.int64)
    return order.astype(np.int32), data, counts


@njit(cache=True)
def _instance_pass(pos, origin, heading, scale, gid, t, anim, g_sphere, g_skinned, g_off, g_fps, g_dur, g_loop,
                   g_last, planes, cull, vis, cs):  # pragma: no cover - compiled
    n = pos.shape[0]
    for i in range(n):
        g = gid[i]
        h = heading[i]
        if not np.isfinite(h):
            h = 0.0
            heading[i] = 0.0
        if g_skinned[g]:
            ti = t[i]
            if not np.isfinite(ti):
                ti = 0.0
            d = g_dur[g]
            if d > 0.0:
                if g_loop[g]:
                    tl = ti - np.floor(ti / d) * d
                else:
                    tl = min(max(ti, 0.0), d)
            else:
                tl = 0.0
            f = g_off[g] + tl * g_fps[g]
            anim[i] = min(max(f, g_off[g]), g_last[g])
        ok = True
        c = np.cos(h)
        s = np.sin(h)
        cs[i, 0] = c
        cs[i, 1] = s
        if cull:
            sc = scale[i]
            sx, sy, sz, sr = g_sphere[g, 0], g_sphere[g, 1], g_sphere[g, 2], g_sphere[g, 3]
            cx = pos[i, 0] - origin[0] + (c * sx + s * sz) * sc
            cy = pos[i, 1] - origin[1] + sy * sc
            cz = pos[i, 2] - origin[2] + (-s * sx + c * sz) * sc
            r = sr * abs(sc)
            for k in range(planes.shape[0]):
                if planes[k, 0] * cx + planes[k, 1] * cy + planes[k, 2] * cz + planes[k, 3] < -r:
                    ok = False
                    break
        vis[i] = ok


@njit(cache=True)
def _scatter(pos, origin, cs, scale, gid, anim, vis, starts, ids, data):  # pragma: no cover - compiled
    cursor = starts.copy()
    for i in range(pos.shape[0]):
        if not vis[i]:
            continue
        g = gid[i]
        k = cursor[g]
        cursor[g] += 1
        ids[k] = i
        sc = scale[i]
        c = cs[i, 0] * sc
        s = cs[i, 1] * sc
        data[k, 0] = c
        data[k, 1] = 0.0
        data[k, 2] = s
        data[k, 3] = pos[i, 0] - origin[0]
        data[k, 4] = 0.0
        data[k, 5] = sc
        data[k, 6] = 0.0
        data[k, 7] = pos[i, 1] - origin[1]
        data[k, 8] = -s
        data[k, 9] = 0.0
        data[k, 10] = c
        data[k, 11] = pos[i, 2] - origin[2]
        data[k, 12] = anim[i]
        data[k, 13] = 0.0
        data[k, 14] = 0.0
        data[k, 15] = 0.0


def instance_batches(pos, origin, heading, scale, gid, t, anim, g_sphere, g_skinned, g_off, g_fps, g_dur, g_loop,
                     g_last, planes, cull):
    """Cull instances and pack their instance data grouped by draw group.

    Two serial numba passes (serial on purpose: llvmpipe's render threads
    share the same cores, and a ``parallel=True`` first pass measured slower
    on the loaded 2-core machine, 32 ms against 6-12 ms for 100K instances):
    the first computes skinned frame coordinates (clip offset + wrapped time * fps, in float64) and tests
    each instance's whole-animation bounding sphere (rotated by the heading,
    scaled) against the frustum; after a per-group count, the second (serial)
    is a counting sort that writes each visible instance's camera-relative
    model rows and animation float in group order, keeping agent order within
    a group (stable), in O(n).

    Parameters
    ----------
    pos : (n, 3) float64 world; origin : (3,) float64 camera position
    heading : (n,) float64; scale : (n,) float64; gid : (n,) int64 group
    t : (n,) float64 animation times; anim : (n,) float64 precomputed
        animation floats for non-skinned groups (keyframed u)
    g_sphere : (G, 4) float64 model-space spheres; g_skinned : (G,) bool;
    g_off, g_fps, g_dur, g_last : (G,) float64; g_loop : (G,) bool
    planes : (6, 4) float64 camera-relative; cull : bool

    Returns
    -------
    ids : (k,) int32 agent indices in group order; data : (k, 16) float32
    instance data; counts : (G,) int64 visible instances per group.
    """
    n = pos.shape[0]
    G = g_sphere.shape[0]
    if n == 0:
        return np.zeros(0, np.int32), np.zeros((0, INSTANCE_FLOATS), np.float32), np.zeros(G, np.int64)
    heading = np.array(heading, np.float64)  # the kernel sanitises a copy
    anim = np.array(anim, np.float64)
    vis = np.empty(n, np.bool_)
    cs = np.empty((n, 2), np.float64)
    _instance_pass(np.ascontiguousarray(pos, np.float64), np.ascontiguousarray(origin, np.float64), heading,
                   np.ascontiguousarray(scale, np.float64), np.ascontiguousarray(gid, np.int64),
                   np.ascontiguousarray(t, np.float64), anim, g_sphere, g_skinned, g_off, g_fps, g_dur, g_loop,
                   g_last, np.ascontiguousarray(planes, np.float64), bool(cull), vis, cs)
    counts = np.bincount(gid[vis], minlength=G).astype(np.int64)
    starts = np.zeros(G, np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    k = int(counts.sum())
    ids = np.empty(k, np.int32)
    data = np.empty((k, INSTANCE_FLOATS), np.float32)
    _scatter(np.ascontiguousarray(pos, np.float64), np.ascontiguousarray(origin, np.float64), cs,
             np.ascontiguousarray(scale, np.float64), np.ascontiguousarray(gid, np.int64), anim, vis, starts, ids,
             data)
    return ids, data, counts


@dataclass
class _Groups:
    rep_index: np.ndarray  # (G,) int
    part: np.ndarray  # (G,) int
    sphere: np.ndarray  # (G, 4) float64
    tris: np.ndarray  # (G,) int64
    offset: np.ndarray  # (R,) int64 first group of each rep


class NoLodSelector:
    """Select every visible instance at full detail.

    Parameters
    ----------
    reps : sequence of representations aligned with ``CrowdState.character``
        (``reps[i]`` draws agents whose character is i). A :class:`StaticRep`
        in this list draws its agents unanimated (used by benchmarks).
    static_reps : extra :class:`StaticRep` objects that ``statics`` may name.
    cull : frustum culling on (default) or off.
    use_kernel : per-instance work in the numba kernel (default) or in the
        numpy reference (:func:`instance_batches_numpy`; tests compare them).
    """

    def __init__(self, reps, static_reps=(), cull: bool = True, use_kernel: bool = True):
        self.use_kernel = bool(use_kernel)
        self.reps = list(reps)
        self.by_key = {r.key: r for r in list(self.reps) + list(static_reps)}
        self.cull = bool(cull)
        rep_index, part, sph, tris, offs = [], [], [], [], []
        g = 0
        for i, r in enumerate(self.reps):
            offs.append(g)
            n = r.n_parts
            rep_index.append(np.full(n, i, np.int64))
            part.append(np.arange(n, dtype=np.int64))
            sph.append(np.asarray(r.part_sphere(), np.float64).reshape(n, 4))
            tris.append(r.part_triangles())
            g += n
        cat = (lambda xs, shape, dt: np.concatenate(xs) if xs else np.zeros(shape, dt))
        self._g = _Groups(cat(rep_index, (0,), np.int64), cat(part, (0,), np.int64), cat(sph, (0, 4), np.float64),
                          cat(tris, (0,), np.int64), np.asarray(offs, np.int64))
        self._is_static = np.array([r.kind == "static" for r in self.reps] or [False])
        self._any_static = bool(self._is_static.any())
        # skinned clip tables per group, for the vectorised frame coordinate
        G = self._g.part.shape[0]
        self._g_off = np.zeros(G)
        self._g_fps = np.zeros(G)
        self._g_dur = np.zeros(G)
        self._g_loop = np.zeros(G, bool)
        self._g_last = np.zeros(G)
        self._g_skinned = np.zeros(G, bool)
        for i, r in enumerate(self.reps):
            if r.kind == "skinned":
                self._g_skinned[offs[i]:offs[i] + r.n_parts] = True
                sl = slice(offs[i], offs[i] + r.n_parts)
                self._g_off[sl] = r.clip_offset
                self._g_fps[sl] = r.clip_fps
                self._g_dur[sl] = r.clip_duration
                self._g_loop[sl] = r.clip_loop
                self._g_last[sl] = r.clip_offset + r.clip_frames - 1
        self._n_clips = np.array([(r.n_clips if r.kind == "keyframed" else r.n_parts) for r in self.reps] or [0])

    # -------------------------------------------------------------------------
    def select(self, state, camera, size, statics=(), agents=None) -> DrawList:
        """Build the frame's DrawList.

        Parameters
        ----------
        state : sim.state.CrowdState
        camera : lod.view.Camera
        size : (width, height) pixels
        statics : sequence of (StaticRep key, (4, 4) float64 world matrix),
            each drawn as a single-instance batch (instance id -1).
        agents : None (every agent) or (m,) increasing int agent indices: only
            these are culled and packed (instance ids stay the state's); e.g. the
            agents no super-hierarchy node draws (Wand & Straßer §3.6)

        Returns
        -------
        DrawList with batches sorted by (representation, part), instances in
        agent order within a batch; ``stats`` holds "instances", "culled",
        "triangles", "points", "batches".
        """
        w, h = int(size[0]), int(size[1])
        aspect = w / max(1, h)
        origin = np.asarray(camera.position, np.float64).copy()
        planes = camera.frustum_planes(aspect)
        sel = None if agents is None else np.asarray(agents, np.int64)

        def pick(a, dtype):
            a = np.asarray(a, dtype)
            return a if sel is None else a[sel]

        n = state.n if sel is None else int(sel.shape[0])
        char = pick(state.character, np.int64)
        clip = pick(state.clip, np.int64)
        nreps = len(self.reps)
        if n and (char.min() < 0 or char.max() >= nreps):
            raise ValueError(f"CrowdState.character: expected indices in 0..{nreps - 1}, got {char.min()}..{char.max()}")
        if self._any_static and n:
            clip = np.where(self._is_static[char], 0, clip)
        if n and (clip.min() < 0 or (clip >= self._n_clips[char]).any()):
            bad = int(np.flatnonzero((clip < 0) | (clip >= self._n_clips[char]))[0])
            raise ValueError(f"CrowdState.clip[{bad if sel is None else int(sel[bad])}] = {clip[bad]}: expected a "
                             f"clip index below {self._n_clips[char[bad]]} for character {char[bad]}")

        gid = self._g.offset[char] + clip if nreps else np.zeros(0, np.int64)
        t = pick(state.anim_time, np.float64)
        anim = np.zeros(n, np.float64)
        for ri, r in enumerate(self.reps):
            if r.kind != "keyframed":
                continue
            mr = np.flatnonzero(char == ri)
            for a in range(r.n_clips):
                ma = mr[clip[mr] == a]
                if ma.size == 0:
                    continue
                seg, u = r.locate(a, t[ma])
                gid[ma] = self._g.offset[ri] + seg
                anim[ma] = u
        pos = pick(state.position, np.float64)
        scale = pick(state.scale, np.float64)
        if n and not (np.isfinite(pos).all() and np.isfinite(scale).all()):
            raise FloatingPointError("CrowdState.position/scale hold NaN or Inf; refusing to draw them")
        heading = pick(state.heading, np.float64)
        args = (pos, origin, heading, scale, gid, t, anim, self._g.sphere, self._g_skinned, self._g_off, self._g_fps,
                self._g_dur, self._g_loop, self._g_last, planes, self.cull)
        if self.use_kernel:
            ids, data, counts = instance_batches(*args)
        else:
            ids, data, counts = instance_batches_numpy(*args)
        if sel is not None:
            ids = sel[ids].astype(np.int32)
        batches = []
        a = 0
        for g in np.flatnonzero(counts).tolist():
            b = a + int(counts[g])
            r = self.reps[int(self._g.rep_index[g])]
            batches.append(DrawBatch(r.key, int(self._g.part[g]), ids[a:b], data[a:b],
                                     triangles=int(self._g.tris[g]) * (b - a)))
            a = b
        n_drawn = int(ids.shape[0])
        n_static = 0
        for skey, mat in statics:
            r = self.by_key.get(skey)
            if r is None or r.kind != "static":
                raise KeyError(f"statics: unknown StaticRep key {skey!r}; known: {sorted(k for k, v in self.by_key.items() if v.kind == 'static')}")
            m = np.asarray(mat, np.float64).reshape(4, 4).copy()
            if not np.isfinite(m).all():
                raise FloatingPointError(f"statics: matrix of {skey!r} holds NaN or Inf")
            m[:3, 3] -= origin
            if self.cull:
                c = m[:3, :3] @ r.sphere[:3] + m[:3, 3]
                rad = r.sphere[3] * float(np.linalg.norm(m[:3, :3], axis=0).max())
                if not cull_spheres(c[None], np.array([rad]), planes)[0]:
                    continue
            d = np.zeros((1, INSTANCE_FLOATS), np.float32)
            d[0, :12] = m[:3, :].reshape(12)
            batches.append(DrawBatch(skey, 0, np.array([-1], np.int32), d, triangles=r.n_triangles))
            n_static += 1
        tri = sum(b.triangles for b in batches)
        stats = {"instances": n_drawn, "culled": int(n - n_drawn), "triangles": int(tri), "points": 0,
                 "batches": len(batches), "statics": n_static}
        return DrawList(origin=origin, view=camera.view_matrix().astype(np.float32),
                        proj=camera.projection(aspect).astype(np.float32), size=(w, h), batches=batches, stats=stats)


# --------------------------------------------------------------------------------------------------------------------
# LOD mode "none" (lod.modes protocol)
# --------------------------------------------------------------------------------------------------------------------

#: ``[lod]`` keys of mode "none": full detail has no parameters
PARAMS: dict = {}


def build(characters, names, fps, params, static_reps=(), progress=None):
    """Mode "none" for ``lod.modes``: a full-detail rep per character and a NoLodSelector."""
    items = list(zip(characters, names, fps))
    if callable(progress):
        items = progress(items, "representations")
    reps = [build_rep(ch, fps=f, key=f"none:{n}") for ch, n, f in items]
    return reps, NoLodSelector(reps, static_reps=static_reps)
