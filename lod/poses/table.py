"""Pose sharing, LOD side: the frame's distinct poses per skinned character and every drawn copy's pose slot.

A skinned copy is drawn at a frame coordinate (``DrawBatch.instance_data[:, 12]``: a fractional row of its
character's baked joint table, :class:`lod.full.reps.SkinnedRep`). Copies whose coordinates fall on the same
*quantised* pose share a slot; the render layer's pose cache (``render/poses/cache.py``) then blends one joint
palette and skins one set of vertices per slot, and every copy draws from its slot with only its instance
transform (issue 29: llvmpipe's vertex stage is one thread, so per-copy skinning is the serial part of a frame).

Quantisation (``[lod] pose_rate``, :data:`POSE_PARAMS`):

- ``"key"`` (default): the clip's keys as the renderer holds them, i.e. the rows of the baked joint table
  (``SkinnedRep.clip_fps``, 30 per second unless the character's ``fps`` says otherwise). A shared pose is then
  exactly one row of the table: its palette is a copy, never a blend. A copy is drawn up to half a key interval
  (1/60 s at 30 fps) from its own time.
- a rate ``r > 0`` (poses per second): local clip times rounded to multiples of ``1 / r`` (finer than the keys
  interpolates between rows as the per-copy path does; coarser shares more).
- ``0``: exact, pose sharing off: every copy its own slot at its own frame coordinate (the per-copy reference;
  the pose cache still skins each copy once, in its compute pass, instead of in the vertex stage).

Looping clips wrap: a time rounded up to the clip's duration is the clip's first pose (the baked table repeats
frame 0 there). A non-looping clip whose last key is not on the grid keeps it as a pose of its own.

Slots are numbered per group (a character: every representation of it that skins with its joint table -- the
full mesh ``none:x``, its LOD chain ``triangles:x``, its clusters ``clusters:x`` -- shares one group, so mode
auto blends a pose once for all of them) in order of first appearance over the DrawList's batches, which keeps
them a pure function of the DrawList. :func:`assign_slots` is the numba kernel (a parallel quantisation pass
above :data:`ASSIGN_PARALLEL_MIN` instances, then a serial first-appearance pass over a dense key table),
:func:`assign_slots_numpy` its plain numpy reference (tests compare them). The slot goes to the instance float
:data:`SLOT_FLOAT` (``i_anim.y`` in the shaders) and the pose's frame coordinate replaces the copy's own in
:data:`FRAME_FLOAT` (``i_anim.x``), so whatever reads a copy's animation -- the posed vertices, a skinning
palette, the morph-target weights, a point placement -- sees one and the same pose; :class:`PoseTable` (``DrawList.poses``) lists each group's
distinct frame coordinates in slot order, and ``DrawList.stats`` gains ``"poses"`` (distinct poses) and
``"posed_vertices"`` (vertices the pose cache skins for the meshes drawn from it: each in the slots its copies
draw).
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from sim.params import Param, ParamError

#: ``[lod] pose_rate`` value that quantises to the clip's keys (the baked rows)
KEY_RATE = "key"
#: instance float holding the pose slot (``i_anim.y``; render/clusters/cuts.py's PALETTE_SLOT_FLOAT)
SLOT_FLOAT = 13
#: instance float holding the frame coordinate (``i_anim.x``)
FRAME_FLOAT = 12
#: highest accepted ``pose_rate`` (poses per second)
RATE_MAX = 1000.0
#: instances from which the quantisation pass runs in parallel
ASSIGN_PARALLEL_MIN = 200_000
#: tolerance (frames) of the loop wrap and of the grid's end
_EPS = 1e-6


def mesh_digest(rep) -> str:
    """Content key of a skinned rep's posed mesh: reps with equal vertices, skin and targets share it."""
    h = hashlib.sha1()
    for a in (rep.positions, rep.normals, rep.joints, rep.weights):
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    t = getattr(rep, "targets", None)
    if t is not None:
        for a in (t.first, t.count, t.column, t.dpos, t.dnrm, t.weights):
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


class PoseRate(Param):
    """``pose_rate``: ``"key"`` or a number of poses per second ``>= 0`` (0 = exact per-copy time)."""

    def describe(self) -> str:
        return f'"{KEY_RATE}" or a number >= 0 and <= {RATE_MAX:g} (poses per second; 0 = exact)'

    def check(self, key: str, value):
        if isinstance(value, str):
            if value != KEY_RATE:
                raise ParamError(key, f"expected {self.describe()}, got {value!r}")
            return value
        try:
            return Param("float", min=0.0, max=RATE_MAX).check(key, value)
        except ParamError:
            raise ParamError(key, f"expected {self.describe()}, got {value!r}") from None


#: ``[lod]`` keys of pose sharing, valid for every mode (joined into lod.temporal.selection.LOD_COMMON_PARAMS)
POSE_PARAMS: dict = {
    "pose_rate": PoseRate("float", KEY_RATE, min=0.0, max=RATE_MAX,
                          doc="copies of a character in the same pose (same clip, time quantised to this many poses "
                              "per second; \"key\": the clip's baked keys) are skinned once per frame; 0 = exact "
                              "per-copy time"),
}


def check_rate(rate):
    """``rate`` validated (``"key"`` or a float in [0, RATE_MAX]); ValueError otherwise."""
    try:
        return POSE_PARAMS["pose_rate"].check("pose_rate", rate)
    except ParamError as e:
        raise ValueError(f"[lod] {e}") from None


def pose_source(rep):
    """The :class:`lod.full.reps.SkinnedRep` whose joint table ``rep``'s frame coordinates index, or None
    (a representation that does not draw skinned poses). A skinned rep is its own source, a clusters rep
    skins with its ``skinned``; any other rep may name one with a ``pose_source`` attribute."""
    src = getattr(rep, "pose_source", None)
    if src is not None:
        return src
    kind = getattr(rep, "kind", None)
    if kind == "skinned" and hasattr(rep, "joint_table"):
        return rep
    if kind == "clusters":
        return getattr(rep, "skinned", None)
    return None


def group_name(rep_key: str) -> str:
    """The character a representation key names: ``"none:walker"``, ``"clusters:walker#skin"`` -> ``"walker"``."""
    return rep_key.split(":", 1)[-1].split("#", 1)[0]


def _same_clips(a, b) -> bool:
    return (a.joint_table.shape == b.joint_table.shape and np.array_equal(a.clip_offset, b.clip_offset)
            and np.array_equal(a.clip_frames, b.clip_frames) and np.allclose(a.clip_fps, b.clip_fps, rtol=0, atol=0)
            and np.array_equal(a.clip_loop, b.clip_loop))


@dataclass
class PoseGroup:
    """The representations of one character that skin with one joint table.

    key : group name; index : position in the registry; source : the SkinnedRep whose joint table (and
    morph-target weights) the poses index; reps : keys of the representations in the group
    """

    key: str
    index: int
    source: object
    reps: list = field(default_factory=list)

    @property
    def n_joints(self) -> int:
        return int(self.source.joint_table.shape[1])


@dataclass
class PoseSet:
    """The distinct poses of one group in one frame.

    group : PoseGroup; frames : (P,) float64 frame coordinates in the group's joint table, slot order;
    instances : copies drawn with them
    """

    group: PoseGroup
    frames: np.ndarray
    instances: int

    @property
    def n_poses(self) -> int:
        return int(self.frames.shape[0])


@dataclass
class PoseTable:
    """The frame's pose sharing (``DrawList.poses``): per group the distinct poses in slot order.

    rate : the ``pose_rate`` it was formed with; sets : group key -> PoseSet (groups drawn this frame);
    rep_group : representation key -> group key (every registered representation)
    """

    rate: object
    sets: dict
    rep_group: dict

    def set_of(self, rep_key: str):
        """The PoseSet of the group drawing representation ``rep_key`` this frame, or None."""
        g = self.rep_group.get(rep_key)
        return None if g is None else self.sets.get(g)

    @property
    def n_poses(self) -> int:
        return int(sum(s.n_poses for s in self.sets.values()))

    @property
    def exact(self) -> bool:
        return not isinstance(self.rate, str) and float(self.rate) == 0.0


# ---------------------------------------------------------------------------- clip tables
@dataclass
class _Clips:
    """Flat clip tables of all groups (kernel inputs)."""

    g_first: np.ndarray  # (G,) int64 first clip of each group
    g_count: np.ndarray  # (G,) int64 clips of each group
    off: np.ndarray  # (C,) float64 first row
    last: np.ndarray  # (C,) float64 last local row (frames - 1)
    loop: np.ndarray  # (C,) bool
    step: np.ndarray  # (C,) float64 frames per pose step (0 = exact)
    keys: np.ndarray  # (C,) int64 grid points of the clip (+1: a non-grid last key)
    key_base: np.ndarray  # (C,) int64 first key of the clip in the dense table
    n_keys: int


def _clip_tables(groups: list, rate) -> _Clips:
    off, last, loop, step, keys = [], [], [], [], []
    g_first, g_count = [], []
    for g in groups:
        s = g.source
        g_first.append(len(off))
        g_count.append(len(s.clip_offset))
        for c in range(len(s.clip_offset)):
            n_last = float(int(s.clip_frames[c]) - 1)
            fps = float(s.clip_fps[c])
            st = 1.0 if rate == KEY_RATE else (0.0 if float(rate) == 0.0 else fps / float(rate))
            if not (st >= 0.0 and math.isfinite(st)):
                st = 1.0
            off.append(float(s.clip_offset[c]))
            last.append(n_last)
            loop.append(bool(s.clip_loop[c]))
            step.append(st)
            keys.append(int(math.floor(n_last / st + _EPS)) + 2 if st > 0.0 else 0)
    keys_a = np.asarray(keys, np.int64)
    base = np.concatenate([[0], np.cumsum(keys_a)[:-1]]).astype(np.int64) if len(keys) else np.zeros(0, np.int64)
    return _Clips(np.asarray(g_first, np.int64), np.asarray(g_count, np.int64), np.asarray(off, np.float64),
                  np.asarray(last, np.float64), np.asarray(loop, np.bool_), np.asarray(step, np.float64), keys_a,
                  base, int(keys_a.sum()))


# ---------------------------------------------------------------------------- assignment
@njit(cache=True, inline="always")
def _quantise_one(i, gi, f, g_first, g_count, off, last, loop, step, keys, key_base, key, qf):  # pragma: no cover
    g = gi[i]
    lo = g_first[g]
    hi = lo + g_count[g]
    x = f[i]
    while hi - lo > 1:  # the last clip of the group whose first row is <= x
        mid = (lo + hi) // 2
        if off[mid] <= x:
            lo = mid
        else:
            hi = mid
    c = lo
    lf = min(max(x - off[c], 0.0), last[c])
    st = step[c]
    if st <= 0.0:
        key[i] = -1
        qf[i] = off[c] + lf
        return
    k = math.floor(lf / st + 0.5)
    q = k * st
    n_grid = keys[c] - 1
    if loop[c] and q >= last[c] - _EPS:
        k = 0  # the clip's end is its start
        q = 0.0
    elif q > last[c] + _EPS:
        k = n_grid  # a last key off the grid
        q = last[c]
    key[i] = key_base[c] + k
    qf[i] = off[c] + q


@njit(cache=True)
def _quantise(gi, f, g_first, g_count, off, last, loop, step, keys, key_base, key, qf):  # pragma: no cover
    for i in range(f.shape[0]):
        _quantise_one(i, gi, f, g_first, g_count, off, last, loop, step, keys, key_base, key, qf)


@njit(cache=True, parallel=True)
def _quantise_parallel(gi, f, g_first, g_count, off, last, loop, step, keys, key_base, key, qf):  # pragma: no cover
    for i in prange(f.shape[0]):  # each instance writes only its own key and frame
        _quantise_one(i, gi, f, g_first, g_count, off, last, loop, step, keys, key_base, key, qf)


@njit(cache=True)
def _first_appearance(gi, key, qf, n_keys, n_groups, slot, pose_group, pose_frame):  # pragma: no cover
    """Serial: slot of every instance (first appearance per group); returns the number of poses."""
    table = np.full(n_keys, -1, np.int64)
    count = np.zeros(n_groups, np.int64)
    n = 0
    for i in range(key.shape[0]):
        g = gi[i]
        k = key[i]
        if k >= 0 and table[k] >= 0:
            slot[i] = table[k]
            continue
        s = count[g]
        count[g] += 1
        slot[i] = s
        if k >= 0:
            table[k] = s
        pose_group[n] = g
        pose_frame[n] = qf[i]
        n += 1
    return n


def assign_slots(gi, f, clips: _Clips, n_groups: int, parallel_min: int = ASSIGN_PARALLEL_MIN):
    """Pose slots of instances (numba).

    Parameters
    ----------
    gi : (n,) int64 group of each instance; f : (n,) float64 frame coordinates (finite)
    clips : the flat clip tables (:func:`_clip_tables`); n_groups : groups in the registry

    Returns
    -------
    slot : (n,) int64 slot within the instance's group; frame : (n,) float64 the frame coordinate of its pose;
    pose_group : (P,) int64 and pose_frame : (P,) float64 the distinct poses in order of first appearance (each
    group's in slot order)
    """
    n = int(f.shape[0])
    gi = np.ascontiguousarray(gi, np.int64)
    f = np.ascontiguousarray(f, np.float64)
    key = np.empty(n, np.int64)
    qf = np.empty(n, np.float64)
    args = (gi, f, clips.g_first, clips.g_count, clips.off, clips.last, clips.loop, clips.step, clips.keys,
            clips.key_base, key, qf)
    (_quantise_parallel if n >= parallel_min else _quantise)(*args)
    slot = np.empty(n, np.int64)
    pg = np.empty(n, np.int64)
    pf = np.empty(n, np.float64)
    m = _first_appearance(gi, key, qf, max(1, clips.n_keys), max(1, int(n_groups)), slot, pg, pf)
    return slot, qf, pg[:m].copy(), pf[:m].copy()


def assign_slots_numpy(gi, f, clips: _Clips, n_groups: int):
    """Reference of :func:`assign_slots` (plain numpy, same results)."""
    gi = np.asarray(gi, np.int64)
    f = np.asarray(f, np.float64)
    n = f.shape[0]
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64), np.zeros(0)
    c = np.empty(n, np.int64)
    for g in range(int(n_groups)):
        m = gi == g
        a, k = int(clips.g_first[g]), int(clips.g_count[g])
        c[m] = a + np.clip(np.searchsorted(clips.off[a:a + k], f[m], side="right") - 1, 0, k - 1)
    lf = np.clip(f - clips.off[c], 0.0, clips.last[c])
    st = clips.step[c]
    exact = st <= 0.0
    k = np.floor(lf / np.where(exact, 1.0, st) + 0.5)
    q = k * st
    wrap = clips.loop[c] & (q >= clips.last[c] - _EPS)
    beyond = ~wrap & (q > clips.last[c] + _EPS)
    k = np.where(wrap, 0, np.where(beyond, clips.keys[c] - 1, k)).astype(np.int64)
    q = np.where(wrap, 0.0, np.where(beyond, clips.last[c], q))
    key = np.where(exact, -1, clips.key_base[c] + k)
    qf = clips.off[c] + np.where(exact, lf, q)
    # an exact instance is a key of its own; a quantised one shares its key's first appearance
    ident = np.where(exact, -1 - np.arange(n), key)
    _, first, inv = np.unique(ident, return_index=True, return_inverse=True)
    new = np.zeros(n, bool)
    new[first] = True
    leader = first[inv]  # the instance whose pose each instance uses
    slot = np.zeros(n, np.int64)
    for g in range(int(n_groups)):
        m = new & (gi == g)
        slot[m] = np.arange(int(m.sum()))
    slot = slot[leader]
    order = np.flatnonzero(new)
    return slot, qf, gi[order], qf[order]


# ---------------------------------------------------------------------------- sharing
class PoseSharing:
    """The registry of skinned representations and the per-frame slot assignment.

    Parameters
    ----------
    rate : ``pose_rate``: ``"key"`` (default), poses per second > 0, or 0 (exact)
    use_kernel : the numba kernel (default) or the numpy reference
    """

    def __init__(self, rate=KEY_RATE, use_kernel: bool = True):
        self._rate = check_rate(rate)
        self.use_kernel = bool(use_kernel)
        self.groups: dict = {}  # group key -> PoseGroup
        self._rep_group: dict = {}  # rep key -> group key
        self._rep_mesh: dict = {}  # rep key -> (mesh digest, vertices) when its batches draw from posed vertices
        self._clips = None

    @property
    def rate(self):
        return self._rate

    @rate.setter
    def rate(self, value) -> None:
        self._rate = check_rate(value)
        self._clips = None

    def register(self, reps) -> None:
        """Add representations (those without skinned poses are ignored). A representation joins the group of
        its character when its joint table has the same shape and clips, else it forms a group of its own."""
        for r in reps:
            src = pose_source(r)
            if src is None or r.key in self._rep_group:
                continue
            name = group_name(r.key)
            g = self.groups.get(name)
            if g is not None and not _same_clips(g.source, src):
                name = r.key
                g = self.groups.get(name)
            if g is None:
                g = self.groups[name] = PoseGroup(name, len(self.groups), src)
                self._clips = None
            g.reps.append(r.key)
            self._rep_group[r.key] = name
            if getattr(r, "kind", None) == "skinned":  # (the posed mesh it draws from, its vertices)
                self._rep_mesh[r.key] = (mesh_digest(r), int(np.asarray(r.positions).shape[0]))

    def group_of(self, rep_key: str):
        return self._rep_group.get(rep_key)

    def assign(self, drawlist) -> PoseTable:
        """Give every drawn copy of a registered representation its slot (instance float :data:`SLOT_FLOAT`,
        in place), attach the frame's :class:`PoseTable` as ``drawlist.poses`` and count ``stats["poses"]``
        and ``stats["posed_vertices"]``; returns the table.

        Raises FloatingPointError when a copy's frame coordinate is NaN or Inf (nothing non-finite is drawn).
        """
        groups = list(self.groups.values())
        if self._clips is None:
            self._clips = _clip_tables(groups, self._rate)
        bs, gi, fs = [], [], []
        for b in drawlist.batches:
            gk = self._rep_group.get(b.rep)
            if gk is None or not b.n_instances:
                continue
            d = np.asarray(b.instance_data)
            f = d[:, FRAME_FLOAT].astype(np.float64)
            if not np.isfinite(f).all():
                raise FloatingPointError(f"DrawBatch {b.rep!r} part {b.part}: a frame coordinate is NaN or Inf; "
                                         "refusing to pose it")
            bs.append(b)
            fs.append(f)
            gi.append(np.full(f.shape[0], self.groups[gk].index, np.int64))
        n_groups = len(groups)
        if bs:
            gi_a, f_a = np.concatenate(gi), np.concatenate(fs)
            if self.use_kernel:
                slot, qf, pg, pf = assign_slots(gi_a, f_a, self._clips, n_groups)
            else:
                slot, qf, pg, pf = assign_slots_numpy(gi_a, f_a, self._clips, n_groups)
        else:
            slot, qf, pg, pf = np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64), np.zeros(0)
        a = 0
        for b in bs:
            k = b.n_instances
            if not b.instance_data.flags.writeable:
                b.instance_data = np.array(b.instance_data, np.float32)
            b.instance_data[:, SLOT_FLOAT] = slot[a:a + k]
            b.instance_data[:, FRAME_FLOAT] = qf[a:a + k]  # the pose's frame: every reader of i_anim.x agrees
            a += k
        counts = np.bincount(np.concatenate(gi) if gi else np.zeros(0, np.int64), minlength=n_groups)
        order = np.argsort(pg, kind="stable")
        pg, pf = pg[order], pf[order]
        cut = np.searchsorted(pg, np.arange(n_groups + 1))
        sets = {g.key: PoseSet(g, pf[cut[g.index]:cut[g.index + 1]].copy(), int(counts[g.index]))
                for g in groups if counts[g.index]}
        table = PoseTable(self._rate, sets, dict(self._rep_group))
        # the pose cache skins a mesh in the slots its copies draw only (render.poses.cache.PoseCache.posed)
        # (reps of one mesh -- a chain drawn from the full mesh's vertices -- share its posed vertices)
        used: dict = {}  # (group, mesh) -> (poses,) bool: the slots its copies read (a mask: no sort of a million)
        a = 0
        for b in bs:
            m = self._rep_mesh.get(b.rep)
            if m is not None:
                g = self._rep_group[b.rep]
                mask = used.get((g, m))
                if mask is None:
                    mask = used[(g, m)] = np.zeros(sets[g].n_poses, np.bool_)
                mask[slot[a:a + b.n_instances]] = True
            a += b.n_instances
        drawlist.poses = table
        drawlist.stats["poses"] = table.n_poses
        drawlist.stats["posed_vertices"] = int(sum(int(mask.sum()) * m[1] for (_, m), mask in used.items()))
        return table


__all__ = ["ASSIGN_PARALLEL_MIN", "KEY_RATE", "POSE_PARAMS", "RATE_MAX", "SLOT_FLOAT", "PoseGroup", "PoseRate",
           "PoseSet", "PoseSharing", "PoseTable", "assign_slots", "assign_slots_numpy", "check_rate", "group_name",
           "mesh_digest", "pose_source"]
