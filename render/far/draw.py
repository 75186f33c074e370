"""Drawer of the far tier (kind ``"far"``, ``lod.far``; issue 45): every far agent is one splat of its pre-filtered
footprint, placed straight from its instance row.

Per representation (:meth:`Drawer.upload`): its footprint tables (``lod.far.footprint.FarTable``, one per clip)
packed as vec4s, lit by the renderer's light: per view cell the ambient and headlight terms and the covered
area, then the direct term at every light azimuth of the table's grid, interpolated at the light's elevation
(a heading turns the light about +Y, never changes its elevation), then the varied part (its mean base colour
and lighting terms: an agent's variation word changes that colour, and the shader lights the change). They are
packed again when the light changes. Layout per clip: ``centre`` (the bounding sphere's, model space), then
``VE x VA`` cells of :data:`CELL` vec4s (``shaders/far/far_splat.glsl``).

Per frame (:meth:`Drawer.draw`), after the opaque kinds and the point splats (:attr:`Drawer.order`):

1. ``far_splat``: one thread per far agent adds its colour x coverage into its pixel's integer accumulators
   (order-free), and the visible part of its blob shadow when the renderer draws blobs, and keeps the nearest
   depth. The colour and area are interpolated between the four view cells around the agent's view direction;
   the two smaller terms, an agent's colour variation and its blob, are the nearest cell's (on llvmpipe each
   table load costs: a million agents, 100 -> 75 ms). The pass is compiled with the blob and variation code
   only when the frame uses them;
2. ``far_resolve``: one full-screen triangle; a reached pixel takes the agents' mean colour with their joint
   coverage (independent agents: ``1 - prod(1 - alpha)``) over the frame darkened by their joint shadow,
   blended at their nearest depth under the depth test (no depth write), and resets its accumulators.
"""
from __future__ import annotations

import math

import numpy as np

from lod.far import footprint as fp
from render.context import release_all, track
from render.shaders import load_source, program_sources
from render.tint import instance_words, takes_variation

#: threads per work group of the splat pass (must match far_splat.glsl)
GROUP = 64
#: largest work-group count per dispatch dimension (GL guarantees 65535)
MAX_GROUPS_X = 65535
#: uint32 accumulators per pixel (depth, r, g, b, alpha, -log(1 - alpha), -log(1 - shadow))
ACC_WORDS = 7
#: radial samples of a blob shadow's opacity in :func:`ground_shadow`
BLOB_SAMPLES = 64
#: vec4s per view cell and per clip (far_splat.glsl CELL, CLIP_VEC4): the lit colour and area, the direct term per
#: light azimuth, the varied part's base colour and light-free terms, its direct terms four to a vec4
VARIED_VEC4 = fp.LIGHT_AZIMUTHS // 4
CELL = 1 + fp.LIGHT_AZIMUTHS + 1 + VARIED_VEC4
CLIP_VEC4 = 1 + fp.VIEW_ELEVATIONS * fp.VIEW_AZIMUTHS * CELL


def ground_shadow(t) -> np.ndarray:
    """(VE, VA) the blob shadow under an agent of far table ``t`` (``render.world.shadows``: its radius from the
    rest pose's extent, its opacity profile) that the body leaves in view from each view direction: the integral
    of opacity x the floor ring's visible share (``FarTable.ground``, interpolated between the rings) over the
    disc, m^2 at scale 1 (seen from straight above; the splat foreshortens it by the view's elevation)."""
    from render.world.shadows import blob_opacity, blob_radius

    if t.ground is None or t.extent is None or not float(t.extent[1]) > 0.0:
        return np.zeros(t.area.shape)
    rb = blob_radius(t.extent)
    rho = (np.arange(BLOB_SAMPLES) + 0.5) / BLOB_SAMPLES  # over the blob's radius
    rings = t.ring_radii()
    g = t.ground.reshape(-1, rings.shape[0])
    vis = np.stack([np.interp(rho * rb, rings, row) for row in g])  # (views, samples)
    ring_area = 2.0 * np.pi * rho * rb * (rb / BLOB_SAMPLES)
    return (vis * (blob_opacity(rho) * ring_area)[None, :]).sum(axis=1).reshape(t.area.shape)


def lit_tables(tables, light, blobs: bool = False) -> np.ndarray:
    """(clips * CLIP_VEC4, 4) float32: the far tables of one representation lit by ``light``
    (``render.world.light.Light``), in the splat shader's layout (see the module docstring); ``blobs``: the
    renderer draws blob shadows, so each view cell carries the part of one under the agent that shows
    (:func:`ground_shadow`, in the alpha of its first direct vec4)."""
    d = np.asarray(light.direction, np.float64)
    el = math.degrees(math.asin(max(-1.0, min(1.0, d[1] / max(np.linalg.norm(d), 1e-30)))))
    fe = (el + 90.0) / 180.0 * (fp.LIGHT_ELEVATIONS - 1)
    e0 = min(int(math.floor(fe)), fp.LIGHT_ELEVATIONS - 2)
    te = fe - e0
    color = np.asarray(light.color, np.float64)
    out = np.zeros((len(tables), CLIP_VEC4, 4), np.float32)
    for k, t in enumerate(tables):
        out[k, 0, :3] = t.centre
        cells = out[k, 1:].reshape(fp.VIEW_ELEVATIONS, fp.VIEW_AZIMUTHS, CELL, 4)
        cells[:, :, 0, :3] = float(light.ambient) * t.ambient + 0.35 * t.head
        cells[:, :, 0, 3] = t.area
        direct = (1.0 - te) * t.direct[:, :, e0] + te * t.direct[:, :, e0 + 1]  # (VE, VA, LA, 3)
        la = fp.LIGHT_AZIMUTHS
        cells[:, :, 1:1 + la, :3] = 0.55 * color * direct
        if blobs:
            cells[:, :, 1, 3] = ground_shadow(t)
        if t.varied is not None:  # the varied part (far_splat.glsl varied()): lit by the shader after the word
            v = t.varied
            cells[:, :, 1 + la, :3] = t.varied_base
            cells[:, :, 1 + la, 3] = float(light.ambient) * v[..., 0] + 0.35 * v[..., 1]
            vd = v[..., 2:].reshape(v.shape[:2] + (fp.LIGHT_ELEVATIONS, la))
            vdir = 0.55 * ((1.0 - te) * vd[:, :, e0] + te * vd[:, :, e0 + 1])  # (VE, VA, LA)
            cells[:, :, 2 + la:, :] = vdir.reshape(vdir.shape[:2] + (VARIED_VEC4, 4))
    out = out.reshape(-1, 4)
    return np.where(np.isfinite(out), out, 0.0).astype(np.float32)


class Drawer:
    """Plug-in drawer of ``lod.far.rep.FarRep`` (see the module docstring).

    last_counts : dict, the far agents handed over ("far") in the last frame
    """

    #: after the point splats (10): the far splats blend over every opaque surface and depth-test against it
    order = 12
    #: the blob pass skips far agents: the far splat carries the visible part of each one's blob itself
    blob_shadows = False

    def __init__(self, renderer):
        self.r = renderer
        self.ctx = renderer.ctx
        if int(getattr(self.ctx, "version_code", 0)) < 430:
            raise RuntimeError(f"the far tier needs OpenGL 4.3 (compute shaders and storage buffers); this "
                               f"context offers {self.ctx.version_code // 100}.{self.ctx.version_code % 100 // 10}")
        self._objects: list = []
        self._reps: dict = {}  # key -> list of FarTable
        self._base: dict = {}  # key -> first vec4 of its tables
        self._table = None
        self._table_light = None  # the light (and blob mode) the table was lit with
        self._bufs: dict = {}
        w, h = renderer.size
        acc = np.zeros((w * h, ACC_WORDS), np.uint32)
        acc[:, 0] = 0xFFFFFFFF
        self._acc = self._track(self.ctx.buffer(acc.tobytes()), "far.accumulators")
        self._splats: dict = {}  # (blobs, varied) -> the splat pass compiled with those defines
        self._resolve = self._track(self.ctx.program(**program_sources("far_resolve")), "far.resolve")
        self._vao = self._track(self.ctx.vertex_array(self._resolve, []), "far.resolve_vao")
        self.last_counts = {"far": 0}

    def _track(self, obj, label: str):
        return track(self._objects, obj, label)

    def _tints(self, b):
        """(k,) uint32 colour-variation words of a far batch's agents (the renderer's tint table; ``lod.variation``),
        or None when nothing varies. Far agents are state rows, so a plain gather (``render.tint.instance_words``
        checks every id: 12 ms a million)."""
        table = getattr(self.r, "tint_table", None)
        if table is None or not takes_variation(b.rep):
            return None
        table = np.asarray(table, np.uint32)
        ids = np.asarray(b.instance_ids)
        if ids.size and (int(ids.min()) < 0 or int(ids.max()) >= table.shape[0]):
            return instance_words(table, ids)[:, 0].copy()
        return table[ids]

    def _splat(self, blobs: bool, varied: bool):
        """The splat pass with the code of blob shadows and of colour variation only where they are used."""
        k = (bool(blobs), bool(varied))
        if k not in self._splats:
            head, rest = load_source("far_splat.glsl").split("\n", 1)
            defines = "".join(f"#define {d}\n" for d, on in zip(("BLOBS", "VARIED"), k) if on)
            self._splats[k] = self._track(self.ctx.compute_shader(head + "\n" + defines + rest), f"far.splat{k}")
        return self._splats[k]

    def _buffer(self, name, data: np.ndarray):
        raw = memoryview(np.ascontiguousarray(data)).cast("B")
        b = self._bufs.get(name)
        if b is None or b.size < len(raw):
            if b is not None:
                b.release()
                self._objects.remove(b)
            size = 1 << max(8, int(np.ceil(np.log2(max(len(raw), 1)))))
            b = self._track(self.ctx.buffer(reserve=size, dynamic=True), f"far.{name}")
            self._bufs[name] = b
        if len(raw):
            b.write(raw)
        return b

    def upload(self, rep) -> None:
        """Keep a FarRep's tables (packed and lit at the next draw); replaces a previous upload."""
        self._reps[rep.key] = list(rep.tables)
        self._table_light = None

    def _tables(self):
        lit = (self.r.lighting.light, self.r.lighting.mode == "blob")
        if self._table is None or self._table_light != lit:
            parts, base = [], 0
            for key, tables in self._reps.items():
                self._base[key] = base
                parts.append(lit_tables(tables, *lit))
                base += parts[-1].shape[0]
            data = np.concatenate(parts) if parts else np.zeros((1, 4), np.float32)
            if self._table is not None:
                self._table.release()
                self._objects.remove(self._table)
            self._table = self._track(self.ctx.buffer(data.tobytes()), "far.tables")
            self._table_light = lit
        return self._table

    def draw(self, batches, drawlist, view_proj) -> None:
        """Splat the far agents of this frame's ``lod.far.select.FarBatch`` es and blend them in."""
        batches = [b for b in batches if b.rep in self._reps and b.n_instances]
        self.last_counts = {"far": int(sum(b.n_instances for b in batches))}
        if not batches:
            return
        ctx = self.ctx
        w, h = self.r.size
        table = self._tables()
        light = np.asarray(self.r.lighting.light.direction, np.float64)
        proj = np.asarray(drawlist.proj, np.float64)
        vp = np.ascontiguousarray(np.asarray(view_proj, np.float64).T, np.float32).tobytes()
        blobs = self.r.lighting.mode == "blob"
        table.bind_to_storage_buffer(2)
        self._acc.bind_to_storage_buffer(3)
        for i, b in enumerate(batches):
            tints = self._tints(b)
            varied = tints is not None and bool(tints.any())
            cs = self._splat(blobs, varied)
            cs["u_view_proj"].write(vp)
            cs["u_size"].value = (int(w), int(h))
            cs["u_light_az"].value = float(math.atan2(light[0], light[2]))
            cs["u_pixels"].value = (float(proj[0, 0] * w * 0.5), float(proj[1, 1] * h * 0.5))
            if varied:
                cs["u_light_color"].value = tuple(float(c) for c in self.r.lighting.light.color)
                self._buffer(f"tints{i}", np.ascontiguousarray(tints)).bind_to_storage_buffer(4)
            rows = self._buffer(f"rows{i}", np.asarray(b.instance_data, np.float32).reshape(-1, 4))
            words = self._buffer(f"words{i}", np.asarray(b.words, np.uint32).reshape(-1))
            rows.bind_to_storage_buffer(0)
            words.bind_to_storage_buffer(1)
            cs["u_count"].value = int(b.n_instances)
            tint = getattr(b, "tint", None)  # colour by representation or level (lod.debug_colors)
            cs["u_tint"].value = tuple(float(v) for v in tint[:4]) if tint is not None else (0.0, 0.0, 0.0, 0.0)
            cs["u_base"].value = int(self._base[b.rep])
            groups = -(-b.n_instances // GROUP)
            gx = min(groups, MAX_GROUPS_X)
            cs.run(gx, -(-groups // gx), 1)
        ctx.memory_barrier()
        self._resolve["u_size"].value = (int(w), int(h))
        fbo = self.r.fbo
        fbo.depth_mask = False
        fbo.use()  # moderngl applies a framebuffer's write masks when it is bound
        ctx.enable(ctx.BLEND)
        ctx.blend_func = (ctx.ONE, ctx.ONE_MINUS_SRC_ALPHA, ctx.ZERO, ctx.ONE)  # premultiplied (far_resolve)
        try:
            self._vao.render(mode=ctx.TRIANGLES, vertices=3)
        finally:
            ctx.disable(ctx.BLEND)
            fbo.depth_mask = True
            fbo.use()
        ctx.memory_barrier()

    def release(self) -> None:
        """Release every GL object (reverse creation order; safe twice)."""
        release_all(self._objects)
        self._table = None
        self._bufs.clear()
