"""GPU side of mode points' representations whose samples follow the animation (``lod.points.follow``; issue 27).

Per representation (:func:`upload`), static: the rest-pose samples (triangle, barycentric, filtered colour, the
filtered normal in the sample's shading frame: 16 bytes each), the triangles' corners in the follow vertex
numbering, and the animation the mesh already has: skinned, the vertices with their skin (48 bytes each), the
baked joint table as the texture the skinned draw reads (``shaders/poses/skinning.glsl``) and the morph targets'
textures (``render/poses/targets.py``, vertex rows renumbered); keyframed, every segment's vertices at its two ends
(``render/points/draw.py`` ``pack_samples``).

Per frame (:class:`FollowFrame`), for the :class:`lod.points.rep.FollowBatch` es of the frame, one slot per
distinct pose (pose sharing: the copies of a pose place its samples once):

1. the pose pass (``shaders/points/points_pose.glsl``): each pose's vertex prefix posed into the frame's placed
   buffer: skinned, skin ∘ morph with the pose cache's palette of the pose (``render/poses/cache.py``, read by
   the slot ``lod.poses`` gave the pose's copies: the cache is the frame's one evaluation of each pose; where
   it has no palette this frame, from the joint table at the pose's baked row, counted as an evaluation of
   its own); keyframed, the keyframes' interpolation;
2. the placement pass (``shaders/points/points_place.glsl``): each pose's sample prefix, the barycentric blend of the
   posed corners, into the same buffer;
3. the drawer's splat passes read the placed samples (``PLACED`` variants of ``points_splat.glsl`` and
   ``points_gl.vert``; a job's first sample is its pose's first placed sample plus the node's), and the
   triangles the traversal keeps are drawn from the posed vertices (``points_tri.vert`` ``PLACED``).

The placed buffer is bound whole, so a frame's poses are placed in rounds of at most the storage-block limit
(llvmpipe: 128 MB, 8 M samples and vertices); with several rounds each pass poses and places its round again.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from lod.poses.table import SLOT_FLOAT
from render.points.jobs import indexed_triangle_jobs, posed_job_table

#: bytes per placed sample or posed vertex (points_placed.glsl)
PLACED_BYTES = 16
#: threads per work group of the pose and placement passes
PASS_GROUP = 64
#: texture unit of the joint table in the pose pass (its fallback: no pose palette this frame)
JOINT_UNIT = 0
#: frames of tolerance between a follow pose and the pose cache's slot it reads (float32 instance rows)
SLOT_FRAME_TOLERANCE = 1e-3


@dataclass
class FollowGpu:
    """The static GPU resources of one FollowRep (see the module docstring)."""

    key: str
    skinned: bool
    box: tuple  # (lo (3,), scale): the pose box of the placed positions (render.points.draw.sample_box)
    samples: object
    corners: object
    verts: object
    joints: object | None
    targets: tuple | None
    vcount: int  # vertices per pose (follow numbering)
    tri_corners: np.ndarray  # (T_stored, 3) uint32 corners in tri_order order, follow numbering
    vbase: np.ndarray | None  # keyframed: first vertex of each segment in ``verts``
    objects: list = field(default_factory=list)
    tri_ranges: dict = field(default_factory=dict)
    splat: int = 2
    path: str = "compute"


def pose_box(rep) -> tuple:
    """(lo, scale) of the cube holding every posed vertex of ``rep`` (its base's clip or segment boxes)."""
    from render.points.samples import sample_box

    b = rep.base
    boxes = np.asarray(b.clip_aabb if rep.skinned else b.seg_aabb, np.float64).reshape(-1, 2, 3)
    lo, scale = sample_box(boxes[:, 0], boxes[:, 1])
    pad = 1e-3 * scale
    return lo - pad, scale + 2.0 * pad


def sample_words(tree) -> np.ndarray:
    """(P, 4) uint32 rest-pose samples: triangle, barycentric unorm16x2, colour RGBA8, shading-frame normal."""
    from render.points.samples import oct_words, rgba8_words

    h = tree.octree
    out = np.zeros((h.n_points, 4), np.uint32)
    out[:, 0] = np.asarray(h.tri, np.int64).astype(np.uint32)
    b = np.rint(np.clip(np.asarray(h.bary, np.float64), 0.0, 1.0) * 65535.0).astype(np.uint32)
    out[:, 1] = b[:, 0] | (b[:, 1] << 16)
    out[:, 2] = rgba8_words(np.asarray(h.col0, np.float64))
    out[:, 3] = oct_words(np.asarray(tree.lnrm, np.float64))
    return out


def skinned_vertex_words(base, vorder) -> np.ndarray:
    """(V, 12) uint32 vertices in the follow numbering: position (float bits), normal (octahedral), colour
    (RGBA8), joints (uint16 pairs), weights (float bits): the inputs of points_pose.glsl."""
    from render.points.samples import oct_words, rgba8_words

    o = np.asarray(vorder, np.int64)
    V = o.shape[0]
    out = np.zeros((V, 12), np.uint32)
    out[:, 0:3] = np.ascontiguousarray(np.asarray(base.positions, np.float32)[o]).view(np.uint32)
    out[:, 3] = oct_words(np.asarray(base.normals, np.float64)[o])
    out[:, 4] = rgba8_words(np.asarray(base.colors, np.float64)[o])
    j = np.asarray(base.joints, np.uint32)[o]
    out[:, 5] = j[:, 0] | (j[:, 1] << 16)
    out[:, 6] = j[:, 2] | (j[:, 3] << 16)
    out[:, 8:12] = np.ascontiguousarray(np.asarray(base.weights, np.float32)[o]).view(np.uint32)
    return out


def upload(ctx, rep, track) -> FollowGpu:
    """The GPU resources of a FollowRep (``track(obj, label)`` registers each GL object)."""
    from render.points.samples import pack_samples
    from render.poses.palette import joint_texture
    from render.poses.targets import target_textures

    t = rep.tree
    objs: list = []

    def buf(a, label):
        data = np.ascontiguousarray(a).tobytes()
        b = ctx.buffer(data) if data else ctx.buffer(reserve=16)
        objs.append(track(b, f"{rep.key}.{label}"))
        return b

    lo, scale = pose_box(rep)
    samples = buf(sample_words(t), "follow_samples")
    corners = buf(np.asarray(t.corners, np.uint32), "follow_corners")
    vorder = np.asarray(t.vorder, np.int64)
    joints = targets = vbase = None
    if rep.skinned:
        b = rep.base
        verts = buf(skinned_vertex_words(b, vorder), "follow_vertices")
        joints = joint_texture(ctx, rep.key, b.joint_table)
        F = int(np.asarray(b.joint_table).shape[0])  # baked frames (the morph targets' table has as many)
        objs.append(track(joints, f"{rep.key}.follow_joints"))
        if b.targets is not None:
            tt = dataclasses.replace(b.targets, first=np.asarray(b.targets.first)[vorder],
                                     count=np.asarray(b.targets.count)[vorder])
            targets = target_textures(ctx, tt, F, f"{rep.key}.follow")
            objs.extend(track(x, f"{rep.key}.follow_targets") for x in targets)
        V = vorder.shape[0]
    else:
        kf = rep.base
        V = vorder.shape[0]
        rows = (np.asarray(rep.vbase, np.int64)[:, None] + vorder[None, :]).reshape(-1)
        verts = buf(pack_samples(kf.positions0[rows], kf.positions1[rows], kf.normals0[rows], kf.normals1[rows],
                                 kf.colors0[rows], kf.colors1[rows], lo, scale), "follow_kvertices")
        vbase = np.arange(np.asarray(rep.vbase).shape[0], dtype=np.int64) * V
    tri_corners = np.asarray(t.corners, np.uint32)[np.asarray(t.octree.tri_order, np.int64)]
    return FollowGpu(rep.key, rep.skinned, (lo, scale), samples, corners, verts, joints, targets, int(V),
                     tri_corners, vbase, objs, {}, int(getattr(rep, "splat_size", 2)),
                     str(getattr(rep, "renderer", "compute")))


def cache_slots(pal, b) -> np.ndarray | None:
    """Per pose of FollowBatch ``b``, its slot in the pose cache's palettes ``pal`` (``render.poses.cache.PosePalette``
    of b's character): the slot ``lod.poses`` gave the pose's first copy (instance float ``SLOT_FLOAT``). None when
    there is no palette this frame, a copy has no slot, or a slot's frame is not the pose's (the follow batch was
    quantised at another ``pose_rate``): the pose pass then evaluates the pose from the joint table itself."""
    if pal is None:
        return None
    slot = np.asarray(b.slot, np.int64)
    P = int(np.asarray(b.pose).shape[0])
    if not P or slot.shape[0] != b.n_instances:
        return None
    first = np.full(P, -1, np.int64)
    first[slot[::-1]] = np.arange(slot.shape[0], dtype=np.int64)[::-1]
    if (first < 0).any():
        return None
    cs = np.asarray(b.instance_data)[first, SLOT_FLOAT].astype(np.float64)  # P rows (not all n as float64 first)
    if not np.isfinite(cs).all():
        return None
    cs = np.rint(cs).astype(np.int64)
    if cs.min() < 0 or cs.max() >= pal.n_poses:
        return None
    if not (np.abs(np.asarray(pal.frames, np.float64)[cs] - np.asarray(b.pose, np.float64)) <= SLOT_FRAME_TOLERANCE).all():
        return None
    return cs


def _with_prefix(rows: np.ndarray) -> np.ndarray:
    """(J, 4) uint32 jobs: the (J, 3) columns and the exclusive prefix of column 1 (the item counts)."""
    j = np.asarray(rows, np.int64).reshape(-1, 3)
    pre = np.zeros(j.shape[0], np.int64)
    if j.shape[0] > 1:
        np.cumsum(j[:-1, 1], out=pre[1:])
    return np.concatenate([j, pre[:, None]], axis=1).astype(np.uint32)


@dataclass
class _Slot:
    batch: int  # index among the frame's follow batches
    slot: int  # pose index within the batch
    vertices: int
    samples: int


class FollowFrame:
    """One frame's placement: poses, rounds, and the job tables the drawer's passes read.

    Parameters
    ----------
    drawer : render.points.draw.Drawer (its context, programs, buffers and instance windows)
    batches : the frame's FollowBatches (of uploaded reps), in the drawer's order
    offs : id(batch) -> first row of the batch in the frame's instance buffer
    limit : bytes a round of poses may place (the drawer's storage-binding limit, maybe an injected one)
    hard : bytes one storage binding can address (the GL limit): one pose may exceed ``limit`` up to it
    """

    def __init__(self, drawer, batches, offs: dict, limit: int, hard: int | None = None):
        self.d = drawer
        self.batches = batches
        self.offs = offs
        cap = max(1, int(limit) // PLACED_BYTES)
        hard_cap = max(cap, int(hard if hard is not None else limit) // PLACED_BYTES)
        slots = [_Slot(bi, s, int(b.pose_vertices[s]), int(b.pose_points[s]))
                 for bi, b in enumerate(batches) for s in range(b.pose.shape[0])]
        slots = [s for s in slots if s.vertices + s.samples > 0]
        self.rounds: list = []
        cur, used = [], 0
        for s in slots:
            n = s.vertices + s.samples
            if cur and used + n > cap:
                self.rounds.append(cur)
                cur, used = [], 0
            if n > hard_cap:
                raise ValueError(f"points drawer: one pose of {batches[s.batch].rep!r} needs {n} placed samples and "
                                 f"vertices, above the storage-block limit of {cap}")
            cur.append(s)
            used += n
        if cur:
            self.rounds.append(cur)
        self._placed = -1  # the round the placed buffer holds
        # skinned poses read the pose cache's palettes by slot (one evaluation of each pose per frame, issue 33)
        cache = getattr(getattr(drawer, "r", None), "poses", None)
        self._pal: dict = {}  # batch index -> (PosePalette, cache slot per pose) of skinned batches the cache serves
        for bi, b in enumerate(batches):
            g = drawer._follow.get(b.rep)
            if cache is not None and g is not None and g.skinned:
                pal = cache.palette(b.rep)
                cs = cache_slots(pal, b)
                if cs is not None:
                    self._pal[bi] = (pal, cs)
        self.counts = {"placed_points": sum(s.samples for s in slots), "posed_vertices": sum(s.vertices for s in slots),
                       "poses": len(slots)}
        #: skinned poses evaluated from the joint table by this frame's pose passes (no palette of the cache)
        self.own_evaluations = 0

    # ------------------------------------------------------------------ layout
    def _layout(self, r: int):
        """Per batch (slot -> vertex base, slot -> sample base; -1: not in round r) and the buffer length."""
        vb = [np.full(b.pose.shape[0], -1, np.int64) for b in self.batches]
        sb = [np.full(b.pose.shape[0], -1, np.int64) for b in self.batches]
        n = 0
        for s in self.rounds[r]:
            vb[s.batch][s.slot] = n
            n += s.vertices
            sb[s.batch][s.slot] = n
            n += s.samples
        return vb, sb, n

    def ensure(self, r: int, place: bool = True) -> None:
        """Pose (and place) round r into the placed buffer, unless it already holds it."""
        if self._placed == r:
            return
        d = self.d
        vb, sb, n = self._layout(r)
        buf = d._buffer("follow_placed", None, reserve=max(n, 1) * PLACED_BYTES)
        buf.bind_to_storage_buffer(9)
        by_rep: dict = {}
        for s in self.rounds[r]:
            by_rep.setdefault(self.batches[s.batch].rep, []).append(s)
        for key, slots in by_rep.items():
            g = d._follow[key]
            self._pose(g, slots, vb)
        if place:
            d.ctx.memory_barrier()
            for key, slots in by_rep.items():
                self._place(d._follow[key], slots, vb, sb)
        d.ctx.memory_barrier()
        self._placed = r if place else -1

    def _pose(self, g: FollowGpu, slots, vb) -> None:
        """Pose the vertex prefixes of ``slots`` (poses of one rep) into the placed buffer. Skinned, from the pose
        cache's palettes at each pose's slot (``POSE_SLOT``: the pose evaluated once, by the cache), or, where the
        cache has none this frame, from the joint table at the pose's frame (counted in :attr:`own_evaluations`)."""
        d = self.d
        slots = [s for s in slots if s.vertices]
        if not slots:
            return
        pal = None
        if g.skinned and all(s.batch in self._pal for s in slots):
            pal = self._pal[slots[0].batch][0]
        rows, us = [], []
        for s in slots:
            b = self.batches[s.batch]
            if pal is not None:
                word = int(self._pal[s.batch][1][s.slot])
                us.append(float(b.pose[s.slot]))  # the frame: morph-target weights
            elif g.skinned:
                word = int(np.array([b.pose[s.slot]], np.float32).view(np.uint32)[0])
            else:
                word = int(g.vbase[int(b.part)])
                us.append(float(b.pose[s.slot]))
            rows.append((vb[s.batch][s.slot], s.vertices, word))
        if g.skinned and pal is None:
            self.own_evaluations += len(rows)
            r = getattr(d, "r", None)
            if r is not None:
                r.pose_evaluations += len(rows)
        jobs = _with_prefix(np.array(rows, np.int64))
        defines = (f"LOCAL_SIZE {PASS_GROUP}",)
        if g.skinned:
            if pal is not None:
                defines += ("POSE_SLOT",)
            if g.targets is not None:
                from render.poses.targets import TARGETS_DEFINE
                defines += (TARGETS_DEFINE,)
        else:
            defines += ("KEYFRAMED",)
        cs = d._compute("points_pose", defines)
        d._buffer("follow_pose_jobs", jobs).bind_to_storage_buffer(2)
        g.verts.bind_to_storage_buffer(6)
        if g.skinned:
            g.joints.use(JOINT_UNIT)  # the morph targets' and the fallback's frame pair
            if "u_joints" in cs:
                cs["u_joints"].value = JOINT_UNIT
            if pal is not None:
                pal.use(cs)
            if g.targets is not None:
                from render.poses.targets import use_targets
                use_targets(cs, g.targets)
        if us:
            d._buffer("follow_pose_u", np.asarray(us, np.float32)).bind_to_storage_buffer(10)
        lo, scale = g.box
        for name, val in (("u_lo", tuple(float(x) for x in lo)), ("u_scale", float(scale))):
            if name in cs:
                cs[name].value = val
        items = int(jobs[-1, 1]) + int(jobs[-1, 3])
        cs["u_njobs"].value = int(jobs.shape[0])
        cs["u_items"].value = items
        d._dispatch(cs, items, PASS_GROUP)

    def _place(self, g: FollowGpu, slots, vb, sb) -> None:
        d = self.d
        rows = [(sb[s.batch][s.slot], s.samples, vb[s.batch][s.slot]) for s in slots if s.samples]
        if not rows:
            return
        jobs = _with_prefix(np.array(rows, np.int64))
        cs = d._compute("points_place", (f"LOCAL_SIZE {PASS_GROUP}",))
        d._buffer("follow_place_jobs", jobs).bind_to_storage_buffer(2)
        g.samples.bind_to_storage_buffer(6)
        g.corners.bind_to_storage_buffer(5)
        items = int(jobs[-1, 1]) + int(jobs[-1, 3])
        cs["u_njobs"].value = int(jobs.shape[0])
        cs["u_items"].value = items
        d._dispatch(cs, items, PASS_GROUP)

    # ------------------------------------------------------------------ job tables
    def point_jobs(self, r: int, batches_of_fade) -> np.ndarray:
        """(J, 4) uint32 splat jobs (first placed sample, count, instance row, prefix) of round r's poses among
        ``batches_of_fade``."""
        _, sb, _ = self._layout(r)
        mine = {id(x) for x in batches_of_fade}
        return posed_job_table([(b.point_jobs, b.slot, sb[bi], self.offs[id(b)])
                                for bi, b in enumerate(self.batches) if id(b) in mine], add_base=True)

    def triangle_jobs(self, r: int, fol_fade: dict) -> tuple[list, np.ndarray]:
        """Round r's triangle job tables [(fade, key, FollowGpu, jobs (first triangle, count, instance row,
        prefix))] as the drawer's triangle pass takes them, and per instance row of the frame the first posed
        vertex of its pose (-1: not in this round)."""
        vb, _, _ = self._layout(r)
        rows = max((self.offs[id(b)] + b.n_instances for b in self.batches), default=0)
        shift = np.full(max(rows, 1), -1, np.int64)
        out = []
        for fade, bs in fol_fade.items():
            mine = {id(x) for x in bs}
            per_key: dict = {}
            for bi, b in enumerate(self.batches):
                if id(b) not in mine:
                    continue
                o = self.offs[id(b)]
                slot = np.asarray(b.slot, np.int64)
                shift[o:o + b.n_instances] = vb[bi][slot]
                per_key.setdefault(b.rep, []).append((b.tri_jobs, slot, vb[bi], o))
            for key, items in per_key.items():
                jobs = posed_job_table(items, add_base=False)
                if jobs.shape[0]:
                    out.append((fade, key, self.d._follow[key], jobs))
        return out, shift

    def placed_buffer(self):
        return self.d._bufs["follow_placed"]


__all__ = ["FollowFrame", "FollowGpu", "PLACED_BYTES", "SLOT_FRAME_TOLERANCE", "cache_slots", "pose_box", "sample_words", "skinned_vertex_words", "upload"]
