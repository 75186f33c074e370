"""Drawer of point-hierarchy representations (kind ``"points"``; Wand & Straßer
2002, §3.2 rendering; splatting after Schütz, Kerbl and Wimmer, *Rendering
Point Clouds with Compute Shaders*).

GPU storage per representation (uploaded once): all points of all segment
octrees in one storage buffer (start/end position, colour and normal, 48
bytes each, see ``shaders/points_common.glsl``), the keyframed vertices of
all segments in the same layout, and every segment's triangles as corner
vertex indices in ``tri_order`` order. Per frame, the instance data of all
point batches go into one buffer and the traversal's (instance, range) jobs
into two (points, triangles), each job with the exclusive prefix sum of the
counts. The compute splat runs one work group per SPLAT_JOBS_PER_GROUP
consecutive point jobs; the triangle
draw finds a vertex's job by binary search over the prefix sums; the
GL_POINTS reference gets one (point, instance) item per vertex.

Drawing, after the built-in triangle batches:

1. the selected triangles, one non-indexed draw pulling their vertices
   (``points_tri.vert``), depth-tested and lit like every other triangle;
2. the points. ``"compute"`` (main path): clear a per-pixel uint depth-key
   buffer, a compute pass projecting every selected point (interpolated
   between the keyframes at the instance's u, transformed by its model
   matrix) and doing ``atomicMin`` of its window depth into the anchor slot
   of its s x s pixel footprint (s = splat size 1..3; the footprint is the
   GL point rule's), a second compute pass where the point that won an anchor
   writes its lit colour there, then a full-screen resolve taking per pixel
   the nearest of the s x s anchors whose footprints cover it (the same
   result as scattering into every footprint pixel, with one atomic per point
   instead of s * s) and writing colour and ``gl_FragDepth``, so the fixed-function depth test
   compares points with the triangles already in the depth buffer (no depth
   texture needed). llvmpipe offers no 64-bit atomics, hence two passes
   instead of one packed (depth, index) atomicMin. ``"gl_points"``
   (reference): the same points as ``GL_POINTS`` of size s.
"""
from __future__ import annotations

import moderngl
import numpy as np

from lod.drawlist import fade_uniform
from render.shaders import load_source, program_sources

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
#: work-group size of the clear pass (must match points_clear.glsl)
CLEAR_GROUP = 256
#: largest work-group count per dispatch dimension (GL guarantees 65535)
MAX_GROUPS_X = 65535
#: bytes per sample (point or vertex): vec4 p0, vec4 p1, uvec4 attr
SAMPLE_BYTES = 48
#: point splat paths
PATHS = ("compute", "gl_points")


def pack_samples(p0, p1, n0, n1, c0, c1) -> np.ndarray:
    """(n, 12) uint32 words of samples in the ``Sample`` layout (positions and
    normals' z as float bits, colours RGBA8, normals' xy snorm16x2).

    Non-finite inputs are replaced by 0 (nothing non-finite reaches the GPU).
    """
    n = np.asarray(p0).shape[0]
    f = np.zeros((n, 8), np.float32)
    f[:, 0:3] = p0
    f[:, 3] = np.asarray(n0)[:, 2]
    f[:, 4:7] = p1
    f[:, 7] = np.asarray(n1)[:, 2]
    f = np.where(np.isfinite(f), f, 0.0).astype(np.float32)
    out = np.zeros((n, 12), np.uint32)
    out[:, :8] = f.view(np.uint32)

    def rgba8(c):
        c = np.nan_to_num(np.clip(np.asarray(c, np.float64), 0.0, 1.0))
        b = np.rint(c * 255.0).astype(np.uint32)
        return b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16) | (b[:, 3] << 24)

    def snorm2(v):
        v = np.nan_to_num(np.clip(np.asarray(v, np.float64)[:, :2], -1.0, 1.0))
        q = np.rint(v * 32767.0).astype(np.int16).view(np.uint16).astype(np.uint32)
        return q[:, 0] | (q[:, 1] << 16)

    out[:, 8] = rgba8(c0)
    out[:, 9] = rgba8(c1)
    out[:, 10] = snorm2(n0)
    out[:, 11] = snorm2(n1)
    return out


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
    if not parts:
        return np.zeros((0, 4), np.uint32)
    j = np.concatenate(parts)
    pre = np.zeros(j.shape[0], np.int64)
    np.cumsum(j[:-1, 1], out=pre[1:])
    if pre[-1] + j[-1, 1] >= 2 ** 32:
        raise ValueError(f"points drawer: {pre[-1] + j[-1, 1]} work items in one frame exceed 2**32")
    return np.concatenate([j, pre[:, None]], axis=1).astype(np.uint32)


def expand_jobs(jobs: np.ndarray) -> np.ndarray:
    """(total, 2) uint32 (sample, instance) per work item of a job table
    (the GL_POINTS path draws one vertex per item)."""
    counts = jobs[:, 1].astype(np.int64)
    total = int(counts.sum())
    out = np.empty((total, 2), np.uint32)
    rep_start = np.repeat(jobs[:, 0].astype(np.int64) - jobs[:, 3].astype(np.int64), counts)
    out[:, 0] = rep_start + np.arange(total)
    out[:, 1] = np.repeat(jobs[:, 2], counts)
    return out


class _GpuPoints:
    def __init__(self, key, objects, points, verts, corners, pbase, tbase, splat, path):
        self.key = key
        self.objects = objects
        self.points = points
        self.verts = verts
        self.corners = corners
        self.pbase = pbase
        self.tbase = tbase
        self.splat = splat
        self.path = path


class Drawer:
    """Plug-in drawer of ``lod.points_mode.PointsRep`` (see the module docstring).

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
        self._reps: dict[str, _GpuPoints] = {}
        self._objects: list = []
        self._bufs: dict = {}
        self._progs: dict = {}
        self.last_counts = {"points": 0, "triangles": 0}
        w, h = renderer.size
        self._pixels = (w + MARGIN) * (h + MARGIN)  # anchor slots
        self._depth = self._track(self.ctx.buffer(reserve=4 * self._pixels), "points.depth_keys")
        self._color = self._track(self.ctx.buffer(reserve=4 * self._pixels), "points.colors")
        self._empty = self._track(self.ctx.vertex_array(self._program("points_resolve"), []), "points.empty_vao")

    # ------------------------------------------------------------------ resources
    def _track(self, obj, label):
        try:
            obj.label = label
        except Exception:  # pragma: no cover
            pass
        self._objects.append(obj)
        return obj

    def _program(self, name):
        if name not in self._progs:
            self._progs[name] = self._track(self.ctx.program(**program_sources(name)), f"points.program.{name}")
        return self._progs[name]

    def _compute(self, name, defines=()):
        k = (name, tuple(defines))
        if k not in self._progs:
            src = load_source(f"{name}.glsl")
            head, rest = src.split("\n", 1)
            src = head + "\n" + "".join(f"#define {d}\n" for d in defines) + rest
            self._progs[k] = self._track(self.ctx.compute_shader(src), f"points.compute.{name}")
        return self._progs[k]

    def _buffer(self, name, data: np.ndarray):
        """Per-frame storage buffer ``name`` (grown by doubling) holding ``data``."""
        raw = np.ascontiguousarray(data).tobytes()
        b = self._bufs.get(name)
        if b is None or b.size < len(raw):
            if b is not None:
                b.release()
                self._objects.remove(b)
            size = 1 << max(8, int(np.ceil(np.log2(max(len(raw), 1)))))
            b = self._track(self.ctx.buffer(reserve=size, dynamic=True), f"points.{name}")
            self._bufs[name] = b
        if raw:
            b.write(raw)
        return b

    def upload(self, rep) -> None:
        """GPU storage of all segment hierarchies of a PointsRep (replaces a previous upload)."""
        if rep.key in self._reps:
            self._release_rep(self._reps.pop(rep.key))
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
        pts = [pack_samples(h.pos0, h.pos1, h.nrm0, h.nrm1, h.col0, h.col1) for h in hs]
        points = buf(np.concatenate(pts) if pts else np.zeros((0, 12), np.uint32), "points")
        kf = rep.keyframed
        verts = buf(pack_samples(kf.positions0, kf.positions1, kf.normals0, kf.normals1, kf.colors0, kf.colors1),
                    "vertices")
        tris = [rep.segment_triangles(s) for s in range(len(hs))]
        tcount = np.array([t.shape[0] for t in tris], np.int64)
        tbase = np.zeros(len(hs), np.int64)
        np.cumsum(tcount[:-1], out=tbase[1:])
        corners = buf(np.concatenate(tris).astype(np.uint32) if tris else np.zeros((0, 3), np.uint32), "corners")
        self._reps[rep.key] = _GpuPoints(rep.key, objs, points, verts, corners, pbase, tbase,
                                         int(getattr(rep, "splat_size", 2)), getattr(rep, "renderer", "compute"))

    def _release_rep(self, g) -> None:
        for o in reversed(g.objects):
            o.release()

    def release(self) -> None:
        """Release every GL object (reverse creation order; safe twice)."""
        for g in list(self._reps.values()):
            self._release_rep(g)
        self._reps.clear()
        for o in reversed(self._objects):
            try:
                o.release()
            except Exception:  # pragma: no cover
                pass
        self._objects.clear()
        self._bufs.clear()
        self._progs.clear()

    # ------------------------------------------------------------------ drawing
    def _uniforms(self, prog, view_proj, **vals):
        from render.renderer import AMBIENT, SUN_DIRECTION

        if "u_view_proj" in prog:
            prog["u_view_proj"].write(np.ascontiguousarray(view_proj.T, np.float32).tobytes())
        if "u_sun" in prog:
            s = np.asarray(SUN_DIRECTION, np.float64)
            prog["u_sun"].value = tuple((s / np.linalg.norm(s)).tolist())
        if "u_ambient" in prog:
            prog["u_ambient"].value = AMBIENT
        if "u_tint" in prog:
            prog["u_tint"].value = (0.0, 0.0, 0.0, 0.0)
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
        """Draw point batches (``lod.points_mode.PointsBatch``) of this frame."""
        ctx = self.ctx
        batches = [b for b in batches if b.rep in self._reps and b.n_instances]
        self.last_counts = {"points": 0, "triangles": 0}
        if not batches:
            return
        offs, rows = {}, 0
        for b in batches:
            offs[id(b)] = rows
            rows += b.n_instances
        inst = np.concatenate([np.asarray(b.instance_data, np.float32).reshape(-1, 16) for b in batches])
        if not np.isfinite(inst).all():
            raise FloatingPointError("points drawer: instance data hold NaN or Inf")
        self._buffer("instances", inst).bind_to_storage_buffer(1)
        w, h = self.r.size
        vp = np.asarray(view_proj, np.float64)
        # batches of one screen-door fade (lod.drawlist DrawBatch.fade; lod.keyframed_selection) draw together
        by_fade: dict = {}
        for b in batches:
            by_fade.setdefault(fade_uniform(getattr(b, "fade", None)), []).append(b)
        # 1. triangles selected by the traversal
        tprog = self._program("points_tri")
        self._uniforms(tprog, vp)
        for fade, key, g in [(f, k, g) for f in by_fade for k, g in self._reps.items()]:
            jobs = job_table(by_fade[fade], key, g.tbase, "tri_jobs", offs)
            if not jobs.shape[0]:
                continue
            if "u_fade" in tprog:
                tprog["u_fade"].value = fade
            total = int(jobs[-1, 1]) + int(jobs[-1, 3])
            self._buffer("tri_jobs", jobs).bind_to_storage_buffer(2)
            g.verts.bind_to_storage_buffer(5)
            g.corners.bind_to_storage_buffer(6)
            tprog["u_njobs"].value = int(jobs.shape[0])
            self._empty_for(tprog).render(moderngl.TRIANGLES, vertices=3 * total)
            self.last_counts["triangles"] += total
        # 2. points
        per_rep, fades = [], []
        for fade, key, g in [(f, k, g) for f in by_fade for k, g in self._reps.items()]:
            jobs = job_table(by_fade[fade], key, g.pbase, "point_jobs", offs)
            if jobs.shape[0]:
                per_rep.append((g, jobs, int(jobs[-1, 1]) + int(jobs[-1, 3])))
                fades.append(fade)
        if not per_rep:
            return
        path = self.path or per_rep[0][0].path
        if path not in PATHS:
            raise ValueError(f"points drawer: path must be one of {PATHS}, got {path!r}")
        if path == "gl_points":
            prog = self._program("points_gl")
            self._uniforms(prog, vp)
            ctx.enable(ctx.PROGRAM_POINT_SIZE)
            for (g, jobs, total), fade in zip(per_rep, fades):
                self._buffer("point_items", expand_jobs(jobs)).bind_to_storage_buffer(7)
                g.points.bind_to_storage_buffer(0)
                if "u_fade" in prog:
                    prog["u_fade"].value = fade
                prog["u_splat"].value = float(drawlist.options.get("splat_size", g.splat))
                self._empty_for(prog).render(moderngl.POINTS, vertices=total)
                self.last_counts["points"] += total
            ctx.disable(ctx.PROGRAM_POINT_SIZE)
            return
        clear = self._compute("points_clear")
        self._depth.bind_to_storage_buffer(3)
        self._color.bind_to_storage_buffer(4)
        clear["u_pixels"].value = self._pixels
        ctx.memory_barrier()  # the last frame's resolve has read the keys
        self._dispatch(clear, self._pixels, CLEAR_GROUP)
        ctx.memory_barrier()
        # one splat size per frame (the resolve gathers s x s anchors); all
        # reps of a scene share the [lod] splat_size
        splat = int(drawlist.options.get("splat_size", per_rep[0][0].splat))
        for defines in ((), ("COLOR_PASS",)):
            cs = self._compute("points_splat", defines + (f"LOCAL_SIZE {SPLAT_GROUP}", f"MARGIN {MARGIN}",
                                                          f"JOBS_PER_GROUP {SPLAT_JOBS_PER_GROUP}"))
            self._uniforms(cs, vp, u_size=(w, h))
            for (g, jobs, total), fade in zip(per_rep, fades):
                self._buffer("point_jobs", jobs).bind_to_storage_buffer(2)
                g.points.bind_to_storage_buffer(0)
                if "u_fade" in cs:
                    cs["u_fade"].value = fade
                cs["u_njobs"].value = int(jobs.shape[0])
                cs["u_splat"].value = splat
                self._dispatch(cs, int(jobs.shape[0]), SPLAT_JOBS_PER_GROUP)
                ctx.memory_barrier()
        self.last_counts["points"] = sum(t for _, _, t in per_rep)
        rprog = self._program("points_resolve")
        rprog["u_size"].value = (w, h)
        rprog["u_splat"].value = splat
        self.r.fbo.use()
        self._empty.render(moderngl.TRIANGLES, vertices=3)

    def _empty_for(self, prog):
        k = ("vao", id(prog))
        if k not in self._progs:
            self._progs[k] = self._track(self.ctx.vertex_array(prog, []), "points.vao")
        return self._progs[k]
