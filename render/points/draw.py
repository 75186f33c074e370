"""Drawer of point-hierarchy representations (kind ``"points"``; Wand & Straßer
2002, §3.2 rendering; splatting after Schütz, Kerbl and Wimmer, *Rendering
Point Clouds with Compute Shaders*).

GPU storage: the points of every uploaded representation in one storage
buffer (32 bytes each: start/end position as unorm16 in the representation's
box, colours RGBA8, octahedral normals; ``shaders/points/points_common.glsl``), and
per representation its keyframed vertices in the same layout and every
segment's triangles as corner vertex indices in ``tri_order`` order. The box
(:func:`sample_box`) is folded into each instance's model matrix
(:func:`fold_box`), so no shader dequantises. Per frame, the instance data of
all point batches go into one buffer, the traversal's (instance, range) point
jobs of all representations into one table per screen-door fade (exclusive
prefix sums of the counts), and its triangle jobs into an indexed draw list of
(vertex, instance) items (:func:`indexed_triangle_jobs`).

Drawing, after the built-in triangle batches:

1. the selected triangles, one indexed draw per representation pulling their
   vertices (``points_tri.vert``), depth-tested and lit like every other
   triangle;
2. the points. ``"compute"`` (main path): a compute pass projecting every
   selected point (interpolated between the keyframes at the instance's u,
   transformed by its model matrix) and doing ``atomicMin`` of its window
   depth into the anchor slot of its s x s pixel footprint (s = splat size
   1..3; the footprint is the GL point rule's); the first point of an anchor
   marks its TILE x TILE tile. A second pass where the points on an anchor's
   nearest surface add their lit colour, weighted, into the anchor's
   accumulators (:mod:`render.points.blend`; ``[lod] splat_blend = 0``: the
   nearest point alone). Then a resolve over the pixels the marked tiles reach
   (merged into runs per tile row, or one full-screen triangle when they cover
   most of the screen) takes per pixel the nearest of the s x s anchors whose
   footprints cover it and the weighted mean of those on its surface (the same
   as scattering into every footprint pixel, with one atomic per point, four
   when blending, instead of s * s) and writes colour and ``gl_FragDepth``, so the
   fixed-function depth test compares points with the triangles already in
   the depth buffer (no depth texture needed). The next frame's clear resets
   only the marked tiles. llvmpipe offers no 64-bit atomics, hence two passes
   instead of one packed (depth, index) atomicMin. One work group takes
   SPLAT_JOBS_PER_GROUP consecutive jobs. ``"gl_points"`` (reference): the
   same points as ``GL_POINTS`` of size s, one (point, instance) item per
   vertex.
"""
from __future__ import annotations

import moderngl
import numpy as np

from lod.drawlist import fade_uniform
from render.points import occlusion as occ
from render.points.blend import BLEND_FOOTPRINTS, blend_uniforms, rule_defines
from render.points import pack
from render.context import release_all, track
from render.points.follow import FollowFrame
from render.points.follow import upload as upload_follow
from render.points.frame import instance_windows
from render.screen import rect_vertices, resolve_rects
from render.points.samples import (SAMPLE_BYTES, SAMPLE_WORDS, fold_box, oct_encode, oct_words,  # noqa: F401
                                pack_samples, rgba8_words, sample_box, unpack_samples)
from render.points.jobs import (TRI_RANGE_CACHE, expand_jobs, indexed_triangle_jobs)  # noqa: F401 (re-exported)
from render.shaders import load_source, program_sources
from render.tint import TINT_BYTES

#: threads per work group of the splat passes (they stride over each job's points); 8 is
#: llvmpipe's SIMD width and measured 2x faster than 64 there (mean job: 160
#: points); a hardware GPU wants 64 or more
SPLAT_GROUP = 8
#: border (pixels) of the anchor grid below and left of the image: a splat of
#: size s <= 3 anchored there still covers pixel 0 (points_splat.glsl MARGIN)
MARGIN = 2
#: consecutive jobs per work group of the splat passes (points_splat.glsl
#: JOBS_PER_GROUP): a far view of many instances has many short jobs (grid:
#: 8,400 jobs of ~32 points) and a work group has a fixed cost on llvmpipe; 16
#: measured 1.2x faster than 1 on the grid's draw (20.0 vs 25.9 ms at 640x480,
#: 42.5 vs 49.7 ms at 1280x720) and no slower on long jobs
SPLAT_JOBS_PER_GROUP = 16
#: jobs of at most this many points are splatted one job per thread (``THREAD_PER_JOB`` in
#: points_splat.glsl) instead of one job per work group: a far crowd drawn coarser than its roots
#: (lod/points/coarse.py) has a million jobs of one or two points, where a work group per job
#: leaves 7 of its 8 threads idle; the image is the same (the passes' atomics are order-free)
SHORT_JOB_POINTS = 4
#: side (anchor slots) of the tiles the depth pass marks: the resolve draws only
#: the blocks of pixels whose footprints reach a marked tile and the next clear
#: resets only marked tiles; a far view fills few of them (the 400-instance splat
#: benchmark: 9 % of the 8 x 8 tiles; its resolve 0.9 ms instead of 5.8 ms)
TILE = 8
#: consecutive tiles of the filled-tile list per work group of the clear pass
TILES_PER_GROUP = 4
#: the resolve draws one full-screen triangle instead of the touched rectangles
#: when they cover more than this share of the screen (llvmpipe rasterizes one
#: large triangle about 1.4x cheaper per pixel than 32 x 32 quads, measured)
FULL_RESOLVE_SHARE = 0.6
#: the clear resets every anchor slot instead of the touched tiles' when more than
#: this share of the tiles was touched
FULL_CLEAR_SHARE = 0.5
#: work-group size of the clear pass (must match points_clear.glsl)
CLEAR_GROUP = 256
#: instance rows of a storage-buffer window are a multiple of this (32 x 64 B instance rows, 32 x 8 B colour
#: words: offsets on 256-byte boundaries)
WINDOW_ROWS = 32
#: largest work-group count per dispatch dimension (GL guarantees 65535)
MAX_GROUPS_X = 65535
#: point splat paths
PATHS = ("compute", "gl_points")
#: keys of ``Drawer.last_counts``: points and triangles drawn, the jobs (nodes of instances) occlusion
#: culling left out with their points and triangles, and 1 when the culling was paused this frame
COUNTS = ("points", "triangles", "occluded_point_jobs", "occluded_points", "occluded_tri_jobs",
          "occluded_triangles", "occlusion_paused", "placed_points", "posed_vertices", "poses")


def job_table(batches, key: str, bases: np.ndarray, which: str, inst_offsets: dict) -> np.ndarray:
    """(J, 4) uint32 jobs (first sample, count, instance, exclusive prefix) of
    all batches of representation ``key``; ``which`` is "point_jobs" or
    "tri_jobs", ``bases`` the first sample of each segment, ``inst_offsets``
    maps id(batch) to its first row in the frame's instance buffer."""
    parts = []
    for b in batches:
        if b.rep != key:
            continue
        j = np.asarray(getattr(b, which), np.int64).reshape(-1, 3)
        j = j[j[:, 2] > 0]
        if j.size:
            parts.append(np.stack([bases[b.part] + j[:, 1], j[:, 2], inst_offsets[id(b)] + j[:, 0]], axis=1))
    return _with_prefix(np.concatenate(parts) if parts else np.zeros((0, 3), np.int64))


def _merge_jobs(parts) -> np.ndarray:
    """One job table of several (their prefixes continued)."""
    if len(parts) == 1:
        return parts[0]
    return _with_prefix(np.concatenate([p[:, :3] for p in parts]).astype(np.int64))


def _with_prefix(j: np.ndarray) -> np.ndarray:
    """(J, 4) uint32 jobs: the (J, 3) rows (first, count, instance) and the exclusive prefix of the counts."""
    if not j.shape[0]:
        return np.zeros((0, 4), np.uint32)
    pre = np.zeros(j.shape[0], np.int64)
    np.cumsum(j[:-1, 1], out=pre[1:])
    if pre[-1] + j[-1, 1] >= 2 ** 32:
        raise ValueError(f"points drawer: {pre[-1] + j[-1, 1]} work items in one frame exceed 2**32")
    return np.concatenate([j, pre[:, None]], axis=1).astype(np.uint32)


def _sub(jobs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The rows ``mask`` of a job table, prefixes recomputed."""
    return _with_prefix(jobs[np.asarray(mask, bool)][:, :3].astype(np.int64))


class _GpuPoints:
    def __init__(self, key, objects, box, verts, corners, pbase, tbase, splat, path):
        self.key = key
        self.objects = objects
        self.box = box  # (lo, scale) of the quantised positions (sample_box)
        self.verts = verts
        self.corners = corners
        self.pbase = pbase
        self.tbase = tbase
        self.splat = splat
        self.path = path


class Drawer:
    """Plug-in drawer of ``lod.points.rep.PointsRep`` (see the module docstring).

    Attributes
    ----------
    path : None (use each rep's ``renderer``) or "compute" / "gl_points" to force one
    last_counts : dict, points and triangles drawn in the last frame
    """

    order = 10

    def __init__(self, renderer):
        self.r = renderer
        self.ctx = renderer.ctx
        if int(getattr(self.ctx, "version_code", 0)) < 430:
            raise RuntimeError(f"[lod] mode 'points' needs OpenGL 4.3 (compute shaders and storage buffers); this "
                               f"context offers {self.ctx.version_code // 100}.{self.ctx.version_code % 100 // 10}")
        self.path = None
        #: the compute splat's colour rule when the DrawList names none (render.points.blend): True, the
        #: weighted mean of the points within ``blend_footprints`` of an anchor's nearest; False, the nearest
        self.blend = True
        #: blend tolerance, splat footprints (BLEND_FOOTPRINTS)
        self.blend_footprints = BLEND_FOOTPRINTS
        #: blend weights: "area" (a point's projected area, |n . v|) or "flat" (every point alike)
        self.blend_weight = "area"
        self._blend_uniforms = {}
        self._on = True  # this frame's rule: blend (_set_blend)
        self._rule_cleared = ()  # the colour rule the anchors were last reset for
        #: bytes one storage-buffer binding may address (None: the context's GL_MAX_SHADER_STORAGE_BLOCK_SIZE)
        self.ssbo_limit = None
        self._reps: dict[str, _GpuPoints] = {}
        self._follow: dict = {}  # key -> render.points.follow.FollowGpu
        self._objects: list = []
        self._bufs: dict = {}
        self._progs: dict = {}
        self._vaos: dict = {}  # kind -> (buffer, vertex array) of the per-frame buffers (_vao_of)
        self.last_counts = dict.fromkeys(COUNTS, 0)
        #: occlusion culling of hierarchy nodes (render.points.occlusion; compute path, no MSAA)
        self.occlusion = False
        self._occl_pause = 0  # frames left without the test (render.points.occlusion.OCCLUSION_RETRY_FRAMES)
        self._pvs = np.zeros(0, np.int64)  # keys of the jobs visible in the last frame (render.points.occlusion.job_key)
        w, h = renderer.size
        self._pixels = (w + MARGIN) * (h + MARGIN)  # anchor slots
        self._slot_tiles = (-(-(w + MARGIN) // TILE), -(-(h + MARGIN) // TILE))
        self._pixel_tiles = -(-w // TILE) * -(-h // TILE)
        self._depth = self._track(self.ctx.buffer(reserve=4 * self._pixels), "points.depth_keys")
        self._tiles = self._track(self.ctx.buffer(reserve=4 * self._slot_tiles[0] * self._slot_tiles[1]),
                                  "points.tiles")
        self._dirty = None  # anchor tiles to clear before the next splat (None: all)
        self._points = None  # the samples of every uploaded rep (upload, _append_points)
        self._points_used = 0
        self._append_points(np.zeros((1, SAMPLE_WORDS), np.uint32))  # never empty
        # per anchor slot: four accumulators (blend) or one packed colour (the nearest; points_splat.glsl)
        self._color = self._track(self.ctx.buffer(reserve=16 * self._pixels), "points.colors")

    # ------------------------------------------------------------------ resources
    def _track(self, obj, label: str):
        return track(self._objects, obj, label)  # render.context.track

    def _program(self, name, defines=()):
        defines = tuple(defines) + self.r.shadow_defines()  # points_gl, points_tri: lit.frag (shadow.glsl)
        k = (name, tuple(defines)) if defines else name
        if k not in self._progs:
            self._progs[k] = self._track(self.ctx.program(**program_sources(name, defines=tuple(defines))),
                                         f"points.program.{name}")
        return self._progs[k]

    def _compute(self, name, defines=()):
        k = (name, tuple(defines))
        if k not in self._progs:
            src = load_source(f"{name}.glsl")
            head, rest = src.split("\n", 1)
            src = head + "\n" + "".join(f"#define {d}\n" for d in defines) + rest
            self._progs[k] = self._track(self.ctx.compute_shader(src), f"points.compute.{name}")
        return self._progs[k]

    def _buffer(self, name, data: np.ndarray | None, reserve: int = 0):
        """Per-frame storage buffer ``name`` (grown by doubling) holding ``data`` (None: at least ``reserve``
        bytes, contents left as they are, for a pass to write)."""
        # a view, not a copy, of a frame's million rows
        raw = memoryview(np.ascontiguousarray(data)).cast("B") if data is not None else b""
        need = max(len(raw), int(reserve))
        b = self._bufs.get(name)
        if b is None or b.size < need:
            if b is not None:
                b.release()
                self._objects.remove(b)
            size = 1 << max(8, int(np.ceil(np.log2(max(need, 1)))))
            b = self._track(self.ctx.buffer(reserve=size, dynamic=True), f"points.{name}")
            self._bufs[name] = b
        if raw:
            b.write(raw)
        return b

    def upload(self, rep) -> None:
        """GPU storage of all segment hierarchies of a PointsRep, or of a FollowRep's samples and animation
        (``render/points/follow.py``); replaces a previous upload."""
        if rep.key in self._reps:
            self._release_rep(self._reps.pop(rep.key))
        if rep.key in self._follow:
            self._release_rep(self._follow.pop(rep.key))
        if getattr(rep, "follow", False):
            self._follow[rep.key] = upload_follow(self.ctx, rep, self._track)
            return
        ctx = self.ctx
        objs = []

        def buf(a, label):
            data = np.ascontiguousarray(a).tobytes()
            b = ctx.buffer(data) if data else ctx.buffer(reserve=16)
            b.label = f"{rep.key}.{label}"
            objs.append(b)
            return b

        hs = rep.hierarchies
        pcount = np.array([h.n_points for h in hs], np.int64)
        pbase = np.zeros(len(hs), np.int64)
        np.cumsum(pcount[:-1], out=pbase[1:])
        kf = rep.keyframed
        lo, scale = sample_box(kf.positions0, kf.positions1, *[p for h in hs for p in (h.pos0, h.pos1)])
        pts = [pack_samples(h.pos0, h.pos1, h.nrm0, h.nrm1, h.col0, h.col1, lo, scale) for h in hs]
        pbase += self._append_points(np.concatenate(pts) if pts else np.zeros((0, SAMPLE_WORDS), np.uint32))
        verts = buf(pack_samples(kf.positions0, kf.positions1, kf.normals0, kf.normals1, kf.colors0, kf.colors1,
                                 lo, scale), "vertices")
        tris = [rep.segment_triangles(s) for s in range(len(hs))]
        tcount = np.array([t.shape[0] for t in tris], np.int64)
        tbase = np.zeros(len(hs), np.int64)
        np.cumsum(tcount[:-1], out=tbase[1:])
        tri_corners = np.concatenate(tris).astype(np.uint32) if tris else np.zeros((0, 3), np.uint32)
        corners = buf(tri_corners, "corners")
        self._reps[rep.key] = _GpuPoints(rep.key, objs, (lo, scale), verts, corners, pbase, tbase,
                                         int(getattr(rep, "splat_size", 2)), getattr(rep, "renderer", "compute"))
        self._reps[rep.key].tri_corners = tri_corners
        self._reps[rep.key].tri_ranges = {}
        self._reps[rep.key].hier = rep.hierarchies  # node boxes for occlusion culling (render.points.occlusion)  # (first, count) -> (unique vertices, local corner indices)

    def _append_points(self, packed: np.ndarray) -> int:
        """Append packed samples to the buffer all reps share (grown by
        doubling, old content copied on the GPU); returns their first index.
        A replaced rep's range is not reused (uploads are rare)."""
        raw = np.ascontiguousarray(packed, np.uint32).tobytes()
        first = self._points_used
        need = (first + packed.shape[0]) * SAMPLE_BYTES
        if self._points is None or self._points.size < need:
            size = 1 << max(12, int(np.ceil(np.log2(max(need, 1)))))
            new = self._track(self.ctx.buffer(reserve=size), "points.samples")
            if self._points is not None:
                if first:
                    self.ctx.copy_buffer(new, self._points, first * SAMPLE_BYTES)
                self._objects.remove(self._points)
                self._points.release()
            self._points = new
        if raw:
            self._points.write(raw, offset=first * SAMPLE_BYTES)
        self._points_used = first + packed.shape[0]
        return first

    def _release_rep(self, g) -> None:
        for o in reversed(g.objects):
            if o in self._objects:
                self._objects.remove(o)
            o.release()

    def release(self) -> None:
        """Release every GL object (reverse creation order; safe twice)."""
        for g in list(self._reps.values()) + list(self._follow.values()):
            self._release_rep(g)
        self._reps.clear()
        self._follow.clear()
        release_all(self._objects)  # render.context: reverse order, each once
        self._bufs.clear()
        self._points = None
        self._points_used = 0
        self._progs.clear()
        self._vaos.clear()

    # ------------------------------------------------------------------ drawing
    def _uniforms(self, prog, view_proj, **vals):
        if "u_view_proj" in prog:
            prog["u_view_proj"].write(np.ascontiguousarray(view_proj.T, np.float32).tobytes())
        self.r.lighting.apply(prog)  # the scene's light (render.light; point splats receive no shadow map)
        if "u_fade" in prog:
            prog["u_fade"].value = (0.0, 0.0)
        for k, v in vals.items():
            if k in prog:
                prog[k].value = v

    def _dispatch(self, cs, items: int, group: int):
        groups = -(-items // group)
        gx = min(groups, MAX_GROUPS_X)
        gy = -(-groups // gx)
        cs.run(gx, gy, 1)

    def draw(self, batches, drawlist, view_proj) -> None:
        """Draw point batches (``lod.points.rep.PointsBatch``, and ``FollowBatch`` es of representations whose
        samples follow the animation, ``render/points/follow.py``) of this frame."""
        ctx = self.ctx
        batches = [b for b in batches if (b.rep in self._reps or b.rep in self._follow) and b.n_instances]
        self.last_counts = dict.fromkeys(COUNTS, 0)
        if not batches:
            return
        offs, rows = {}, 0
        for b in batches:
            offs[id(b)] = rows
            rows += b.n_instances
        # the model matrices also dequantise their rep's positions (fold_box, the follow reps' pose box; packed in
        # numba: render.points.pack)
        inst, finite = pack.fold_rows(batches, [self._gpu_of(b.rep).box for b in batches])
        if not finite:
            raise FloatingPointError("points drawer: instance data hold NaN or Inf")
        inst_buf = self._buffer("instances", inst)
        # colour words per instance row (variation, debug colour: render/tint.py, shaders/core/tint.glsl)
        tint_buf = self._buffer("tints", pack.batch_words(batches, self.r.tint_table))
        row_bytes = inst.shape[1] * inst.itemsize
        limit = self.ssbo_limit or int(ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27))
        # instance rows one storage binding can hold (render/points/frame.py), a multiple of WINDOW_ROWS so
        # every window's offset meets GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT (<= 256 bytes in practice)
        window = max(WINDOW_ROWS, limit // row_bytes // WINDOW_ROWS * WINDOW_ROWS)

        def bind_rows(first):  # instance rows first .. first + window - 1 (and their colour words)
            n = min(window, rows - first)
            inst_buf.bind_to_storage_buffer(1, offset=first * row_bytes, size=n * row_bytes)
            tint_buf.bind_to_storage_buffer(12, offset=first * TINT_BYTES, size=n * TINT_BYTES)

        self._win = (bind_rows, rows, window, limit)
        w, h = self.r.size
        vp = np.asarray(view_proj, np.float64)
        # batches of one screen-door fade (lod.drawlist DrawBatch.fade; lod.temporal.selection) draw together
        by_fade: dict = {}
        fol_fade: dict = {}
        for b in batches:
            (fol_fade if b.rep in self._follow else by_fade).setdefault(fade_uniform(getattr(b, "fade", None)),
                                                                         []).append(b)
        first = self._gpu_of(batches[0].rep)
        path = self.path or first.path
        # one splat size per frame (the resolve gathers s x s anchors); all reps of a scene share
        # the [lod] splat_size
        splat = int(drawlist.options.get("splat_size", first.splat))
        self._set_blend(drawlist.proj, splat, drawlist.options.get("splat_blend"))
        # samples that follow the animation: their poses placed this frame (render/points/follow.py)
        fol = None
        if fol_fade:
            fol = FollowFrame(self, [b for b in batches if b.rep in self._follow], offs, limit,
                              int(ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27)))
            self.last_counts.update({k: v for k, v in fol.counts.items()})
        # 1. the traversal's jobs: triangle tables per (fade, rep), point tables per fade over every
        # rep (their samples share one buffer)
        tris = [(f, k, g, pack.job_table(by_fade[f], k, g.tbase, "tri_jobs", offs))
                for f in by_fade for k, g in self._reps.items()]
        tris = [t for t in tris if t[3].shape[0]]
        groups = []
        for fade, bs in by_fade.items():
            parts = [pack.job_table(bs, key, g.pbase, "point_jobs", offs) for key, g in self._reps.items()]
            parts = [j for j in parts if j.shape[0]]
            if parts:
                groups.append((fade, _merge_jobs(parts)))
        if (groups or fol is not None) and path not in PATHS:
            raise ValueError(f"points drawer: path must be one of {PATHS}, got {path!r}")
        # occlusion culling (render.points.occlusion): the nearest share first, the rest tested against its depth
        # (a frame of triangles only draws them all: nothing splatted to test afterwards); the samples that
        # follow the animation are drawn without the test (their node boxes depend on the pose)
        occl = bool(self.occlusion and path == "compute" and not getattr(self.r, "samples", 0) and groups)
        if occl and self._occl_pause > 0:  # the last test found too little hidden (render.points.occlusion)
            self._occl_pause -= 1
            self.last_counts["occlusion_paused"] = 1
            occl = False
        hidden = self._occlusion_split(by_fade, tris, groups, vp, splat) if occl else None
        self._draw_triangles(tris, vp, None if hidden is None else hidden[0])
        if fol is not None:
            self._follow_triangles(fol, fol_fade, vp)
        if not groups and fol is None:
            return
        if path == "gl_points":  # the reference path: one binding (not windowed)
            self._gl_points(groups, fol, fol_fade, vp, splat)
            return
        self._depth.bind_to_storage_buffer(3)
        self._color.bind_to_storage_buffer(4)
        self._tiles.bind_to_storage_buffer(8)
        ctx.memory_barrier()  # the last frame's resolve has read the keys
        self._clear()
        ctx.memory_barrier()
        if hidden is None:
            drawn = [(f, j) for f, j in groups]
            self._splat(drawn, vp, splat, color=False)
        else:
            tri_first, pt_first = hidden[0], hidden[1]
            self._splat([(f, _sub(j, m)) for (f, j), m in zip(groups, pt_first)], vp, splat, color=False)
            # 2. the depth so far (triangles and splat anchors) as a max-depth pyramid; test the rest
            ctx.memory_barrier()
            pyr = occ.depth_pyramid(occ.occluder_depth(
                np.frombuffer(self.r.fbo.read(attachment=-1, dtype="f4", components=1), np.float32),
                np.frombuffer(self._depth.read(size=4 * self._pixels), np.uint32), (w, h), MARGIN, splat))
            # every job is tested: the untested first ones too, for the next frame's visible set
            tri_hid = [occ.occluded(r, z, pyr) for r, z, _ in hidden[2]]
            pt_hid = [occ.occluded(r, z, pyr) for r, z, _ in hidden[3]]
            self._pvs = np.unique(np.concatenate([b[2][~m] for b, m in zip(hidden[2] + hidden[3],
                                                                              tri_hid + pt_hid)]))
            work = sum(occ.TRIANGLE_WEIGHT * float(j[:, 1].astype(np.float64).sum()) for _, _, _, j in tris) + \
                sum(float(j[:, 1].astype(np.float64).sum()) for _, j in groups)
            hid = sum(occ.TRIANGLE_WEIGHT * float(j[m, 1].astype(np.float64).sum())
                      for (_, _, _, j), m in zip(tris, tri_hid)) + \
                sum(float(j[m, 1].astype(np.float64).sum()) for (_, j), m in zip(groups, pt_hid))
            if hid < occ.OCCLUSION_MIN_SHARE * work:
                self._occl_pause = occ.OCCLUSION_RETRY_FRAMES
            tri_vis = [(~a) & ~m for a, m in zip(tri_first, tri_hid)]
            pt_vis = [(~a) & ~m for a, m in zip(pt_first, pt_hid)]
            self._draw_triangles(tris, vp, tri_vis)
            self._splat([(f, _sub(j, m)) for (f, j), m in zip(groups, pt_vis)], vp, splat, color=False)
            c = self.last_counts
            for (_, _, _, j), a, v in zip(tris, tri_first, tri_vis):
                c["occluded_tri_jobs"] += int((~a & ~v).sum())
                c["occluded_triangles"] += int(j[~a & ~v, 1].astype(np.int64).sum())
            drawn = []
            for (f, j), a, v in zip(groups, pt_first, pt_vis):
                c["occluded_point_jobs"] += int((~a & ~v).sum())
                c["occluded_points"] += int(j[~a & ~v, 1].astype(np.int64).sum())
                drawn.append((f, _sub(j, a | v)))
        drawn = [(f, j) for f, j in drawn if j.shape[0]]
        self.last_counts["points"] = sum(int(j[-1, 1]) + int(j[-1, 3]) for _, j in drawn)
        if fol is not None:
            self.last_counts["points"] += self._splat_follow(fol, fol_fade, vp, splat, color=False)
        self._splat(drawn, vp, splat, color=True)
        if fol is not None:
            self._splat_follow(fol, fol_fade, vp, splat, color=True)
        # 3. resolve: the pixels the filled anchor tiles reach (the next frame's clear resets
        # only those tiles)
        tx, ty = self._slot_tiles
        flags = np.frombuffer(self._tiles.read(size=4 * tx * ty), np.uint32).reshape(ty, tx) != 0
        self._dirty = np.flatnonzero(flags.reshape(-1)).astype(np.uint32)
        if not self._dirty.shape[0]:
            return
        rects = resolve_rects(flags, (w, h), TILE, MARGIN, splat)
        if int(((rects[:, 2] - rects[:, 0]) * (rects[:, 3] - rects[:, 1])).sum()) > FULL_RESOLVE_SHARE * w * h:
            verts = np.array([[-1.0, -1.0], [3.0, -1.0], [-1.0, 3.0]], np.float32)
        else:
            verts = rect_vertices(rects, (w, h))
        rprog = self._program("points_resolve", self._rule())
        rprog["u_size"].value = (w, h)
        rprog["u_splat"].value = splat
        for k, v in self._blend_uniforms.items():
            rprog[k].value = v
        vbo = self._buffer("resolve_vertices", verts)
        vao = self._vao_of("resolve_vao", vbo, lambda: self.ctx.vertex_array(rprog, [(vbo, "2f", "in_pos")]), rprog)
        self.r.fbo.use()
        vao.render(moderngl.TRIANGLES, vertices=verts.shape[0])

    def _gpu_of(self, key):
        """The uploaded GPU resources of representation ``key`` (stored or following the animation)."""
        g = self._reps.get(key)
        return g if g is not None else self._follow[key]

    def _gl_points(self, groups, fol, fol_fade, vp, splat: int) -> None:
        """The GL_POINTS reference path: one (sample, instance) vertex per work item, not windowed."""
        ctx = self.ctx
        bind_rows = self._win[0]
        bind_rows(0)
        ctx.enable(ctx.PROGRAM_POINT_SIZE)
        todo = [(self._program("points_gl"), self._points, f, j) for f, j in groups]
        if fol is not None:
            for r in range(len(fol.rounds)):
                fol.ensure(r)
                for fade, bs in fol_fade.items():
                    j = fol.point_jobs(r, bs)
                    if j.shape[0]:
                        self._gl_points_draw(self._program("points_gl", ("PLACED",)), fol.placed_buffer(), fade, j,
                                             vp, splat)
        for prog, buf, fade, jobs in todo:
            self._gl_points_draw(prog, buf, fade, jobs, vp, splat)
        ctx.disable(ctx.PROGRAM_POINT_SIZE)

    def _gl_points_draw(self, prog, buf, fade, jobs, vp, splat: int) -> None:
        buf.bind_to_storage_buffer(0)
        self._uniforms(prog, vp)
        self._buffer("point_items", expand_jobs(jobs)).bind_to_storage_buffer(7)
        if "u_fade" in prog:
            prog["u_fade"].value = fade
        prog["u_splat"].value = float(splat)
        n = int(jobs[-1, 1]) + int(jobs[-1, 3])
        self.last_counts["points"] += n
        self._empty_for(prog).render(moderngl.POINTS, vertices=n)

    def _follow_triangles(self, fol, fol_fade, vp) -> None:
        """The triangles the traversal keeps of the representations that follow the animation, drawn from
        their poses' posed vertices (``points_tri.vert`` PLACED), round by round."""
        for r in range(len(fol.rounds)):
            tris, shift = fol.triangle_jobs(r, fol_fade)
            if not tris:
                continue
            fol.ensure(r, place=False)
            self._draw_triangles(tris, vp, placed=(fol.placed_buffer(), shift))

    def _splat_follow(self, fol, fol_fade, vp, splat: int, color: bool) -> int:
        """One splat pass over the placed samples of every round; returns the points splatted."""
        n = 0
        for r in range(len(fol.rounds)):
            groups = [(fade, fol.point_jobs(r, bs)) for fade, bs in fol_fade.items()]
            groups = [(f, j) for f, j in groups if j.shape[0]]
            if not groups:
                continue
            fol.ensure(r)
            fol.placed_buffer().bind_to_storage_buffer(0)
            self._splat(groups, vp, splat, color, placed=True)
            n += sum(int(j[-1, 1]) + int(j[-1, 3]) for _, j in groups)
        self._points.bind_to_storage_buffer(0)
        return n

    def _draw_triangles(self, tris, vp, masks=None, placed=None) -> None:
        """Draw triangle job tables [(fade, key, gpu rep, jobs)], only the rows of
        ``masks`` (a bool array per table) when given. ``placed``: (buffer, shift) of the
        representations that follow the animation: their vertices are the posed ones in
        ``buffer``, vertex v of instance row i at ``shift[i] + v`` (render/points/follow.py)."""
        tprog = self._program("points_tri", ("PLACED",) if placed is not None else ())
        self._uniforms(tprog, vp)
        for i, (fade, key, g, jobs) in enumerate(tris):
            if masks is not None:
                jobs = _sub(jobs, masks[i])
            if not jobs.shape[0]:
                continue
            if "u_fade" in tprog:
                tprog["u_fade"].value = fade
            bind_rows, rows, window, limit = self._win
            pieces = instance_windows(jobs, rows, window, max(1, limit // 16))
            while pieces:
                first, piece = pieces.pop(0)
                # indexed: one (vertex, instance) item per vertex a job's triangles use, so a
                # vertex shared by several triangles is transformed once
                items, index = indexed_triangle_jobs(piece, g.tri_corners, g.tri_ranges)
                if items.nbytes > limit and piece.shape[0] > 1:  # halve until it binds
                    half = piece.shape[0] // 2
                    pieces[:0] = [(first, piece[:half]), (first, piece[half:])]
                    continue
                bind_rows(first)
                if placed is not None:  # the instance's pose's posed vertices
                    items = items.copy()
                    items[:, 0] += placed[1][first + items[:, 1].astype(np.int64)].astype(np.uint32)
                self._buffer("tri_items", items).bind_to_storage_buffer(7)
                (g.verts if placed is None else placed[0]).bind_to_storage_buffer(5)
                ibo = self._buffer("tri_index", index)
                vao = self._vao_of("tri_vao" if placed is None else "tri_vao_placed", ibo,
                                   lambda: self.ctx.vertex_array(tprog, [], index_buffer=ibo, index_element_size=4),
                                   tprog)
                vao.render(moderngl.TRIANGLES, vertices=int(index.shape[0]))
            self.last_counts["triangles"] += int(jobs[-1, 1]) + int(jobs[-1, 3])

    def _splat(self, groups, vp, splat: int, color: bool, placed: bool = False) -> None:
        """One splat pass (depth keys, or with ``color`` the colour of the winners)
        over point job tables [(fade, jobs)] of the stored samples (bound at 0), or with ``placed`` of the
        frame's placed samples (``render/points/follow.py``, bound at 0 by the caller)."""
        if not placed:
            self._points.bind_to_storage_buffer(0)
        w, h = self.r.size
        common = (f"LOCAL_SIZE {SPLAT_GROUP}", f"MARGIN {MARGIN}", f"JOBS_PER_GROUP {SPLAT_JOBS_PER_GROUP}",
                  f"TILE {TILE}")
        bind_rows, rows, window, limit = self._win
        # per fade: the short jobs (one per thread) and the others (one per work group), in windows that bind
        for fade, jobs in groups:
            if not jobs.shape[0]:
                continue
            short = jobs[:, 1] <= SHORT_JOB_POINTS
            for thread, sel in ((True, short), (False, ~short)):
                if not sel.any():
                    continue
                t = jobs if sel.all() else np.ascontiguousarray(jobs[sel])
                cs = self._compute("points_splat", (("COLOR_PASS",) if color else ()) + common + self._rule()
                                   + (("THREAD_PER_JOB",) if thread else ()) + (("PLACED",) if placed else ()))
                self._uniforms(cs, vp, u_size=(w, h), u_tiles_x=self._slot_tiles[0], u_splat=splat,
                               **self._blend_uniforms)
                if "u_fade" in cs:
                    cs["u_fade"].value = fade
                for first, piece in instance_windows(t, rows, window, limit // 16):
                    bind_rows(first)
                    self._buffer("point_jobs", piece).bind_to_storage_buffer(2)
                    cs["u_njobs"].value = int(piece.shape[0])
                    self._dispatch(cs, int(piece.shape[0]), SPLAT_JOBS_PER_GROUP * (SPLAT_GROUP if thread else 1))
                    self.ctx.memory_barrier()

    def _occlusion_split(self, by_fade, tris, groups, vp, splat: int) -> tuple:
        """render.points.occlusion.split_first over this frame's job tables (the nearest share drawn first)."""
        return occ.split_first(self._reps, self._pvs, by_fade, tris, groups, vp, self.r.size, splat)

    def _rule(self) -> tuple:
        return rule_defines(self._on, self.blend_weight)

    def _set_blend(self, proj, splat: int, footprints=None) -> None:
        """This frame's colour rule (render.points.blend): the DrawList's ``splat_blend`` footprints (None: this
        drawer's ``blend`` and ``blend_footprints``; 0: the nearest point alone) and its uniforms."""
        if footprints is None:
            self._on, fp = bool(self.blend), float(self.blend_footprints)
        else:
            fp = float(footprints) if np.isfinite(footprints) else 0.0
            self._on = fp > 0.0
        self._blend_uniforms = blend_uniforms(proj, self.r.size[1], splat, fp) if self._on else {}
        if self._rule() != self._rule_cleared:  # the anchors hold the other rule's colours: reset them all
            self._dirty = None
            self._rule_cleared = self._rule()

    def _clear(self) -> None:
        """Reset the anchor slots (and tile flags) the last frame filled: all
        of them on the first frame or when most were filled, else one work
        group per filled tile."""
        tx, ty = self._slot_tiles
        dirty = self._dirty
        if dirty is not None and not dirty.shape[0]:
            return
        if dirty is None or dirty.shape[0] > FULL_CLEAR_SHARE * tx * ty:
            clear = self._compute("points_clear", self._rule())
            clear["u_pixels"].value = self._pixels
            clear["u_ntiles"].value = tx * ty
            self._dispatch(clear, max(self._pixels, tx * ty), CLEAR_GROUP)
        else:
            clear = self._compute("points_clear", ("TILE_LIST", f"TILE {TILE}", f"TILES_PER_GROUP {TILES_PER_GROUP}")
                                  + self._rule())
            self._buffer("dirty_tiles", dirty).bind_to_storage_buffer(10)
            clear["u_count"].value = int(dirty.shape[0])
            clear["u_slots"].value = (self.r.size[0] + MARGIN, self.r.size[1] + MARGIN)
            clear["u_tiles_x"].value = tx
            self._dispatch(clear, int(dirty.shape[0]), TILES_PER_GROUP)
        self._dirty = np.zeros(0, np.uint32)

    def _vao_of(self, kind: str, buffer, make, prog=None):
        """The vertex array ``make()`` reading the per-frame ``buffer`` (with program ``prog``): kept
        while that buffer object is the current one (and ``prog`` its program); when the buffer was
        outgrown (replaced), or the program recompiled, the old vertex array is released."""
        entry = self._vaos.get(kind)
        if entry is None or entry[0] is not buffer or (prog is not None and entry[1].program is not prog):
            if entry is not None:
                self._objects.remove(entry[1])
                entry[1].release()
            entry = self._vaos[kind] = (buffer, self._track(make(), f"points.{kind}"))
        return entry[1]

    def _empty_for(self, prog):
        k = ("vao", id(prog))
        if k not in self._progs:
            self._progs[k] = self._track(self.ctx.vertex_array(prog, []), "points.vao")
        return self._progs[k]
