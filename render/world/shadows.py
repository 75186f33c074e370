"""The scene's light and the agents' shadows: blob decals or a shadow map (``[render] shadows``).

:class:`Lighting` belongs to a :class:`render.renderer.Renderer` (``renderer.lighting``) and does three things:

- ``apply(prog)``: sets the light uniforms (:mod:`render.world.light`) and the shadow-map uniforms
  (``shaders/world/shadow.glsl``) of any program that declares them. The renderer calls it for every character
  program; world shaders (ground, props) call it on theirs, include ``shadow.glsl`` and multiply their direct
  light by ``shadow_visibility(v_world, normal)``.
- ``shadow_pass``: with ``mode == "map"``, before anything else of the frame is drawn, renders the depth of the
  casters from the light into a ``size`` x ``size`` depth texture. The projection is orthographic along the
  light direction and fitted to the light-space bounds of the casters drawn this frame within ``distance`` metres
  of the camera (Williams 1978, *Casting curved shadows on curved surfaces*, with the bounds fit of
  "stable" directional shadow maps: the window is snapped to whole texels in world space so that a moving camera
  does not make the edges crawl). Casters are the built-in triangle batches in their chosen representation:
  full detail (mode none), triangle chain levels (mode triangles, geomorphs included), keyframed and static
  representations (props); each is drawn with the very program of the camera pass (``Renderer._draw_batch``)
  and slope-scaled polygon offset; cluster cuts (mode clusters) cast through the cluster drawer pointed at the map
  (the renderer's skinning palette is rebuilt after it); a plug-in drawer with a
  ``cast_shadows(batches, drawlist, light_vp)`` method (props) draws its own depth. The terrain and a ground
  (``static:terrain``, ``static:ground``) only receive. Point representations, and cluster cuts with occlusion
  culling on (its queries cannot run inside the frame's), do not cast: their agents get blob shadows instead.
  Receivers sample it with 3x3 PCF on a depth-comparing sampler (Reeves, Salesin & Cook 1987), with a normal
  offset and a constant bias against acne.
- ``draw``: blob shadows, a soft dark disc under each agent (mode "blob", and in mode "map" for the agents drawn
  as points or clusters; never under a plug-in drawer's statics that say ``blob_shadows = False``: the world's
  props and obstacle solids). One instanced draw of a quad per agent lying at its floor point (only the quads that
  can cover a pixel centre: a far agent's is a fraction of a pixel, usually between centres; :mod:`render.world.blobs`,
  the image unchanged) (the representation's
  lowest vertex under the centre of its footprint, through the instance matrix), radius from the footprint of the
  representation's rest pose times the instance scale; alpha-blended, depth-tested without depth writes, lifted by
  :data:`BLOB_LIFT` metres and pulled forward by polygon offset (no z-fighting with the ground). The renderer
  runs it as a plug-in drawer ordered after every other writer of the ground's depth and colour -- its own
  batches (characters, terrain), the world's ground, the clusters and the compute rasteriser's work
  (``render.renderer.RASTER_ORDER``: ground it rasterised after the blobs would cover them) -- and before the
  point splats: a decal on whatever is already in the depth buffer at the agent's feet, hidden where a character
  stands in front of it.

Everything handed to the GPU is checked finite; a frame without casters draws no map (everything lit).
"""
from __future__ import annotations

import math

import moderngl
import numpy as np

from render.world.blobs import blob_rows, covering
from render.context import release_all, track
from render.world.light import DEFAULT_SHADOWS, SHADOW_MODES, Light, apply_light  # noqa: F401  (re-exported)

#: default side of the shadow map, texels
DEFAULT_MAP_SIZE = 2048
#: default distance from the camera within which agents cast into the shadow map, metres
DEFAULT_SHADOW_DISTANCE = 60.0
#: texture unit of the shadow map (0, 1: joints and palette; 2, 3: geomorphs; 4-6: morph targets)
SHADOW_UNIT = 7
#: opacity of a blob shadow at its centre, and the fraction of its radius where it starts to fade
BLOB_OPACITY = 0.55
BLOB_INNER = 0.25
#: blob radius = this x (x extent + z extent) of the representation's rest pose, clamped to BLOB_HEIGHT_RANGE x its
#: height (a humanoid 1.8 m tall, 0.55 m wide and 0.3 m deep gets 0.42 m; T-posed, 1.8 m wide, 0.54 m)
BLOB_RADIUS_FACTOR = 0.5
BLOB_HEIGHT_RANGE = (0.2, 0.3)
#: metres a blob lies above the agent's floor point
BLOB_LIFT = 0.01
#: polygon offset (factor, units) of the blobs (towards the camera) and of the shadow-map casters (away)
BLOB_POLYGON_OFFSET = (-1.0, -4.0)
CASTER_POLYGON_OFFSET = (2.0, 4.0)
#: shadow-map depth bias (in depth units) and normal offset (in shadow-map texels)
MAP_DEPTH_BIAS = 0.0015
MAP_NORMAL_OFFSET_TEXELS = 1.5
#: representation-key prefixes that receive but never cast into the shadow map
RECEIVE_ONLY = ("static:terrain", "static:ground")


def footprint(rep) -> tuple | None:
    """(centre x, floor y, centre z, blob radius, bounding radius) of a representation's rest pose, in model
    units, or None when it has no vertex positions (``positions``, ``positions0``, ``skinned.positions`` or
    ``keyframed.positions0``, or those of ``base``: points that follow the animation, ``lod.points.follow``)."""
    for path in (("positions",), ("positions0",), ("skinned", "positions"), ("keyframed", "positions0"),
                 ("base", "positions"), ("base", "positions0")):
        obj = rep
        for name in path:
            obj = getattr(obj, name, None)
        if obj is not None:
            p = np.asarray(obj, np.float64).reshape(-1, 3)
            p = p[np.isfinite(p).all(axis=1)]
            if p.shape[0] == 0:
                return None
            lo, hi = p.min(axis=0), p.max(axis=0)
            c = np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])
            reach = float(np.sqrt(((p - c) ** 2).sum(axis=1)).max())
            return float(c[0]), float(c[1]), float(c[2]), blob_radius(hi - lo), max(reach, 1e-3)
    return None


def blob_radius(extent) -> float:
    """The blob shadow's radius of a rest pose of ``extent`` (x, y, z): :data:`BLOB_RADIUS_FACTOR` x (x + z),
    clamped to :data:`BLOB_HEIGHT_RANGE` x its height, at least 1 mm."""
    ex, ey, ez = (float(v) for v in extent)
    blob = BLOB_RADIUS_FACTOR * (ex + ez)
    if ey > 1e-6:
        blob = min(max(blob, BLOB_HEIGHT_RANGE[0] * ey), BLOB_HEIGHT_RANGE[1] * ey)
    return max(blob, 1e-3)


def blob_opacity(rho) -> np.ndarray:
    """Opacity of a blob shadow at ``rho`` (distance from its centre over its radius): ``blob.frag``'s
    :data:`BLOB_OPACITY` x (1 - smoothstep(:data:`BLOB_INNER`, 1, rho)), 0 from the rim on."""
    r = np.asarray(rho, np.float64)
    t = np.clip((r - BLOB_INNER) / (1.0 - BLOB_INNER), 0.0, 1.0)
    return BLOB_OPACITY * (1.0 - t * t * (3.0 - 2.0 * t))


def blob_instances(batches, footprints: dict) -> np.ndarray:
    """(n, 4) float32 blob of every agent drawn: camera-relative floor point and radius.

    batches : DrawBatch-like objects (``rep``, ``instance_ids``, ``instance_data`` (k, 16)); statics (ids < 0)
        and representations without a footprint are skipped; an agent in several batches (a screen-door
        transition) gets one blob. Non-finite rows are dropped.
    footprints : rep key -> :func:`footprint` tuple
    """
    rows, ids = [], []
    for b in batches:
        fp = footprints.get(b.rep)
        iid = np.asarray(b.instance_ids)
        if fp is None or iid.size == 0:
            continue
        d = np.asarray(b.instance_data, np.float64).reshape(-1, 16)
        keep = iid >= 0
        if not keep.any():
            continue
        d, iid = d[keep], iid[keep]
        m = d[:, :12].reshape(-1, 3, 4)
        floor = m[:, :, :3] @ np.array(fp[:3]) + m[:, :, 3]
        scale = np.linalg.norm(m[:, :, 0], axis=1)
        rows.append(np.concatenate([floor, (fp[3] * scale)[:, None]], axis=1))
        ids.append(iid)
    if not rows:
        return np.zeros((0, 4), np.float32)
    out, iid = np.concatenate(rows), np.concatenate(ids)
    _, first = np.unique(iid, return_index=True)
    out = out[np.sort(first)]
    return np.ascontiguousarray(out[np.isfinite(out).all(axis=1)], np.float32)


def light_basis(direction) -> np.ndarray:
    """(3, 3) rotation whose rows are the light's x, y and z axes (z = direction towards the light)."""
    z = np.asarray(direction, np.float64)
    z = z / np.linalg.norm(z)
    up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.99 else np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def fit_light_matrix(direction, centres: np.ndarray, radii: np.ndarray, texels: int,
                     origin=(0.0, 0.0, 0.0)) -> np.ndarray | None:
    """(4, 4) float64 orthographic light view-projection of camera-relative positions that holds the spheres
    (``centres`` (n, 3) camera-relative, ``radii`` (n,)) in its window and depth range, the x/y window snapped to
    whole texels of a ``texels``-wide map in world space (``origin``: the camera's world position). None when
    there is nothing finite to fit."""
    c = np.asarray(centres, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).reshape(-1)
    ok = np.isfinite(c).all(axis=1) & np.isfinite(r)
    c, r = c[ok], r[ok]
    if c.shape[0] == 0:
        return None
    R = light_basis(direction)
    q = c @ R.T
    lo, hi = (q - r[:, None]).min(axis=0), (q + r[:, None]).max(axis=0)
    side = max(float((hi[:2] - lo[:2]).max()), 1e-3) * (1.0 + 2.0 / texels)  # square window, one texel spare
    texel = side / texels
    shift = R @ np.asarray(origin, np.float64)  # light-space position of the camera (world -> camera-relative)
    mid = (lo[:2] + hi[:2]) / 2 + shift[:2]
    x0, y0 = (np.floor((mid - side / 2) / texel) * texel) - shift[:2]
    depth = max(float(hi[2] - lo[2]), 1e-3)
    P = np.zeros((4, 4))
    P[0, :3] = 2.0 * R[0] / side
    P[0, 3] = -2.0 * x0 / side - 1.0
    P[1, :3] = 2.0 * R[1] / side
    P[1, 3] = -2.0 * y0 / side - 1.0
    P[2, :3] = -2.0 * R[2] / depth  # the light-facing end (hi) is the near plane (-1)
    P[2, 3] = 2.0 * hi[2] / depth - 1.0
    P[3, 3] = 1.0
    return P if np.isfinite(P).all() else None


class Lighting:
    """Light, blob shadows and shadow map of one renderer (see the module docstring).

    Attributes set by :meth:`configure`: ``light`` (:class:`render.world.light.Light`), ``mode`` (one of
    :data:`SHADOW_MODES`), ``distance`` (metres), ``map_size`` (texels).
    """

    #: draw position among the renderer's plug-in drawers (see :meth:`draw`): after the world (-10), the clusters
    #: (0) and the compute rasteriser (``render.renderer.RASTER_ORDER``), before the points (10)
    order = 5

    def __init__(self, renderer):
        self.r = renderer
        self.ctx = renderer.ctx
        self.light = Light()
        self.mode = "none"  # the scene default (DEFAULT_SHADOWS) is set by crowd.engine; a bare renderer draws none
        self.distance = DEFAULT_SHADOW_DISTANCE
        self.map_size = DEFAULT_MAP_SIZE
        self.footprints: dict = {}
        self._objects: list = []
        self._dummy = None
        self._map = None
        self._map_fbo = None
        self._blob = None  # (program, vertex array, instance buffer, capacity)
        self._light_vp = None  # this frame's fitted matrix (None: nothing in the map)
        self._casting = False
        self._blob_kinds: set = set()  # plug-in kinds whose agents get blobs in mode "map" (_plugin_casters)
        self._params = (0.0, 0.0, 0.0)
        #: counts of the last frame: agents with a blob, blobs drawn (those that can cover a pixel,
        #: render.world.blobs.covering), casters (instances) in the map
        self.last_counts = {"blobs": 0, "blobs_drawn": 0, "casters": 0}

    def configure(self, light: Light | None = None, mode: str | None = None, distance: float | None = None,
                  map_size: int | None = None) -> None:
        """Change the light and the shadow settings (validated by the scene; checked again here)."""
        if light is not None:
            self.light = light
        if mode is not None:
            if mode not in SHADOW_MODES:
                raise ValueError(f"shadows: expected one of {SHADOW_MODES}, got {mode!r}")
            was = self.r.shadow_defines()
            self.mode = mode
            if self.r.shadow_defines() != was:  # the lit programs compile the map's lookup only in mode "map"
                self.r.reprogram()
        if distance is not None:
            if not (math.isfinite(distance) and distance > 0):
                raise ValueError(f"shadow_distance: expected a finite number > 0, got {distance!r}")
            self.distance = float(distance)
        if map_size is not None:
            limit = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
            if not 16 <= int(map_size) <= limit:
                raise ValueError(f"shadow_map_size: expected 16 ..= {limit} texels, got {map_size!r}")
            if int(map_size) != self.map_size:
                self._drop_map()
            self.map_size = int(map_size)

    # ------------------------------------------------------------------ resources
    def _track(self, obj, label: str):
        return track(self._objects, obj, label)  # render.context.track

    def _dummy_map(self):
        if self._dummy is None:
            self._dummy = self._track(self.ctx.depth_texture((1, 1), data=np.ones(1, np.float32).tobytes()),
                                      "shadows.dummy_map")
            self._dummy.compare_func = "<="
        return self._dummy

    def _ensure_map(self):
        if self._map is None:
            s = self.map_size
            self._map = self._track(self.ctx.depth_texture((s, s)), "shadows.map")
            self._map.compare_func = "<="
            self._map.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self._map.repeat_x = self._map.repeat_y = False
            self._map_fbo = self._track(self.ctx.framebuffer(depth_attachment=self._map), "shadows.map_fbo")
        return self._map_fbo

    def _drop_map(self):
        for o in (self._map_fbo, self._map):
            if o is not None:
                o.release()
                self._objects.remove(o)
        self._map = self._map_fbo = None

    def note_rep(self, rep) -> None:
        """Remember the footprint of an uploaded representation (its blob and its reach in the map fit)."""
        fp = footprint(rep)
        if fp is None:
            self.footprints.pop(rep.key, None)
        else:
            self.footprints[rep.key] = fp

    def release(self) -> None:
        """Release every GL object (reverse creation order; safe twice)."""
        release_all(self._objects)  # render.context: reverse order, each once
        self._dummy = self._map = self._map_fbo = self._blob = None

    # ------------------------------------------------------------------ uniforms
    def apply(self, prog) -> None:
        """Light uniforms, and the shadow-map uniforms of a program including ``shadow.glsl``: the map on
        :data:`SHADOW_UNIT` while this frame has one (else a 1x1 lit map and ``u_shadow_on = 0``)."""
        apply_light(prog, self.light)
        if "u_shadow_map" not in prog:
            return
        on = self._light_vp is not None and not self._casting
        (self._map if on else self._dummy_map()).use(SHADOW_UNIT)
        prog["u_shadow_map"].value = SHADOW_UNIT
        if "u_shadow_on" in prog:
            prog["u_shadow_on"].value = 1.0 if on else 0.0
        if on:
            if "u_light_vp" in prog:
                prog["u_light_vp"].write(np.ascontiguousarray(self._light_vp.T, np.float32).tobytes())
            if "u_shadow_params" in prog:
                prog["u_shadow_params"].value = self._params

    # ------------------------------------------------------------------ shadow map
    def shadow_pass(self, batches, plugin: dict, drawlist, pieces: dict, cursor, offsets: list) -> None:
        """Render this frame's shadow map (mode "map"; see the module docstring); else nothing.

        batches : the renderer's built-in batches of the frame (instance data already uploaded at ``offsets``)
        pieces, cursor : batch index -> its pieces in palette chunks, and the render.poses.palette.PaletteCursor that
            builds them (palette skinning; ``Renderer._draw_batch``)
        """
        self._light_vp = None
        self.last_counts["casters"] = 0
        if self.mode != "map":
            return
        r = self.r
        casters = [i for i, b in enumerate(batches)
                   if not b.rep.startswith(RECEIVE_ONLY) and b.rep in self.footprints]
        others = self._plugin_casters(plugin)
        centres, radii = [], []
        for b in [batches[i] for i in casters] + [b for bs in others.values() for b in bs]:
            d = np.asarray(b.instance_data, np.float64).reshape(-1, 16)
            m = d[:, :12].reshape(-1, 3, 4)
            fp = self.footprints[b.rep]
            centres.append(m[:, :, :3] @ np.array(fp[:3]) + m[:, :, 3])
            radii.append(fp[4] * np.linalg.norm(m[:, :, :3], axis=1).max(axis=1))
        if not centres:
            return
        c, rad = np.concatenate(centres), np.concatenate(radii)
        near = np.linalg.norm(c, axis=1) - rad <= self.distance  # camera-relative: the camera is at 0
        vp = fit_light_matrix(self.light.direction, c[near], rad[near], self.map_size,
                              getattr(drawlist, "origin", (0.0, 0.0, 0.0)))
        if vp is None:
            return
        ctx = self.ctx
        fbo = self._ensure_map()
        self._dummy_map().use(SHADOW_UNIT)  # never sample the map while rendering it
        fbo.use()
        ctx.viewport = (0, 0, self.map_size, self.map_size)
        fbo.clear(depth=1.0)
        ctx.polygon_offset = CASTER_POLYGON_OFFSET
        self._casting = True
        try:
            used: set = set()
            for i in casters:
                r._draw_batch(batches[i], offsets[i], vp, used, pieces.get(i), cursor)
            for k, bs in others.items():
                d = r._drawers[k]
                if not bs:
                    continue
                if hasattr(d, "cast_shadows"):
                    fbo.use()
                    d.cast_shadows(bs, drawlist, vp)
                    continue
                saved, r.fbo = r.fbo, fbo  # the cluster drawer draws into the renderer's framebuffer: the map's now
                try:
                    d.draw(bs, drawlist, vp)
                finally:
                    r.fbo = saved
                cursor.invalidate()  # it rebuilt the shared skinning palette for its instances
        finally:
            self._casting = False
            ctx.polygon_offset = (0.0, 0.0)
            r.fbo.use()
            ctx.viewport = (0, 0) + tuple(r.size)
        self.last_counts["casters"] = int(sum(batches[i].n_instances for i in casters)
                                          + sum(b.n_instances for bs in others.values() for b in bs))
        side = 2.0 / float(np.linalg.norm(vp[0, :3]))  # metres across the map
        self._params = (1.0 / self.map_size, MAP_DEPTH_BIAS, MAP_NORMAL_OFFSET_TEXELS * side / self.map_size)
        self._light_vp = vp
        self._map.use(SHADOW_UNIT)

    def _plugin_casters(self, plugin: dict) -> dict:
        """kind -> batches of the plug-in drawers that cast into the map: a drawer with ``cast_shadows(batches,
        drawlist, light_vp)`` (e.g. props), and the cluster drawer unless it runs occlusion queries (GL allows one
        samples query at a time, and the frame's is open). Also remembers which kinds get blobs instead."""
        out = {}
        for k, bs in plugin.items():
            d = self.r._drawers.get(k)
            if d is None or d is self:
                continue
            if hasattr(d, "cast_shadows") or (k == "clusters" and not getattr(d, "uses_queries", False)):
                out[k] = [b for b in bs if not b.rep.startswith(RECEIVE_ONLY) and b.rep in self.footprints]
        self._blob_kinds = {k for k in plugin if k not in out}
        return out

    # ------------------------------------------------------------------ blobs
    def draw(self, _batches, drawlist, view_proj) -> None:
        """Draw the blob shadows of this frame (see the module docstring): every agent of ``drawlist`` in mode
        "blob", the agents drawn as points or clusters in mode "map", none in mode "none".

        The renderer calls this as a plug-in drawer of :attr:`order` 5: after its own triangle batches (the
        characters in modes none and triangles, the terrain), the world's ground (``order`` -10), the clusters
        (0) and the compute rasteriser's work (``render.renderer.RASTER_ORDER``), so the blobs are depth-tested
        against the characters already drawn and no ground drawn later covers them; before the point splats
        (10), which cover them where they are nearer."""
        self.last_counts["blobs"] = self.last_counts["blobs_drawn"] = 0
        if self.mode == "none":
            return
        src = [b for b in drawlist.batches if self._blob_kind(b.rep)]
        if self.mode == "map":  # the agents of drawers that did not cast (points; clusters with occlusion culling)
            src = [b for b in src if self.r._plugin_reps.get(b.rep) in self._blob_kinds]
        blobs = blob_rows(src, self.footprints)  # blob_instances in numba (render.world.blobs)
        self.last_counts["blobs"] = blobs.shape[0]
        if not self.r.samples:  # only the quads that can cover a pixel centre (render.world.blobs.covering)
            blobs = blobs[covering(blobs, view_proj, self.r.size, BLOB_LIFT)]
        n = blobs.shape[0]
        self.last_counts["blobs_drawn"] = n
        if n == 0:
            return
        prog, vao, buf = self._blob_objects(n)
        buf.write(blobs.tobytes())
        prog["u_view_proj"].write(np.ascontiguousarray(np.asarray(view_proj, np.float64).T, np.float32).tobytes())
        prog["u_lift"].value = BLOB_LIFT
        prog["u_blob"].value = (BLOB_OPACITY, BLOB_INNER)
        ctx, fbo = self.ctx, self.r.fbo
        fbo.depth_mask = False
        fbo.use()  # moderngl applies a framebuffer's write masks when it is bound
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        ctx.polygon_offset = BLOB_POLYGON_OFFSET
        try:
            vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=n)
        finally:
            ctx.polygon_offset = (0.0, 0.0)
            ctx.disable(moderngl.BLEND)
            fbo.depth_mask = True
            fbo.use()

    def _blob_kind(self, key: str) -> bool:
        """Whether the agents of representation ``key`` may get blobs: not those of a plug-in drawer with
        ``blob_shadows = False`` (the world's props and obstacle solids: statics that cast into the map)."""
        kind = self.r._plugin_reps.get(key)
        return kind is None or getattr(self.r._drawers.get(kind), "blob_shadows", True)

    def _blob_objects(self, n: int):
        """(program, vertex array, instance buffer) of the blob draw, the buffer holding at least ``n`` blobs."""
        from render.shaders import program_sources

        if self._blob is None or self._blob[3] < n:
            cap = 1024
            while cap < n:
                cap *= 2
            if self._blob is None:
                prog = self._track(self.ctx.program(**program_sources("blob")), "shadows.blob_program")
                quad = self._track(self.ctx.buffer(np.array([-1, -1, 1, -1, -1, 1, 1, 1], np.float32).tobytes()),
                                   "shadows.blob_quad")
            else:
                prog, _, old, _, quad = self._blob
                for o in (self._blob[1], old):
                    o.release()
                    self._objects.remove(o)
            buf = self._track(self.ctx.buffer(reserve=cap * 16, dynamic=True), "shadows.blobs")
            vao = self._track(self.ctx.vertex_array(prog, [(quad, "2f", "in_corner"), (buf, "4f/i", "i_blob")]),
                              "shadows.blob_vao")
            self._blob = (prog, vao, buf, cap, quad)
        return self._blob[0], self._blob[1], self._blob[2]
