"""The renderer: GPU resources for representations and instanced draws of DrawLists.

Draw paths (one program each, shaders in ``render/shaders/``):

- skinned: linear blend skinning (LBS) in the vertex shader. The skinning
  matrices of all baked frames of all clips live in ONE RGBA32F texture (one
  row per frame, three texels per joint, read with ``texelFetch``). Default
  "palette" path: once per frame a transform-feedback pre-pass
  (``palette.vert``, one point per matrix row and instance) blends every drawn
  instance's matrices between the two baked frames around its fractional
  frame coordinate and the result is copied (GPU-side) into a palette
  texture (``render/poses/palette.py``; a frame whose palette would not fit the
  texture is drawn in chunks, each pre-pass followed by its draws); the
  vertex shader then reads 3 texels per influence. The "direct"
  path (``skinned_direct.vert``) blends both frames per vertex (6 texels per
  influence); it is kept for comparison and as a fallback. Blending matrices
  is exact for LBS (see ``lod.full.reps.SkinnedRep``).
- keyframed: per segment vertex start/end attributes mixed by the instance's u
  (Wand & Straßer 2002, §3).
- static: the same instancing path without animation.
- morph targets (``SkinnedRep.targets``): the skinned programs compiled with ``MORPH_TARGETS``
  morph every vertex before skinning (``render/poses/targets.py``); reps without them use the plain ones.

Instance data: every frame, the instance data of all batches are written into one per-frame buffer (orphaned
first, so a draw still reading last frame's data never stalls the write); each batch then re-binds the four
instanced attributes (divisor 1) of its representation's VAO at the batch's byte offset and issues one
instanced draw (moderngl exposes no base-instance draw; an offset re-bind is four cheap GL calls). Measured on
llvmpipe with 64 batches of 500 one-triangle instances, a frame took 14 ms this way against 19.5 ms when
orphaning and writing the buffer once per batch, so the per-frame buffer with offsets is the path kept (it is
also the layout a real GPU prefers).

Colour words: beside the instance data, a per-frame stream of two uint32 per
instance (the agent's colour variation, the batch's debug colour;
``render/tint.py``) bound as ``i_tint``; every vertex shader applies them with
``tint_color`` (``shaders/core/tint.glsl``), as the other drawers do.

Bounded driver memory: Mesa llvmpipe (22.3, ``lp_setup.c``) bins triangles
into "scenes" of at most 36 MB that its rasterizer threads consume; when the
binner (this thread) is ahead of them it allocates another scene, up to 64,
and a rasterized scene keeps its binned data until it is reused. A frame of
58 M triangles (``scenes/horses.toml``, lod mode none) let the binner run
ahead whenever the machine was loaded, so resident memory ratcheted from
0.6 GB to 2.35 GB over ~11 minutes (64 x 36 MB; heap memory in use, not
freed-but-kept: ``malloc_trim`` did not return it). Large instanced draws are
therefore split into submissions of at most ``max_triangles_in_flight``
triangles (whole instances; default :data:`MAX_TRIANGLES_IN_FLIGHT`) with a
``ctx.finish`` between them, which keeps the driver at a few scenes; the wait
costs no measurable time on llvmpipe (scripts/soak.md).

Back faces are culled for single-sided reps (``double_sided`` False: glTF's default, the procedural
characters; 1.36-1.52x less CPU on heavy characters, scripts/bench_full_detail.md), else both sides are lit.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import numpy as np

from lod.drawlist import INSTANCE_FLOATS, fade_uniform
from render.context import create_context, created, release_all, track
from render.poses.palette import (PALETTE_MAX_TEXELS, PALETTE_WIDTH, Palette, PaletteCursor,  # noqa: F401 (re-exported)
                                  joint_texture, plan_chunks)
from render.shaders import prog_name, program_sources
from render.world.shadows import Lighting
from render.poses.targets import TARGETS_DEFINE, target_textures, use_targets
from render.poses import draw as posed_draw
from render.poses.draw import morph_vao
from render.screen import write_pixel_ray
from render.poses.cache import PoseCache
from render.raster.hook import hardware_pieces
from render.raster.hook import split as raster_split
from lod.raster_route import DEFAULT_THRESHOLD
from render.timing import gpu_seconds
from render.tint import TintStream, batch_words
from render.vertex_format import PACKED_VERTICES, compact_influences, skin_attributes, surface_attributes

#: bytes per instance in the instance buffer
INSTANCE_BYTES = INSTANCE_FLOATS * 4
#: initial capacity of the per-frame instance buffer (instances)
INITIAL_INSTANCES = 1024
#: skinning paths: "palette" (per-frame pre-pass, default) or "direct"
SKINNING_MODES = ("palette", "direct")
#: where the compute rasteriser's work composes among the plug-in drawers (their ``order``): after the world drawer
#: (-10: the ground, and the props and solids it hands to the compute path) and the clusters (0: the cuts it takes),
#: before the blob shadows (5: decals that write no depth, which ground rasterised after them would cover) and the
#: points (10)
RASTER_ORDER = 2.5
#: environment variable that turns on debug checks (finite instance data)
DEBUG_ENV = "CROWD_GL_DEBUG"
#: most triangles handed to the driver in one instanced draw before the renderer
#: waits for them (``ctx.finish``): bounds the binned scene data llvmpipe keeps
#: (see "Bounded driver memory" in the module docstring); at ~300 bytes per
#: binned triangle, 100,000 triangles fit one 36 MB llvmpipe scene
MAX_TRIANGLES_IN_FLIGHT = 100_000

_INSTANCE_ATTRS = ("i_m0", "i_m1", "i_m2", "i_anim")
_DRAW_ATTRS = (*_INSTANCE_ATTRS, "i_tint")  # + the colour words (render/tint.py)


#: Representation kinds drawn by plug-in drawers: kind -> module exposing ``Drawer``.
#: A ``Drawer(renderer)`` has ``upload(rep)``, ``draw(batches, drawlist, view_proj) -> None``
#: (called after the built-in triangle batches, inside the frame's queries -- or, for a
#: drawer whose ``uses_queries`` is true, after them: its fragments are then not in
#: ``samples_passed`` nor its time in ``gpu`` -- with the
#: renderer's FBO bound and depth test on), ``release()``, and an ``order`` number
#: (lower draws first; opaque triangle kinds before point splats, which depth-test
#: against them). Modules are imported only when a rep of their kind is uploaded.
PLUGIN_KINDS: dict[str, str] = {
    "clusters": "render.clusters.draw",
    "points": "render.points.draw",
    "far": "render.far.draw",  # the far tier (lod.far): one pre-filtered splat per far agent
    "world": "render.world.draw",  # ground, obstacle solids, props (lod.props)
}


@dataclass
class _GpuRep:
    key: str
    kind: str
    vao: object
    locations: dict
    n_indices: int
    objects: list = field(default_factory=list)  # creation order
    joints: object = None  # texture (skinned)
    capture_vao: object = None
    seg_first: np.ndarray | None = None
    seg_count: np.ndarray | None = None
    n_vertices: int = 0
    n_joints: int = 0
    palette_vao: object = None
    # geomorphs of a LOD chain (lod.chains.mode TriangleDrawBatch.morph): the rep with its vertex
    # collapses (kept for the tables, made on first use), then (vertex array, instance locations, tables)
    morph_source: object = None
    morph: dict = field(default_factory=dict)  # extra defines -> (vertex array, instance locations, tables)
    pose_vaos: dict = field(default_factory=dict)  # pose-sharing programs (render/poses/cache.py) -> (vao, locations)
    targets: tuple | None = None  # morph-target textures (render.poses.targets), None for a rep without targets
    defines: tuple = ()  # preprocessor names of the rep's programs ((TARGETS_DEFINE,) with targets)
    cull: bool = False  # back faces culled (a single-sided skinned or static rep)


class Renderer:
    """Owns every GL object it creates; draws DrawLists into an offscreen FBO.

    Parameters
    ----------
    size : (width, height) pixels
    ctx : moderngl context to use (e.g. a glfw window's); a headless EGL
        context is created (and later released) when None.
    samples : MSAA samples of the colour/depth buffers (0 = none)
    debug : check instance data for NaN/Inf before upload (default: the
        ``CROWD_GL_DEBUG`` environment variable is set and not "0")
    skinning : "palette" (default): a transform-feedback pre-pass blends each
        instance's joint matrices between the two baked frames once per frame
        into a palette texture, and the vertex shader reads 3 texels per
        influence; "direct": every vertex blends both frames itself (6 texels
        per influence). Both share ``shaders/poses/skinning.glsl``; the palette path
        is the faster one on llvmpipe (see scripts/bench_baseline.md).
    """

    def __init__(self, size=(1280, 720), ctx=None, samples: int = 0, debug: bool | None = None,
                 skinning: str = "palette"):
        if skinning not in SKINNING_MODES:
            raise ValueError(f"Renderer skinning: expected one of {SKINNING_MODES}, got {skinning!r}")
        self.skinning = skinning
        self.size = (int(size[0]), int(size[1]))
        if self.size[0] < 1 or self.size[1] < 1:
            raise ValueError(f"Renderer size: expected positive (width, height), got {size}")
        self._own_ctx = ctx is None
        self.ctx = create_context() if ctx is None else ctx
        self.samples = int(samples)
        self.debug = (os.environ.get(DEBUG_ENV, "0") not in ("", "0")) if debug is None else bool(debug)
        self._objects: list = []
        self._reps: dict[str, _GpuRep] = {}
        self._plugin_reps: dict[str, str] = {}  # rep key -> kind drawn by a plug-in drawer
        self._sources: dict = {}  # rep key -> the representation uploaded under it (Renderer.reprogram)
        self._uploading = 0
        self._drawers: dict = {}  # kind -> Drawer (created on first upload of that kind)
        self._programs: dict = {}
        self._released = False
        w, h = self.size
        ctx = self.ctx
        self._color = self._track(ctx.renderbuffer((w, h), 4, samples=self.samples), "render.color")
        self._depth = self._track(ctx.depth_renderbuffer((w, h), samples=self.samples), "render.depth")
        self.fbo = self._track(ctx.framebuffer([self._color], self._depth), "render.fbo")
        if self.samples:
            self._resolve_color = self._track(ctx.renderbuffer((w, h), 4), "render.resolve_color")
            self._resolve = self._track(ctx.framebuffer([self._resolve_color]), "render.resolve_fbo")
        else:
            self._resolve = None
        self._instance_capacity = 0
        self._instances = None
        self._grow_instances(INITIAL_INSTANCES)
        #: (n agents,) uint32 variation words (lod.variation.variation_table) or None; the app sets it
        self.tint_table = None
        self._tint = self._track(TintStream(ctx), "crowd.instance_tints")
        self._palette = Palette(ctx, self._track, self._objects.remove)  # render/poses/palette.py
        #: pose sharing (render/poses/cache.py): copies in one pose drawn from posed vertices skinned once
        self.poses = PoseCache(self)
        #: use the DrawList's pose table (``DrawList.poses``) when it has one; False draws every copy with its
        #: own palette (the per-instance pre-pass, as before pose sharing)
        self.pose_sharing = True
        #: poses evaluated (joint matrices blended for a pose) in the frame being drawn: the pose cache's palettes
        #: plus any per-copy palette (the pre-pass), per-vertex blend ("direct") or follow pose without a palette;
        #: ``DrawList.stats["pose_passes"]`` after :meth:`draw` (issue 33: at most one per distinct pose)
        self.pose_evaluations = 0
        # separate queries, nested: a combined samples+time query reads a
        # constant ~20 ns on llvmpipe (see gpu_seconds)
        self._q_samples = self._track(ctx.query(samples=True), "render.query.samples")
        self._q_time = self._track(ctx.query(time=True), "render.query.time")
        self.last_timings: dict = {}
        #: most triangles per instanced submission before a ``ctx.finish`` (None: no limit)
        self.max_triangles_in_flight = MAX_TRIANGLES_IN_FLIGHT
        #: instanced submissions of the last ``draw`` (> batches when draws were split)
        self.last_submissions = 0
        # the light, the shadow map and the blob shadows, drawn among the plug-in drawers (render.shadows)
        self.lighting = self._drawers["shadows"] = Lighting(self)
        #: pack vertex attributes of reps uploaded from now on (render/vertex_format.py)
        self.packed_vertices = PACKED_VERTICES
        #: light the headlight by the pixel's camera ray, not a position varying (programs compiled from now on)
        self.pixel_ray = True
        #: skinned programs read only as many influences as the rep's vertices use (reps uploaded from now on)
        self.specialize_influences = True
        #: rasterise small triangles in compute (render/raster/; off on contexts below GL 4.3), and the
        #: threshold (pixels, [render] raster_threshold) above which a triangle stays on the hardware path
        self.compute_raster = int(getattr(self.ctx, "version_code", 0)) >= 430
        self.raster_threshold = DEFAULT_THRESHOLD
        self._raster = None
        #: this frame's compute work (render.raster.frame.Work), filled by render/raster/hook.py and the world drawer
        self.raster_work: list = []

    # ------------------------------------------------------------------ resources
    def _track(self, obj, label: str):
        return track(self._objects, obj, label)  # render.context.track

    def _grow_instances(self, n: int) -> None:
        cap = max(INITIAL_INSTANCES, self._instance_capacity)
        while cap < n:
            cap *= 2
        if cap == self._instance_capacity and self._instances is not None:
            return
        if self._instances is not None:
            self._instances.release()
            self._objects.remove(self._instances)
        self._instances = self._track(self.ctx.buffer(reserve=cap * INSTANCE_BYTES, dynamic=True), "crowd.instances")
        self._instance_capacity = cap

    def program(self, name: str, varyings: tuple = (), defines: tuple = ()):
        """Compiled program ``name`` (cached). With ``varyings`` it is the
        vertex-only transform-feedback variant recording those outputs; with
        ``defines`` the variant compiled with those preprocessor names."""
        defines = tuple(defines) + (("PIXEL_RAY",) if self.pixel_ray and not varyings else ())  # render/screen.py
        defines += self.shadow_defines() if not varyings else ()
        key = (name, tuple(varyings), tuple(defines))
        if key not in self._programs:
            src = program_sources(name, fragment=not varyings, defines=tuple(defines))
            prog = self.ctx.program(**src, varyings=list(varyings)) if varyings else self.ctx.program(**src)
            label = f"render.program.{name}" + "".join(f"+{d}" for d in defines) + (".capture" if varyings else "")
            self._programs[key] = self._track(prog, label)
        return self._programs[key]

    # the skinning palette lives in render/poses/palette.py; these forward to it
    palette_width = property(lambda self: self._palette.width, lambda self, v: setattr(self._palette, "width", v),
                             doc="texels per palette row (a multiple of 3)")
    palette_chunk_texels = property(lambda self: self._palette.max_texels,
                                    lambda self, v: setattr(self._palette, "max_texels", int(v)),
                                    doc="most palette texels per chunk (render.poses.palette)")
    _palette_tex = property(lambda self: self._palette.texture)

    @property
    def raster(self):
        """The compute rasteriser (render.raster.frame.Raster), made on first use."""
        if self._raster is None:
            from render.raster.frame import Raster

            self._raster = Raster(self)
        return self._raster

    def _build_palette(self, items) -> list:
        """Palette pre-pass of one chunk (``render.poses.palette.Palette.build``): items are
        (_GpuRep, instance buffer, byte offset of the first instance, count); returns
        each item's first palette texel, the texture bound to unit 1."""
        self.pose_evaluations += sum(int(k) for _, _, _, k in items)  # one palette per copy
        return self._palette.build(self.program("palette", ("v_row",)), items, INSTANCE_BYTES)

    def _palette_chunks(self, items) -> list:
        """``items`` as :meth:`_build_palette` takes them, cut into chunks that fit
        (:func:`render.poses.palette.plan_chunks`): a list of item lists, offsets moved to
        each piece's first instance; each piece also names its item and first instance."""
        plan = plan_chunks([k for _, _, _, k in items], [3 * g.n_joints for g, _, _, _ in items],
                           self._palette.chunk_texels)
        return [[(items[d][0], items[d][1], items[d][2] + f * INSTANCE_BYTES, n, d, f) for d, f, n in ch]
                for ch in plan]

    def shadow_defines(self) -> tuple:
        """Defines of the lit programs: ``SHADOW_MAP`` when shadow maps are on (shaders/world/shadow.glsl
        compiles its lookup only then; render.world.shadows.Lighting.configure re-uploads what was compiled
        without it when the mode changes)."""
        return ("SHADOW_MAP",) if self.lighting.mode == "map" else ()

    def reprogram(self) -> None:
        """Every uploaded representation uploaded again (in upload order), its programs and vertex arrays made
        for the current :meth:`shadow_defines`."""
        for rep in list(self._sources.values()):
            self.upload(rep)

    def upload(self, rep) -> None:
        """Create the GPU resources of a representation (``lod.full.mode`` rep);
        re-uploading a key replaces the old resources."""
        if not self._uploading:  # a drawer's own upload of a part (a clusters rep's skinned mesh) is not a source
            self._sources.pop(rep.key, None)
            self._sources[rep.key] = rep  # (re-)uploaded last: reprogram keeps the order
        self._uploading += 1
        try:
            self._upload(rep)
        finally:
            self._uploading -= 1

    def _upload(self, rep) -> None:
        if rep.key in self._reps:
            self._release_rep(self._reps.pop(rep.key))
        kind = rep.kind
        self.lighting.note_rep(rep)  # footprint of its blob shadow
        if kind in PLUGIN_KINDS:
            self.drawer(kind).upload(rep)
            self._plugin_reps[rep.key] = kind
            return
        self._plugin_reps.pop(rep.key, None)
        ctx = self.ctx
        objs: list = []

        def buf(a, label):
            data = np.ascontiguousarray(a).tobytes()
            b = ctx.buffer(data) if data else ctx.buffer(reserve=16)  # GL buffers cannot be empty
            b.label = f"{rep.key}.{label}"
            objs.append(b)
            return b

        defines = (TARGETS_DEFINE,) if kind == "skinned" and getattr(rep, "targets", None) is not None else ()
        if kind == "skinned":
            jn, wt, n_inf = compact_influences(rep.joints, rep.weights)
            if n_inf < 4 and self.specialize_influences and getattr(rep, "collapse_next", None) is None:
                defines += (f"SKIN_INFLUENCES_{n_inf}",)  # shaders/poses/skinning.glsl (geomorph tables are not compacted)
            prog = self.program(prog_name(kind, self.skinning), defines=defines)
            tex = joint_texture(ctx, rep.key, rep.joint_table)
            tex.label = f"{rep.key}.joints"
            objs.append(tex)
            content = surface_attributes(rep, buf, self.packed_vertices) + \
                skin_attributes(rep, buf, self.packed_vertices, jn, wt)
            n_vertices = rep.positions.shape[0]
        elif kind == "keyframed":
            prog = self.program("keyframed")
            tex = None
            content = [
                (buf(rep.positions0, "positions0"), "3f", "in_position0"),
                (buf(rep.positions1, "positions1"), "3f", "in_position1"),
                (buf(rep.normals0, "normals0"), "3f", "in_normal0"),
                (buf(rep.normals1, "normals1"), "3f", "in_normal1"),
                (buf(rep.colors0, "colors0"), "4f", "in_color0"),
                (buf(rep.colors1, "colors1"), "4f", "in_color1"),
            ]
            n_vertices = rep.positions0.shape[0]
        elif kind == "static":
            prog = self.program("static")
            tex = None
            content = surface_attributes(rep, buf, self.packed_vertices)  # render/vertex_format.py
            n_vertices = rep.positions.shape[0]
        else:
            raise TypeError(f"Renderer.upload: representation {rep.key!r} has unknown kind {kind!r}; "
                            "expected 'skinned', 'keyframed' or 'static'")
        content = [c for c in content if c[2] in prog]
        ibo = buf(np.asarray(rep.indices, np.uint32), "indices")
        vao = ctx.vertex_array(prog, content, index_buffer=ibo, index_element_size=4)
        vao.label = f"{rep.key}.vao"
        objs.append(vao)
        locs = {a: prog[a].location for a in _DRAW_ATTRS if a in prog}
        # capture VAO (transform feedback; no index buffer: one output per vertex)
        cprog = self.program(prog_name(kind, self.skinning), ("v_world", "v_normal"), defines)
        cvao = ctx.vertex_array(cprog, [c for c in content if c[2] in cprog])
        cvao.label = f"{rep.key}.capture_vao"
        objs.append(cvao)
        g = _GpuRep(rep.key, kind, vao, locs, int(np.asarray(rep.indices).size), objs, tex, cvao,
                    n_vertices=int(n_vertices))
        g.capture_locs = {a: cprog[a].location for a in _INSTANCE_ATTRS if a in cprog}
        g.cull = kind in ("skinned", "static") and getattr(rep, "double_sided", True) is False
        g.content = content  # vertex buffers (buffer, format, attribute), reused by plug-in drawers
        # a LOD chain (lod.chains.mode) holds all its levels: a batch without index_range draws level 0
        g.default_count = 3 * int(rep.level_count[0]) if hasattr(rep, "level_count") else g.n_indices
        g.defines = defines
        g.source = rep  # the compute rasteriser reads its arrays (render/raster/)
        if TARGETS_DEFINE in defines:  # morph targets (render.poses.targets); g.objects is objs
            g.targets = target_textures(ctx, rep.targets, rep.joint_table.shape[0], rep.key)
            objs.extend(g.targets)
        if kind == "skinned":
            g.n_joints = int(rep.joint_table.shape[1])
            self.poses.note_rep(rep, tex, g.targets)  # its mesh, posed once per distinct pose
            pvao = ctx.vertex_array(self.program("palette", ("v_row",)), [])
            pvao.label = f"{rep.key}.palette_vao"
            objs.append(pvao)
            g.palette_vao = pvao
        if kind == "keyframed":
            g.seg_first = np.asarray(rep.seg_first, np.int64)
            g.seg_count = np.asarray(rep.seg_count, np.int64)
        if kind == "skinned" and getattr(rep, "collapse_next", None) is not None:
            g.morph_source = rep
        self._objects.extend(objs)
        self._reps[rep.key] = g

    def _release_rep(self, g: _GpuRep) -> None:
        for o in reversed(g.objects):
            o.release()
            if o in self._objects:
                self._objects.remove(o)

    def uploaded_drawer(self, kind: str):
        """The plug-in Drawer of representation ``kind`` when one was created, else None."""
        return self._drawers.get(kind)

    def drawer(self, kind: str):
        """The plug-in Drawer of representation ``kind`` (created on first use)."""
        d = self._drawers.get(kind)
        if d is None:
            import importlib

            d = importlib.import_module(PLUGIN_KINDS[kind]).Drawer(self)
            self._drawers[kind] = d
        return d

    @property
    def reps(self) -> list:
        """Keys of the uploaded representations."""
        return [*self._reps, *self._plugin_reps]

    # ------------------------------------------------------------------ drawing
    def _bind_instances(self, vao, locs: dict, buffer, offset: int, tints=None) -> None:
        for i, name in enumerate(_INSTANCE_ATTRS):
            loc = locs.get(name)
            if loc is not None:
                vao.bind(loc, "f", buffer, "4f", offset=offset + 16 * i, stride=INSTANCE_BYTES, divisor=1)
        (self._tint if tints is None else tints).bind(vao, locs.get("i_tint"), offset // INSTANCE_BYTES)

    def _render_instanced(self, g: _GpuRep, prog, palette_base, offset: int, vertices: int, first: int,
                          k: int, vao=None, locs=None) -> None:
        """Draw ``k`` instances of ``g`` (instance data from byte ``offset`` of
        the instance buffer, already bound there) in submissions of at most
        ``max_triangles_in_flight`` triangles, waiting for the driver between
        them (bounds llvmpipe's binned scenes; see the module docstring). Each
        later submission re-binds the instance attributes at its first
        instance and, for palette skinning, moves ``u_palette_base`` by as
        many palette blocks (the shader indexes both by ``gl_InstanceID``)."""
        ctx = self.ctx
        vao = g.vao if vao is None else vao
        locs = g.locations if locs is None else locs
        budget = self.max_triangles_in_flight
        per = k if not budget else max(1, int(budget) // max(1, vertices // 3))
        for s in range(0, k, per):
            if s:
                ctx.finish()
                self._bind_instances(vao, locs, self._instances, offset + s * INSTANCE_BYTES)
                if palette_base is not None:
                    prog["u_palette_base"].value = palette_base + s * 3 * g.n_joints
            vao.render(ctx.TRIANGLES, vertices=vertices, first=first, instances=min(per, k - s))
            self.last_submissions += 1

    def _set_uniforms(self, prog, view_proj: np.ndarray) -> None:
        prog["u_view_proj"].write(np.ascontiguousarray(view_proj.T, np.float32).tobytes())
        self.lighting.apply(prog)  # light and shadow-map uniforms (render.shadows)
        if "u_joints" in prog:
            prog["u_joints"].value = 0
        if "u_palette" in prog:
            prog["u_palette"].value = 1
        if "u_fade" in prog:
            prog["u_fade"].value = (0.0, 0.0)
        write_pixel_ray(prog, view_proj, self.size)

    def _draw_batch(self, b, offset: int, view_proj, used: set, pieces=None, cursor=None) -> None:
        """Draw built-in batch ``b`` (instance data from byte ``offset``) with ``view_proj``; programs not in
        ``used`` get their uniforms first. ``pieces``: (first instance, count, palette chunk, item) in draw order
        (palette skinning: ``cursor``, a render.poses.palette.PaletteCursor, builds each chunk's palette when its first
        piece comes); default all instances, no palette. The camera pass and the shadow-map pass share it."""
        g = self._reps[b.rep]
        if g.n_indices == 0:
            return
        morph = getattr(b, "morph", None) if g.kind == "skinned" else None
        shared = self.poses.shared(b) if g.kind == "skinned" else None  # pose sharing (render/poses/cache.py)
        if shared is not None:
            vao, locs = posed_draw.pose_vao(self, g, shared[0], morph is not None)  # render/poses/draw.py
        else:
            vao, locs = morph_vao(self, g) if morph is not None else (g.vao, g.locations)
        prog = vao.program
        if id(prog) not in used:
            self._set_uniforms(prog, view_proj)
            used.add(id(prog))
        if morph is not None:  # a geomorphed chain level (lod.chains.mode TriangleDrawBatch.morph)
            level, weight = int(morph[0]), float(morph[1])
            prog["u_morph_level"].value = level
            prog["u_morph_weight"].value = min(1.0, max(0.0, weight)) if weight == weight else 0.0
        use_targets(prog, g.targets)  # no-op without morph targets
        if "u_fade" in prog:  # screen-door transition of a keyframed selection (lod.drawlist.fade_uniform)
            prog["u_fade"].value = fade_uniform(getattr(b, "fade", None))
        if g.kind == "keyframed":
            first, count = int(g.seg_first[b.part]), int(g.seg_count[b.part])
        elif getattr(b, "index_range", None) is not None:  # one level of a LOD chain
            first, count = (int(v) for v in b.index_range)
            if not (0 <= first and 0 <= count and first + count <= g.n_indices):
                raise ValueError(f"DrawBatch {b.rep!r}: index_range {b.index_range} outside the "
                                 f"{g.n_indices} indices of the representation")
        else:
            first, count = 0, g.default_count
        if shared is not None:
            posed_draw.draw_shared(self, g, prog, vao, locs, shared, b, offset, count, first, pieces)
            return
        for f, k, c, j in pieces or [(0, b.n_instances, -1, 0)]:
            pb = cursor.base(c, j) if cursor is not None and c >= 0 else None
            if pb is not None:
                prog["u_palette_base"].value = pb
                prog["u_palette_stride"].value = 3 * g.n_joints
            if g.joints is not None:
                g.joints.use(0)
            off = offset + f * INSTANCE_BYTES
            self._bind_instances(vao, locs, self._instances, off)
            (self.ctx.enable if g.cull else self.ctx.disable)(self.ctx.CULL_FACE)  # single-sided reps
            self._render_instanced(g, prog, pb, off, count, first, k, vao, locs)

    def draw(self, drawlist, background=(0.1, 0.1, 0.12)) -> dict:
        """Draw a ``lod.drawlist.DrawList`` into the offscreen framebuffer.

        Returns
        -------
        dict of seconds: ``upload`` (instance data to the GPU), ``draw`` (CPU
        submission), ``finish`` (waiting in ``ctx.finish``), ``gpu`` (timer
        query, or None where the driver gives nothing usable), and
        ``samples_passed`` (int, fragments that passed the depth test).
        ``drawlist.stats`` gains the counts of what was drawn, among them
        ``gl_created``: the GL objects this draw made (programs compiled on
        first use, buffers grown; ``DrawList.warm_up``).
        """
        ctx = self.ctx
        made = created()  # GL objects made during this draw: one-time costs (stats["gl_created"])
        batches = [b for b in drawlist.batches if b.n_instances]
        self.pose_evaluations = 0
        plugin: dict = {}
        for b in batches:
            if b.rep in self._plugin_reps:
                plugin.setdefault(self._plugin_reps[b.rep], []).append(b)
        batches = [b for b in batches if b.rep not in self._plugin_reps]
        plugin["shadows"] = []  # the blob shadows (Lighting.draw: after the ground, before clusters and points)
        for b in batches:
            if b.rep not in self._reps:
                raise KeyError(f"DrawList batch names representation {b.rep!r}, which was not uploaded; "
                               f"uploaded: {sorted(self._reps)}")
        tp = time.perf_counter()
        # pose sharing (render/poses/cache.py): palettes of the distinct poses, posed vertices, and which skinned
        # batches draw from them (a batch whose slots span several posed windows is sorted by window)
        self.poses.begin(getattr(drawlist, "poses", None) if self.pose_sharing and self.skinning == "palette"
                         else None)
        batches = self.poses.plan(batches, self._reps)
        self.pose_evaluations += int(self.poses.last_stats.get("poses", 0))
        if self.skinning != "palette":  # every vertex blends its copy's frame pair itself
            self.pose_evaluations += sum(b.n_instances for b in batches if b.rep in self._reps
                                         and self._reps[b.rep].kind == "skinned")
        t0 = time.perf_counter()
        # small triangles to the compute rasteriser: its instances last in their batches (render/raster/hook.py)
        batches, hw_counts, self.raster_work = raster_split(self, batches, drawlist)
        total = sum(b.n_instances for b in batches)
        if batches:
            data = np.concatenate([np.asarray(b.instance_data, np.float32).reshape(-1, INSTANCE_FLOATS)
                                   for b in batches]) if len(batches) > 1 else \
                np.ascontiguousarray(batches[0].instance_data, np.float32)
            if self.debug and not np.isfinite(data).all():
                bad = next(b for b in batches if not np.isfinite(b.instance_data).all())
                raise FloatingPointError(f"DrawBatch {bad.rep!r} part {bad.part}: instance data hold NaN or Inf")
            self._grow_instances(total)
            self._instances.orphan(self._instance_capacity * INSTANCE_BYTES)
            self._instances.write(data)
            self._tint.write(batch_words(batches, self.tint_table))  # colour words (render/tint.py)
        t1 = time.perf_counter()
        view_proj = np.asarray(drawlist.proj, np.float64) @ np.asarray(drawlist.view, np.float64)
        self.fbo.use()
        ctx.viewport = (0, 0) + self.size
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        bg = tuple(float(c) for c in background)[:3]
        self.fbo.clear(*bg, 1.0, depth=1.0)
        used = set()
        self.last_submissions = 0
        self._palette.passes = 0
        with self._q_samples, self._q_time:
            starts = np.concatenate([[0], np.cumsum([b.n_instances for b in batches], dtype=np.int64)]) * INSTANCE_BYTES
            # palette skinning: the skinned batches' instances cut into chunks whose palette fits (render.poses.palette);
            # each batch is drawn as its pieces (first instance, count, chunk, item of the chunk) in draw order
            pieces: dict = {}
            chunks: list = []
            if self.skinning == "palette":
                sk = [i for i, b in enumerate(batches) if self._reps[b.rep].kind == "skinned"
                      and self._reps[b.rep].n_indices and self.poses.shared(b) is None]
                chunks = self._palette_chunks([(self._reps[batches[i].rep], self._instances, int(starts[i]),
                                                batches[i].n_instances) for i in sk]) if sk else []
                for c, ch in enumerate(chunks):
                    for j, piece in enumerate(ch):
                        pieces.setdefault(sk[piece[4]], []).append((piece[5], piece[3], c, j))
            cursor = PaletteCursor(self._build_palette, chunks, self.ctx)
            offsets = starts.tolist()
            self.lighting.shadow_pass(batches, plugin, drawlist, pieces, cursor, offsets)  # [render] shadows = "map"
            for i, b in enumerate(batches):
                p = pieces.get(i) if i not in hw_counts else hardware_pieces(pieces.get(i), b.n_instances, hw_counts[i])
                if p != []:
                    self._draw_batch(b, offsets[i], view_proj, used, p, cursor)
            ctx.disable(ctx.CULL_FACE)
            kinds = sorted(plugin, key=lambda k: (getattr(self._drawers[k], "order", 0), k))
            # a drawer issuing occlusion queries of its own (``uses_queries``) runs after the frame's
            # samples query closes: GL allows one active samples query at a time
            querying = [k for k in kinds if getattr(self._drawers[k], "uses_queries", False)]
            rc = None
            for kind in kinds:
                if kind in querying:
                    continue
                if rc is None and getattr(self._drawers[kind], "order", 0) > RASTER_ORDER:
                    rc = self._raster_pass(view_proj)
                self.fbo.use()
                self._drawers[kind].draw(plugin[kind], drawlist, view_proj)
            if rc is None:
                rc = self._raster_pass(view_proj)
            drawlist.stats["raster_triangles"] = int(rc.get("triangles", 0)) - int(rc.get("spilled", 0))
        for kind in querying:
            self.fbo.use()
            self._drawers[kind].draw(plugin[kind], drawlist, view_proj)
        if self.raster_work:  # work a querying drawer handed over (cluster cuts with occlusion culling)
            late = self._raster_pass(view_proj)
            drawlist.stats["raster_triangles"] += int(late.get("triangles", 0)) - int(late.get("spilled", 0))
        t2 = time.perf_counter()
        ctx.finish()
        t3 = time.perf_counter()
        timings = {
            "upload": t1 - t0,
            "draw": t2 - t1 + (t0 - tp),  # the pose cache's palettes and skinning pass included
            "poses": t0 - tp,
            "finish": t3 - t2,
            "gpu": gpu_seconds(self._q_time.elapsed, t3 - t1),
            "samples_passed": int(self._q_samples.samples),
        }
        self.last_timings = timings
        drawlist.stats["pose_passes"] = int(self.pose_evaluations)
        drawlist.stats["gl_created"] = created() - made
        if getattr(drawlist, "poses", None) is not None:  # what the pose cache skinned (the LOD side counted what
            # its copies read; the compute rasteriser's cluster copies also pose the full mesh): frames.csv and
            # auto's fit take the work done
            drawlist.stats["posed_vertices"] = int(self.poses.last_stats.get("posed_vertices", 0))
        return timings

    def _raster_pass(self, view_proj) -> dict:
        """The compute rasteriser's work of the frame (built-in batches, the world's props and solids), composed
        by depth at :data:`RASTER_ORDER`; its counts ({} when there was none)."""
        rc = self.raster.draw(self.raster_work, view_proj) if self.raster_work else {}
        self.raster_work = []
        return rc

    def capture(self, key: str, instance_data: np.ndarray, part: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Vertex positions and normals as the draw shader computes them (``render.poses.capture``)."""
        from render.poses.capture import capture

        return capture(self, key, instance_data, part)

    # ------------------------------------------------------------------ output
    def read_pixels(self) -> np.ndarray:
        """(h, w, 3) uint8 colour of the last frame, top row first."""
        w, h = self.size
        fbo = self.fbo
        if self._resolve is not None:
            self.ctx.copy_framebuffer(self._resolve, self.fbo)
            fbo = self._resolve
        raw = fbo.read(viewport=(0, 0, w, h), components=3, alignment=1)
        return np.frombuffer(raw, np.uint8).reshape(h, w, 3)[::-1].copy()

    def release(self) -> None:
        """Release every GL object in the reverse order of creation (safe twice);
        the context too if this renderer created it."""
        if self._released:
            return
        self._released = True
        for d in reversed(list(self._drawers.values())):
            d.release()
        self._drawers.clear()
        if self._raster is not None:
            self._raster.release()
        self._plugin_reps.clear()
        self.poses.release()
        release_all(self._objects)  # render.context: reverse order, each once
        self._reps.clear()
        self._programs.clear()
        if self._own_ctx:
            self.ctx.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
