"""Full-detail representations and how a character becomes one (LOD mode ``"none"``).

Representations hold plain numpy arrays only, so ``render`` can upload them
without knowing any ``sim`` type:

- :class:`SkinnedRep`: bind-pose mesh + skin + the skinning matrices of all
  clips baked at a fixed rate into one table (linear blend skinning, LBS),
  and, for a mesh with animated morph targets (glTF 2.0 §3.7.2.2), their
  sparse deltas and weights baked at the same frames
  (:class:`lod.full.targets.TargetTable`, blended before skinning).
- :class:`KeyframedRep`: the segments of keyframe animations (Wand & Straßer
  2002, §3): per segment vertex a start and an end position/normal/colour,
  interpolated linearly by a per-instance parameter ``u``.
- :class:`StaticRep`: an unanimated mesh (terrain, reference meshes).

:func:`build_rep` bakes a character into one of them; the whole-animation
bounds come from :mod:`lod.full.bounds`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from lod.full.bounds import _skin_all_frames_sphere, _sphere_of_points, frame_aabbs
from lod.full.targets import TargetTable, build_target_table, clip_offsets, morph_frame_aabbs
from sim.errors import require_float32

#: default rate (frames per second) at which skinned clips are baked
BAKE_FPS = 30.0
#: the sampling margin added to skinned bounds is this multiple of the largest
#: mid-interval gap between the continuous clip and the baked interpolation
SAMPLING_PAD_FACTOR = 2.0
#: most baked frames of one skinned character, over all its clips: the rows of its joint texture
#: (``render/renderer.py``); GL 4.5's smallest allowed GL_MAX_TEXTURE_SIZE. Longer animations are baked at a
#: lower rate (:func:`bake_intervals`).
BAKE_MAX_FRAMES = 16384
#: instances from which KeyframedRep.locate runs its kernel in parallel (below: serial, no thread wake-up)
LOCATE_PARALLEL_MIN = 100_000

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
    targets : lod.full.targets.TargetTable or None
        Morph targets whose weights the clips animate, their weights baked at
        the rows of ``joint_table``; None for a mesh without them (the draw
        path is then exactly the plain skinned one). With targets the bounds
        follow :func:`lod.full.targets.morph_frame_aabbs`.

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
    targets: TargetTable | None = None
    double_sided: bool = True  # sim.mesh.Mesh.double_sided: False lets the renderer cull back faces

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
        kernel = _locate_kernel_parallel if t.shape[0] >= LOCATE_PARALLEL_MIN else _locate_kernel
        kernel(t, np.ascontiguousarray(self.seg_start[a0:a0 + ns], np.float64),
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


@njit(cache=True, inline="always")
def _locate_one(i, t, starts, ends, t0, dur, loop, a0, seg, u):  # pragma: no cover - compiled
    ns = starts.shape[0]
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


@njit(cache=True)
def _locate_kernel(t, starts, ends, t0, dur, loop, a0, seg, u):  # pragma: no cover - compiled
    for i in range(t.shape[0]):
        _locate_one(i, t, starts, ends, t0, dur, loop, a0, seg, u)


@njit(cache=True, parallel=True)
def _locate_kernel_parallel(t, starts, ends, t0, dur, loop, a0, seg, u):  # pragma: no cover - compiled
    for i in prange(t.shape[0]):  # each instance writes only its own seg and u
        _locate_one(i, t, starts, ends, t0, dur, loop, a0, seg, u)


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
    double_sided: bool = True  # sim.mesh.Mesh.double_sided

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


# ---------------------------------------------------------------------------- build
def _finite(name: str, a: np.ndarray) -> np.ndarray:
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: expected finite values, got NaN or Inf")
    return a


def bake_intervals(durations, fps: float, max_frames: int = BAKE_MAX_FRAMES) -> np.ndarray:
    """(C,) int64 frame intervals baked per clip: ``round(duration * fps)``, at least 1.

    A clip bakes intervals + 1 frames. When all clips together would need more than ``max_frames`` (a
    60 s clip at 240 fps, or minutes of motion capture), every clip is baked at the same lower rate
    ``(max_frames - 2 C) / sum(durations)`` instead, so the joint table fits the renderer's texture; the
    GPU interpolates between baked frames either way (the class Notes of :class:`SkinnedRep` hold for any
    rate). ValueError when even one interval per clip does not fit (more than ``max_frames / 2`` clips).
    """
    d = np.asarray(durations, np.float64).reshape(-1)
    n = np.maximum(1, np.round(d * float(fps))).astype(np.int64)
    if int(n.sum()) + d.size <= max_frames:
        return n
    spare = max_frames - 2 * d.size
    if spare < 0:
        raise ValueError(f"bake_intervals: {d.size} clips need at least {2 * d.size} baked frames, "
                         f"above the limit {max_frames}")
    rate = spare / d.sum()  # d.sum() > 0: otherwise n.sum() = C fits
    return np.maximum(1, np.floor(d * rate)).astype(np.int64)


def _bake_clip_matrices(clip, skeleton, times: np.ndarray) -> np.ndarray:
    if hasattr(clip, "skinning_matrices"):
        m = clip.skinning_matrices(skeleton, times)
    else:  # pragma: no cover - older sim.clip without the batched helper
        m = np.stack([skeleton.skinning_matrices(*clip.sample(skeleton, float(t))) for t in times])
    return np.asarray(m, np.float64)


def build_skinned_rep(character, fps: float = BAKE_FPS, key: str | None = None,
                      morph_targets: bool = True) -> SkinnedRep:
    """Bake a ``sim.character.SkinnedCharacter`` into a :class:`SkinnedRep`.

    Every clip is sampled at ``round(duration * fps) + 1`` evenly spaced
    times from 0 to ``duration`` inclusive (at least 2; at a lower rate when all
    clips would exceed :data:`BAKE_MAX_FRAMES`, :func:`bake_intervals`), the skinning matrices
    are stored as float32 3x4 rows, and exact whole-animation bounds are
    computed (see the class Notes). The morph targets of the mesh (if any) are
    baked at the same times into ``targets`` (:mod:`lod.full.targets`);
    ``morph_targets=False`` leaves them out (the mesh at its default weights,
    as representations that do not draw morphs use it).
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

    for cname, clip in character.clips.items():
        dur = float(clip.duration)
        if not np.isfinite(dur) or dur < 0.0:
            raise ValueError(f"character {name!r}: clip {cname!r}: duration: expected >= 0 seconds, got {dur}")
    # frame intervals per clip (a long clip bakes at a lower rate so the joint table fits, bake_intervals)
    intervals = bake_intervals([float(c.duration) for c in character.clips.values()], fps)
    all_times = [np.linspace(0.0, float(c.duration), n + 1) for c, n in zip(character.clips.values(),
                                                                             intervals.tolist())]
    targets = None
    if morph_targets and getattr(mesh, "morph", None) is not None and mesh.morph.n_targets:
        try:
            targets, pos, nrm = build_target_table(mesh.morph, clip_offsets(character, all_times), pos, nrm)
        except ValueError as e:
            raise ValueError(f"character {name!r}: {e}") from None
    tables, offsets, frames, rates, durs, loops, caabb, csph, faabb = [], [], [], [], [], [], [], [], []
    off = 0
    for (cname, clip), times in zip(character.clips.items(), all_times):
        dur = float(clip.duration)
        n_int = times.shape[0] - 1
        m = _bake_clip_matrices(clip, skel, times)[:, :, :3, :]
        require_float32(character, f"clip {cname!r}: skinning matrices", m)
        mid_t = 0.5 * (times[:-1] + times[1:])
        mid = _bake_clip_matrices(clip, skel, mid_t)[:, :, :3, :]
        if targets is not None:
            mt, rows = mesh.morph, slice(off, off + n_int + 1)
            mid_off = mt.offsets(clip.morph_weights(mt, mid_t))[:, targets.source]
            fa = morph_frame_aabbs(targets, pos, jn, w, m, targets.weights[rows], mid, mid_off, SAMPLING_PAD_FACTOR)
        else:
            fa = frame_aabbs(pos, jn, w, m)
            # continuous-pose margin: LBS is linear in the matrices, so the gap
            # between the clip sampled mid-way and the GPU's interpolation is the
            # LBS of the matrix differences D (see the class Notes)
            dev = frame_aabbs(pos, jn, w, mid - 0.5 * (m[:-1] + m[1:]))
            pad = SAMPLING_PAD_FACTOR * np.abs(dev).max(axis=(0, 1)) if dev.size else np.zeros(3)
            fa = fa + np.array([-1.0, 1.0])[None, :, None] * pad
        require_float32(character, f"clip {cname!r}: skinned positions", fa)  # what bounds and the GPU get
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
        targets=targets,
        double_sided=bool(getattr(mesh, "double_sided", True)),
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
            require_float32(character, f"animation {aname!r}: positions", p0)
            require_float32(character, f"animation {aname!r}: positions", p1)
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
    return StaticRep(key, pos, nrm, col, idx, box.astype(np.float32), _sphere_of_points(pos),
                     double_sided=bool(getattr(mesh, "double_sided", True)))


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
