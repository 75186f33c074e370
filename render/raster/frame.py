"""The compute rasteriser's GPU side (``Raster``): uploaded meshes, the per-frame passes, windows.

A frame's compute work is a list of instances (camera-relative model rows, a representation part or a
triangle range, colour words). Its passes (render/raster/__init__.py gives the design):

1. poses: skinned instances' posed vertices from the pose cache (``render/poses/cache.py``, the one place a
   frame's poses are evaluated: each distinct pose skinned once), read in place when the window's skinned
   instances all read one window of the cache, else gathered into the posed table, one copy per pose slot and
   vertex range (``raster_gather.glsl``);
2. vertex pass (``raster_vertex.glsl``): every used vertex of every instance to fixed-point window
   coordinates, depth and clip outcodes;
3. depth pass (``raster_tri.glsl``): a thread per triangle: cull, set aside for the hardware path (too large,
   or crossing the near plane), or rasterise with ``atomicMin`` of the depth key; triangles that lowered a
   key are listed as candidates;
4. id pass: the candidates again, ``atomicMin`` of their ids where their depth won;
5. shading pass (``raster_shade.frag``): one fragment per pixel of the covered screen rectangle, writing
   colour and ``gl_FragDepth`` (the depth test composes it with the hardware path's pixels);
6. the set-aside triangles drawn by the hardware (``raster_spill.vert`` + ``lit.frag``).

Windows: a frame whose tables would pass a texture's size or a storage buffer's binding limit (llvmpipe:
GL_MAX_SHADER_STORAGE_BLOCK_SIZE = 128 MB; the candidate and spill lists hold 4 bytes per triangle) is cut
into windows of whole instances, each run through all six passes; the depth test composes the windows, so the
image is the one an unwindowed frame gives (tested with a small injected limit).
"""
from __future__ import annotations

import numpy as np

from render.context import release_all, track
from render.raster import tables as tb
from render.raster.tables import CHUNK, LOG_CHUNK, VERTS_PER_THREAD
from lod.raster_route import ASIDE_FACTOR, DEFAULT_THRESHOLD, MAX_THRESHOLD, triangle_extent  # noqa: F401
from render.shaders import load_source, with_defines

#: texture units of the tables (0..7: the renderer's joints, palette, morph and target tables, shadow map;
#: 8: the pose cache's posed vertices, render/poses/cache.py POSED_UNIT)
UNITS = {"u_rs_tris": 20, "u_rs_mesh": 21, "u_rs_posed": 22, "u_rs_inst": 23, "u_rs_jobs": 24, "u_screen": 25}
#: side (pixels) of the tiles the id pass marks: the shading pass draws the marked tiles only (a crowd
#: covers a small share of the screen: 100 copies of a 60 K-triangle character fill 3 % of 1280 x 720, where
#: a full-screen pass cost 170-240 ms on a loaded machine)
TILE = 8
#: the shading pass draws one full-screen triangle instead of the tiles' rectangles above this share of the screen
FULL_SHADE_SHARE = 0.6
#: lists of set-aside triangles (raster_tri.glsl): characters with back faces culled, other characters, the world
SPILL_LISTS = 3
#: most windows added to read the pose cache's windows in place (Raster._pose_cuts)
MAX_POSE_CUTS = 16
#: work groups per dispatch dimension (GL guarantees 65535)
MAX_GROUPS = 65535
#: bytes a storage-buffer binding may address when the context does not say
DEFAULT_SSBO_LIMIT = 1 << 27


class _Mesh:
    """An uploaded mesh: where its records and triangles start in the shared tables."""

    def __init__(self, rep, kind, verts, tris, cull):
        self.rep, self.kind, self.verts, self.tris, self.cull = rep, kind, verts, tris, cull
        # rows in the shared tables, placed when the mesh is first drawn (Raster._place): first record and
        # triangle row, and how many of each the slot holds (a replaced rep of the same key reuses its slot)
        self.record = self.tri = None
        self.record_cap = self.tri_cap = 0
        self._stale = False  # holds its predecessor's slot, rows not written yet
        pos = rep.positions0 if kind == tb.KEYFRAMED else rep.positions
        self.extent, self.radius, self.centre = triangle_extent(pos, rep.indices)
        self._ranges: dict = {}  # (first triangle, count) -> (first vertex, vertices) used

    def extent_of(self, first: int, count: int) -> float:
        """The routing summary (lod.raster_route.triangle_extent) of triangles first .. first + count - 1: a LOD
        chain's coarse levels have larger triangles than its level 0 (cached)."""
        if first == 0 and count >= self.tris:
            return self.extent
        k = ("extent", first, count)
        e = self._ranges.get(k)
        if e is None:
            pos = self.rep.positions0 if self.kind == tb.KEYFRAMED else self.rep.positions
            e = self._ranges[k] = triangle_extent(pos, np.asarray(self.rep.indices).reshape(-1, 3)[first:first + count])[0]
        return e

    def vertex_range(self, first: int, count: int) -> tuple[int, int]:
        """(first vertex, vertices) spanned by triangles first .. first + count - 1 (cached)."""
        k = (first, count)
        r = self._ranges.get(k)
        if r is None:
            t = np.asarray(self.rep.indices, np.int64).reshape(-1, 3)[first:first + count]
            r = (int(t.min()), int(t.max()) - int(t.min()) + 1) if t.size else (0, 0)
            if len(self._ranges) > 4096:
                self._ranges.clear()
            self._ranges[k] = r
        return r


class Raster:
    """The compute rasteriser of one renderer (see the module docstring).

    Attributes
    ----------
    ssbo_limit : bytes one storage-buffer binding may address (None: the context's limit); tests inject a
        small one to force windows
    texel_limit : most texels of a per-frame table (None: the texture size limit)
    last_counts : counts of the last frame: ``triangles`` handed to the compute path, ``rasterised`` (not
        culled, not set aside), ``spilled`` (drawn by the hardware), ``candidates``, ``windows``, ``instances``
    """

    def __init__(self, renderer):
        self.r = renderer
        self.ctx = renderer.ctx
        self._objects: list = []
        self._meshes: dict[str, _Mesh] = {}
        self._progs: dict = {}
        self._bufs: dict = {}
        self._records = np.zeros((0, 4 * tb.RECORD_TEXELS), np.uint32)
        self._tris = np.zeros((0, 4), np.uint32)
        self._dead = 0  # table rows (records + triangles) of replaced meshes not reused yet
        self._dirty = True
        mk = lambda dt, label: tb.Table(self.ctx, dt, f"raster.{label}", self._track, self._forget)  # noqa: E731
        self.mesh_table, self.tri_table = mk("u4", "mesh"), mk("u4", "tris")
        self.inst_table, self.job_table = mk("u4", "instances"), mk("u4", "jobs")
        self.screen_table, self.posed_table = mk("i4", "screen"), mk("f4", "posed")
        w, h = renderer.size
        self._pixels = w * h
        self._depth = self._track(self.ctx.buffer(reserve=4 * self._pixels), "raster.depth")
        self._ids = self._track(self.ctx.buffer(reserve=4 * self._pixels), "raster.ids")
        self._ones = None  # bytes of 0xff the size of the per-pixel buffers (their clear value)
        self._counts = self._track(self.ctx.buffer(reserve=16), "raster.counts")
        self._tiles_xy = (-(-w // TILE), -(-h // TILE))
        self._tiles = self._track(self.ctx.buffer(reserve=4 * self._tiles_xy[0] * self._tiles_xy[1]), "raster.tiles")
        self.ssbo_limit = None
        self.texel_limit = None
        #: bytes the per-pixel buffers may bind (None: the context's storage-buffer limit); tests inject one
        self.pixel_limit = None
        #: copies of a mesh in one pose-cache slot gathered once into the posed table (False: one gathered copy
        #: of the slot's posed vertices per instance: the benchmarks' "without sharing"; the poses are evaluated
        #: once by the pose cache either way)
        self.share_poses = True
        #: every eligible instance to the compute path, whatever its estimated triangle size (its large and
        #: near-plane triangles still go to the hardware): tests and benchmarks
        self.route_all = False
        self.last_counts: dict = {}
        #: seconds of each pass of the last frame (only while ``profile`` is set: a ctx.finish after each pass)
        self.profile = False
        self.last_passes: dict = {}

    def _mark(self, name: str) -> None:
        """Profiling (``profile``): wall and CPU seconds (every thread: llvmpipe's) since the last mark."""
        if self.profile:
            import time

            self.ctx.finish()
            t, c = time.perf_counter(), time.process_time()
            w0, c0 = self.last_passes.get(name, (0.0, 0.0))
            self.last_passes[name] = (w0 + t - self._t[0], c0 + c - self._t[1])
            self._t = (t, c)

    # ------------------------------------------------------------------ resources
    def _track(self, obj, label):
        return track(self._objects, obj, label)

    def _forget(self, obj):
        if obj in self._objects:
            self._objects.remove(obj)
        obj.release()

    def _compute(self, name: str, defines=()):
        k = (name, tuple(defines))
        if k not in self._progs:
            src = with_defines(load_source(f"{name}.glsl"), ())
            head, rest = src.split("\n", 1)
            src = head + "\n" + "".join(f"#define {d}\n" for d in defines) + rest
            self._progs[k] = self._track(self.ctx.compute_shader(src), f"raster.{name}")
        return self._progs[k]

    def _buffer(self, name: str, data: np.ndarray | None = None, nbytes: int = 0):
        """Per-frame storage buffer ``name`` (grown by doubling), holding ``data`` when given."""
        raw = b"" if data is None else np.ascontiguousarray(data).tobytes()
        need = max(len(raw), int(nbytes), 16)
        b = self._bufs.get(name)
        if b is None or b.size < need:
            if b is not None:
                self._forget(b)
            size = 1 << int(np.ceil(np.log2(need)))
            b = self._bufs[name] = self._track(self.ctx.buffer(reserve=size, dynamic=True), f"raster.{name}")
        if raw:
            b.write(raw)
        return b

    def release(self) -> None:
        release_all(self._objects)
        self._progs.clear()
        self._bufs.clear()
        self._meshes.clear()

    # ------------------------------------------------------------------ meshes
    def mesh(self, rep, cull: bool, g=None) -> _Mesh | None:
        """The mesh of representation ``rep`` (back faces culled or not; a skinned one needs the renderer's
        ``_GpuRep`` ``g`` for its joint table): its routing summary at once, its table rows when first drawn
        (:meth:`_place`); None for a kind the compute path does not draw. Props and obstacle solids (kind
        "world", lod.props) are static meshes. A skinned mesh's posed vertices come from the pose cache each
        frame (:func:`render.raster.hook.split` routes its copies here only when the cache has them)."""
        m = self._meshes.get(rep.key)
        if m is not None and m.rep is rep:
            return m
        kind = {"static": tb.STATIC, "keyframed": tb.KEYFRAMED, "skinned": tb.POSED,
                "world": tb.STATIC}.get(getattr(rep, "kind", ""))
        if kind is None or (kind == tb.POSED and g is None):
            return None
        verts = int(np.asarray(rep.positions0 if kind == tb.KEYFRAMED else rep.positions).shape[0])
        new = _Mesh(rep, kind, verts, int(np.asarray(rep.indices).size // 3), bool(cull))
        if m is not None and m.record is not None:  # a rep replaced under its key (a view-dependent terrain)
            new.record, new.record_cap, new.tri, new.tri_cap = m.record, m.record_cap, m.tri, m.tri_cap
            new._stale = True
        self._meshes[rep.key] = new
        return new

    @staticmethod
    def _rows(m: _Mesh) -> tuple:
        """(vertex records, triangle rows) of mesh ``m`` in the tables' layout."""
        rep = m.rep
        if m.kind == tb.KEYFRAMED:
            recs = np.concatenate([tb.vertex_records(rep.positions0, rep.normals0, rep.colors0),
                                   tb.vertex_records(rep.positions1, rep.normals1, rep.colors1)])
        else:
            recs = tb.vertex_records(rep.positions, rep.normals, rep.colors)
        return recs, tb.triangle_rows(rep.indices)

    def _place(self, m: _Mesh) -> None:
        """Give mesh ``m`` its rows in the shared tables: a rep replaced under its key (a view-dependent
        terrain, every frame) overwrites its predecessor's slot when it fits, else takes a new slot with a
        quarter of headroom and leaves the old one dead; the tables are compacted once dead rows outnumber
        live ones, so they never grow with the number of replacements."""
        if m.record is not None and not m._stale:
            return
        recs, tris = self._rows(m)
        if m.record is not None and recs.shape[0] <= m.record_cap and tris.shape[0] <= m.tri_cap:
            self._records[m.record:m.record + recs.shape[0]] = recs
            self._tris[m.tri:m.tri + tris.shape[0]] = tris
        else:
            if m.record is not None:
                self._dead += m.record_cap + m.tri_cap
            grow = 1.25 if m.record is not None else 1.0
            m.record_cap, m.tri_cap = int(recs.shape[0] * grow), int(tris.shape[0] * grow)
            m.record, m.tri = self._records.shape[0], self._tris.shape[0]
            pad = lambda a, n: np.concatenate([a, np.zeros((n - a.shape[0], a.shape[1]), a.dtype)])  # noqa: E731
            self._records = np.concatenate([self._records, pad(recs, m.record_cap)])
            self._tris = np.concatenate([self._tris, pad(tris, m.tri_cap)])
        m._stale = False
        self._dirty = True
        if self._dead > self._records.shape[0] + self._tris.shape[0] - self._dead:
            self._compact()

    def _compact(self) -> None:
        """The tables rebuilt from the placed meshes only (replaced meshes' slots dropped)."""
        live = [m for m in self._meshes.values() if m.record is not None]
        recs, tris = [], []
        r = t = 0
        for m in live:
            a = self._records[m.record:m.record + m.record_cap]
            b = self._tris[m.tri:m.tri + m.tri_cap]
            m.record, m.tri = r, t
            recs.append(a)
            tris.append(b)
            r, t = r + a.shape[0], t + b.shape[0]
        self._records = np.concatenate(recs) if recs else self._records[:0]
        self._tris = np.concatenate(tris) if tris else self._tris[:0]
        self._dead = 0
        self._dirty = True

    def _frame_triangles(self, work: list) -> None:
        """Place the explicit triangles of this frame's work (cluster cuts) after the meshes' in the triangle
        table (from the row after the last mesh row)."""
        extra = [w for w in work if w.tris is not None]
        if not extra:
            return
        base = -(-self._tris.shape[0] // tb.WIDTH) * tb.WIDTH
        rows = np.concatenate([w.tris for w in extra])
        at = base
        for w in extra:
            w.tri_abs = at
            at += w.tris.shape[0]
        if self.tri_table.rows < tb.rows_for(at):  # grown: the mesh rows are written again
            self._dirty = True
            self.tri_table.ensure(at)
            self._upload_meshes()
        self.tri_table.write(tb.triangle_rows(rows), base)

    def _upload_meshes(self) -> None:
        if not self._dirty:
            return
        n = self._records.shape[0] * tb.RECORD_TEXELS
        self.mesh_table.ensure(n)
        full = np.zeros((self.mesh_table.rows * tb.WIDTH, 4), np.uint32)
        full[:n] = self._records.reshape(-1, 4)
        self.mesh_table.write(full)
        self.tri_table.ensure(max(self._tris.shape[0], self.tri_table.rows * tb.WIDTH))
        full = np.zeros((self.tri_table.rows * tb.WIDTH, 4), np.uint32)
        full[:self._tris.shape[0]] = self._tris
        self.tri_table.write(full)
        self._dirty = False

    # ------------------------------------------------------------------ frame
    def limits(self) -> tuple[int, int]:
        """(triangles per window, texels per table) this context allows."""
        ssbo = int(self.ssbo_limit or self.ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", DEFAULT_SSBO_LIMIT))
        texels = int(self.texel_limit or tb.WIDTH * int(self.ctx.info["GL_MAX_TEXTURE_SIZE"]))
        # the spill buffer holds SPILL_LISTS lists of 4 bytes per triangle (the largest per-triangle buffer)
        return max(1, min(ssbo // (4 * SPILL_LISTS), (1 << 32) - CHUNK)), texels

    def fits(self) -> bool:
        """Whether the per-pixel buffers (depth keys, ids: 4 bytes a pixel) bind within the storage-buffer
        limit; above it (renders beyond ~5,792 x 5,792 on llvmpipe) the compute path stays off."""
        ssbo = int(self.pixel_limit or self.ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", DEFAULT_SSBO_LIMIT))
        return 4 * self._pixels <= ssbo

    def draw(self, work: list, view_proj: np.ndarray) -> dict:
        """Rasterise ``work`` (a list of :class:`Work`) into the renderer's framebuffer (bound, depth test on);
        returns the frame's counts (also ``last_counts``)."""
        counts = dict.fromkeys(("instances", "triangles", "rasterised", "spilled", "candidates", "windows"), 0)
        self.last_counts = counts
        work = [w for w in work if w.rows.shape[0] and w.count]
        if not work:
            return counts
        if self.profile:
            import time

            self.ctx.finish()
            self.last_passes, self._t = {}, (time.perf_counter(), time.process_time())
        for w in work:
            self._place(w.mesh)
        self._upload_meshes()
        self._frame_triangles(work)
        # one row per instance: batch index, rows, tints
        n = np.array([w.rows.shape[0] for w in work], np.int64)
        wi = np.repeat(np.arange(len(work)), n)
        rows = np.concatenate([w.rows for w in work]).astype(np.float32)
        tints = np.concatenate([w.tints for w in work]).astype(np.uint32)
        # each copy's pose slot (lod.poses; a cluster cut's from its item): its row in the pose cache
        slots = np.concatenate([w.slots for w in work]).astype(np.int64)
        if not np.isfinite(rows).all():
            raise FloatingPointError("compute raster: instance data hold NaN or Inf")
        tcount = np.array([w.count for w in work], np.int64)[wi]
        vcount = np.array([w.vcount for w in work], np.int64)[wi]
        posed = np.array([w.mesh.kind == tb.POSED for w in work])[wi]
        max_tris, max_texels = self.limits()
        # windows of whole instances: triangles, screen texels, posed texels, instance records
        cuts = tb.instance_cuts(tcount, vcount, np.where(posed, vcount * tb.POSED_TEXELS, 0), max_tris, max_texels)
        cuts = self._pose_cuts(work, wi, slots, posed, cuts)
        counts["instances"] = int(rows.shape[0])
        counts["triangles"] = int(tcount.sum())
        vp = np.asarray(view_proj, np.float64)
        for a, b in zip(cuts[:-1], cuts[1:]):
            self._window(work, wi[a:b], rows[a:b], tints[a:b], slots[a:b], tcount[a:b], vcount[a:b], vp, counts)
            counts["windows"] += 1
        return counts

    def hit_counts(self, work: list, view_proj: np.ndarray) -> np.ndarray:
        """Diagnostic (tests): (h, w) uint32, how many of ``work``'s rasterised triangles cover each pixel centre
        (the depth pass's coverage with ``atomicAdd`` in place of the depth test; one window)."""
        self._count_pass = True
        try:
            self.draw(work, view_proj)
        finally:
            self._count_pass = False
        w, h = self.r.size
        return np.frombuffer(self._ids.read(), np.uint32)[:w * h].reshape(h, w).copy()

    _count_pass = False

    def _pose_cuts(self, work, wi, slots, posed, cuts: list) -> list:
        """``cuts`` with windows also cut where the skinned instances (``posed``) move to another mesh or window of
        the pose cache (a character posed beyond one cache window: 100 copies of a 60 K-vertex mesh in their own
        poses), so that each window reads its posed vertices in place (:meth:`_in_place`); at most
        :data:`MAX_POSE_CUTS` more windows, else the windows gather."""
        sel = np.flatnonzero(posed)
        if sel.shape[0] < 2:
            return cuts
        src = np.full(wi.shape[0], -1, np.int64)
        meshes: dict = {}
        for b in np.unique(wi[sel]).tolist():
            w = work[b]
            mine = sel[wi[sel] == b]
            pv = self.r.poses.posed(w.pose_key, w.mesh.rep.key, slots=slots[mine])
            if pv is not None:
                m = meshes.setdefault((w.pose_key, w.mesh.rep.key), len(meshes))
                src[mine] = (m << 20) + pv.window_of(slots[mine])
        s = src[sel]
        new = sel[1:][s[1:] != s[:-1]].tolist()
        if not new or len(new) > MAX_POSE_CUTS:
            return cuts
        return sorted(set(cuts) | set(new))

    def _in_place(self, work, wi, posed, slots, vfirst):
        """``(texture, first posed vertex per instance)`` when every skinned instance of the window (``posed``
        (k,) bool) draws one mesh in one character's poses held in one window of the pose cache: the vertex pass
        then reads that window in place (its layout is the posed table's, ``shaders/poses/posed.glsl``), with no
        gather; else None."""
        sel = np.flatnonzero(posed)
        keys = {(work[b].pose_key, work[b].mesh.rep.key) for b in np.unique(wi[sel]).tolist()}
        if len(keys) != 1:
            return None
        pose_key, mesh_key = keys.pop()
        s = np.asarray(slots[sel], np.float64).round().astype(np.int64)
        pv = self.r.poses.posed(pose_key, mesh_key, slots=s)
        if pv is None:  # routing keeps such copies on the hardware path (render.raster.hook)
            raise RuntimeError(f"compute raster: no posed vertices of {mesh_key!r} in the pose cache")
        win = np.unique(pv.window_of(s))
        if win.shape[0] != 1:
            return None
        w = pv.windows[int(win[0])]
        base = np.zeros(posed.shape[0], np.int64)
        base[sel] = (s - w.first) * pv.vertices + np.asarray(vfirst, np.int64)[sel]
        return w.texture, base

    def _gather(self, work, wi, slots, vcount, vfirst, reps) -> None:
        """Copy the window's pose slots (``reps``: the instance standing for each, its record naming where the
        copy goes) from the pose cache's posed vertices into the posed table: one dispatch per mesh and posed
        window of the cache."""
        from render.poses.cache import POSED_UNIT

        self.posed_table.texture.bind_to_image(1, read=False, write=True)
        cs = self._compute("raster_gather", (f"RS_VERTS_PER_THREAD {VERTS_PER_THREAD}",))
        self._samplers(cs)
        for b in np.unique(wi[reps]):
            w = work[b]
            sel = reps[wi[reps] == b]
            pv = self.r.poses.posed(w.pose_key, w.mesh.rep.key, slots=slots[sel])
            if pv is None:  # routing keeps such copies on the hardware path (render.raster.hook)
                raise RuntimeError(f"compute raster: no posed vertices of {w.mesh.rep.key!r} in the pose cache")
            win = pv.window_of(slots[sel])
            for wn in np.unique(win):
                part = sel[win == wn]
                jobs = tb.vertex_jobs(vcount[part], vfirst[part])
                jobs[:, 3] = slots[part][jobs[:, 0]].astype(np.uint32)
                jobs[:, 0] = part[jobs[:, 0]]
                pv.bind(int(wn), cs, POSED_UNIT)
                cs["u_njobs"].value = int(jobs.shape[0])
                self._buffer("pose_jobs", jobs).bind_to_storage_buffer(5)
                self._dispatch(cs, int(jobs.shape[0]))
                self.ctx.memory_barrier()

    def _window(self, work, wi, rows, tints, slots, tcount, vcount, vp, counts) -> None:
        ctx = self.ctx
        k = rows.shape[0]
        meshes = [w.mesh for w in work]
        kind = np.array([m.kind for m in meshes], np.uint32)[wi]
        flags = np.array([(tb.CULL if m.cull else 0) | (tb.WORLD if w.world else 0)
                          for m, w in zip(meshes, work)], np.uint32)[wi]
        vfirst = np.array([w.vfirst for w in work], np.int64)[wi]
        tfirst = np.array([w.first for w in work], np.int64)[wi]
        mesh_rec = np.array([m.record for m in meshes], np.int64)[wi]
        mesh_tri = np.array([m.tri if w.tri_abs is None else w.tri_abs for m, w in zip(meshes, work)], np.int64)[wi]
        verts = np.array([m.verts for m in meshes], np.int64)[wi]
        screen = np.zeros(k, np.int64)
        np.cumsum(vcount[:-1], out=screen[1:])
        # the posed vertices read in place from the pose cache's window when all come from one, else one posed copy
        # per distinct (mesh, pose slot, vertex range) gathered into the posed table: copies in one pose once
        in_place = self._in_place(work, wi, kind == tb.POSED, slots, vfirst) if (kind == tb.POSED).any() else None
        if in_place is None:
            posed, posed_n, reps = tb.pose_slots(kind == tb.POSED, mesh_rec, slots, vfirst, vcount, self.share_poses)
        else:
            posed = in_place[1]
        wrap = lambda x: (np.asarray(x, np.int64) % (1 << 32)).astype(np.uint32)  # noqa: E731 (GLSL uint wraps)
        u = rows[:, 12]
        recs = tb.instance_records(rows, np.where(kind == tb.KEYFRAMED, u, 0.0), kind, flags, mesh_rec,
                                   wrap(posed - vfirst), wrap(screen - vfirst), tints, verts)
        # triangle jobs: chunks of CHUNK triangles of each instance
        nj = -(-tcount // CHUNK)
        ji = np.repeat(np.arange(k), nj)
        jstart = np.zeros(k, np.int64)
        np.cumsum(nj[:-1], out=jstart[1:])
        c = np.arange(ji.shape[0]) - jstart[ji]
        jobs = np.zeros((ji.shape[0], 4), np.uint32)
        jobs[:, 0] = mesh_tri[ji] + tfirst[ji] + c * CHUNK
        jobs[:, 1] = np.minimum(CHUNK, tcount[ji] - c * CHUNK)
        jobs[:, 2] = ji
        vjobs = tb.vertex_jobs(vcount, vfirst)
        # tables
        self.inst_table.ensure(k * tb.INST_TEXELS)
        self.inst_table.write(recs)
        self.job_table.ensure(jobs.shape[0])
        self.job_table.write(jobs)
        self.screen_table.ensure(int(vcount.sum()))
        for name, t in (("u_rs_tris", self.tri_table), ("u_rs_mesh", self.mesh_table),
                        ("u_rs_inst", self.inst_table), ("u_rs_jobs", self.job_table), ("u_screen", self.screen_table)):
            t.texture.use(UNITS[name])
        if in_place is not None:
            in_place[0].use(UNITS["u_rs_posed"])
        else:
            self.posed_table.ensure(max(1, int(posed_n.sum()) * tb.POSED_TEXELS))
            self.posed_table.texture.use(UNITS["u_rs_posed"])
        # 1. poses (skinned instances), gathered from the pose cache (unless read in place)
        if in_place is None and (kind == tb.POSED).any():
            self._mark("tables")
            self._gather(work, wi, slots, vcount, vfirst, reps)
            self._mark("poses")
        # 2. vertex pass
        cs = self._compute("raster_vertex", (f"RS_VERTS_PER_THREAD {VERTS_PER_THREAD}",))
        self._samplers(cs)
        cs["u_view_proj"].write(np.ascontiguousarray(vp.T, np.float32).tobytes())
        cs["u_size"].value = tuple(self.r.size)
        cs["u_njobs"].value = int(vjobs.shape[0])
        self.screen_table.texture.bind_to_image(0, read=False, write=True)
        self._buffer("vertex_jobs", vjobs).bind_to_storage_buffer(5)
        self._dispatch(cs, int(vjobs.shape[0]))
        ctx.memory_barrier()
        self._mark("vertex")
        # 3. depth pass
        ntri = int(tcount.sum())
        # all-ones written from a kept buffer: moderngl's clear with a chunk fills the mapped buffer 4 bytes at a
        # time (11 ms for a 1280 x 720 buffer on llvmpipe, twice a frame), a write of the same bytes takes 0.5 ms
        if self._ones is None or len(self._ones) != self._depth.size:
            self._ones = b"\xff" * self._depth.size
        self._depth.write(self._ones)
        if self._count_pass:
            self._ids.clear()
        else:
            self._ids.write(self._ones)
        self._counts.clear()
        self._depth.bind_to_storage_buffer(0)
        self._ids.bind_to_storage_buffer(1)
        self._counts.bind_to_storage_buffer(2)
        self._buffer("candidates", nbytes=4 * ntri).bind_to_storage_buffer(3)
        spill = self._buffer("spill", nbytes=4 * SPILL_LISTS * ntri)
        spill.bind_to_storage_buffer(4)
        w, h = self.r.size
        cs = self._compute("raster_tri", (f"RS_LOG_CHUNK {LOG_CHUNK}",) + (("COUNT_PASS",) if self._count_pass else ()))
        self._samplers(cs)
        cs["u_size"].value = (w, h)
        cs["u_count"].value = int(jobs.shape[0])
        cs["u_max_extent"].value = int(round(min(MAX_THRESHOLD, ASIDE_FACTOR * self.threshold) * 256.0))
        cs["u_spill_cap"].value = ntri
        ctx.memory_barrier()
        self._dispatch(cs, int(jobs.shape[0]))
        ctx.memory_barrier()
        n_cand, *n_spill = (int(x) for x in np.frombuffer(self._counts.read(size=16), np.uint32))
        self._mark("depth")
        counts["candidates"] += n_cand
        counts["spilled"] += sum(n_spill)
        counts["rasterised"] += ntri - sum(n_spill)
        if self._count_pass:
            return
        # 4. id pass
        if n_cand:
            cs = self._compute("raster_tri", (f"RS_LOG_CHUNK {LOG_CHUNK}", "ID_PASS", f"RS_TILE {TILE}"))
            self._samplers(cs)
            cs["u_size"].value = (w, h)
            cs["u_count"].value = n_cand
            cs["u_tiles_x"].value = self._tiles_xy[0]
            self._tiles.clear()
            self._tiles.bind_to_storage_buffer(6)
            self._dispatch(cs, -(-n_cand // 8))
            ctx.memory_barrier()
            self._mark("id")
            # 5. shading
            self._shade(vp)
            self._mark("shade")
        # 6. the triangles set aside, drawn by the hardware
        if sum(n_spill):
            self._spill(vp, ntri, n_spill)
            self._mark("spill")

    def _samplers(self, prog) -> None:
        for name, unit in UNITS.items():
            if name in prog:
                prog[name].value = unit

    def _dispatch(self, cs, groups: int) -> None:
        if groups <= 0:
            return
        gx = min(groups, MAX_GROUPS)
        cs.run(gx, -(-groups // gx), 1)

    def _lit_program(self, name: str, vertex: str, fragment: str, extra=()):
        """A draw program of ``vertex`` and ``fragment`` files with the renderer's PIXEL_RAY choice."""
        defines = tuple(extra) + (("PIXEL_RAY",) if self.r.pixel_ray and not extra else ()) + self.r.shadow_defines()
        k = (name, defines)
        if k not in self._progs:
            prog = self.ctx.program(vertex_shader=with_defines(load_source(vertex), defines),
                                    fragment_shader=with_defines(load_source(fragment), defines))
            self._progs[k] = self._track(prog, f"raster.{name}")
        return self._progs[k]

    def _uniforms(self, prog, vp) -> None:
        from render.screen import write_pixel_ray

        self._samplers(prog)
        if "u_view_proj" in prog:
            prog["u_view_proj"].write(np.ascontiguousarray(vp.T, np.float32).tobytes())
        self.r.lighting.apply(prog)
        if "u_fade" in prog:
            prog["u_fade"].value = (0.0, 0.0)
        write_pixel_ray(prog, vp, self.r.size)
        if "u_pixel_ray" in prog and not self.r.pixel_ray:
            from render.screen import pixel_ray_matrix

            prog["u_pixel_ray"].write(np.ascontiguousarray(pixel_ray_matrix(vp, self.r.size).T,
                                                           np.float32).tobytes())

    def _shade(self, vp) -> None:
        prog = self._lit_program("shade", "points_resolve.vert", "raster_shade.frag")
        self._uniforms(prog, vp)
        prog["u_size"].value = tuple(self.r.size)
        self._depth.bind_to_storage_buffer(0)
        self._ids.bind_to_storage_buffer(1)
        from render.screen import rect_vertices, resolve_rects

        tx, ty = self._tiles_xy
        w, h = self.r.size
        flags = np.frombuffer(self._tiles.read(size=4 * tx * ty), np.uint32).reshape(ty, tx) != 0
        rects = resolve_rects(flags, (w, h), TILE, 0, 1)  # pixel p reads its own slot (no splat margin)
        if not rects.shape[0]:
            return
        if int(((rects[:, 2] - rects[:, 0]) * (rects[:, 3] - rects[:, 1])).sum()) > FULL_SHADE_SHARE * w * h:
            verts = np.array([[-1.0, -1.0], [3.0, -1.0], [-1.0, 3.0]], np.float32)
        else:
            verts = rect_vertices(rects, (w, h))
        vbo = self._buffer("shade_vertices", verts)
        key = ("vao", id(prog), id(vbo))
        if key not in self._progs:
            self._progs[key] = self._track(self.ctx.vertex_array(prog, [(vbo, "2f", "in_pos")]), "raster.shade_vao")
        self.r.fbo.use()
        self.ctx.disable(self.ctx.CULL_FACE)
        self._progs[key].render(self.ctx.TRIANGLES, vertices=int(verts.shape[0]))

    def _spill(self, vp, cap: int, n_spill: list) -> None:
        """Draw the set-aside triangles: the lists of culling characters, other characters, the world."""
        self._bufs["spill"].bind_to_storage_buffer(4)
        self.r.fbo.use()
        for lst, n in enumerate(n_spill):
            if not n:
                continue
            world = lst == 2
            prog = (self._lit_program("spill_world", "raster_spill.vert", "world_mesh.frag", ("RS_WORLD_SPILL",))
                    if world else self._lit_program("spill", "raster_spill.vert", "lit.frag"))
            self._uniforms(prog, vp)
            if "u_tint" in prog:
                prog["u_tint"].value = (0.0, 0.0, 0.0, 0.0)  # the debug colour rides in the vertex colour
            key = ("vao", id(prog))
            if key not in self._progs:
                self._progs[key] = self._track(self.ctx.vertex_array(prog, []), "raster.spill_vao")
            (self.ctx.enable if lst == 0 else self.ctx.disable)(self.ctx.CULL_FACE)
            prog["u_first"].value = lst * cap
            self._progs[key].render(self.ctx.TRIANGLES, vertices=3 * n)
        self.ctx.disable(self.ctx.CULL_FACE)

    #: pixels ([render] raster_threshold, lod/raster_route.py): a triangle whose window box is wider or taller
    #: than ASIDE_FACTOR times it goes to the hardware path
    threshold = DEFAULT_THRESHOLD


class Work:
    """Instances of one mesh part handed to the compute path: ``rows`` (k, 16) float32 instance data
    (lod.drawlist), ``tints`` (k, 2) uint32 colour words, triangles ``first .. first + count - 1`` of the mesh
    (or, given ``tris`` (count, 3): those triangles of the mesh's vertices, e.g. a cluster cut's, placed in the
    frame's part of the triangle table) using vertices ``vfirst .. vfirst + vcount - 1``; ``world``: shaded as
    props and obstacle solids. A skinned mesh's copies read the pose cache's posed vertices of the pose group
    of representation ``pose_key`` (default: the mesh's own) at their ``slots`` (default: instance float
    ``lod.poses.SLOT_FLOAT``)."""

    __slots__ = ("mesh", "rows", "tints", "first", "count", "vfirst", "vcount", "world", "tris", "tri_abs",
                 "pose_key", "slots")

    def __init__(self, mesh, rows, tints, first: int, count: int, world: bool = False, tris=None, pose_key=None,
                 slots=None):
        from lod.poses.table import SLOT_FLOAT

        self.mesh, self.rows, self.tints = mesh, np.asarray(rows, np.float32).reshape(-1, 16), tints
        self.pose_key = mesh.rep.key if pose_key is None else pose_key
        self.slots = np.rint(self.rows[:, SLOT_FLOAT] if slots is None else np.asarray(slots)).astype(np.int64)
        self.first, self.count, self.world = int(first), int(count), bool(world)
        self.tris = None if tris is None else np.asarray(tris, np.uint32).reshape(-1, 3)
        self.tri_abs = None  # first row of ``tris`` in the triangle table (Raster.draw)
        if self.tris is None:
            self.vfirst, self.vcount = mesh.vertex_range(self.first, self.count)
        else:
            self.first, self.count = 0, int(self.tris.shape[0])
            lo = int(self.tris.min()) if self.tris.size else 0
            self.vfirst, self.vcount = lo, (int(self.tris.max()) - lo + 1 if self.tris.size else 0)
