"""Drawer of the world: the ground with its grid, obstacle solids and props.

A plug-in drawer of the renderer (``render.renderer.PLUGIN_KINDS["world"]``) for
representations of kind ``"world"`` (``lod.props``): a prop chain or the
obstacle solids (:class:`lod.props.chain.PropChainRep`: positions, normals,
colours and every level's triangles) or the ground
(:class:`lod.props.solids.GroundRep`). Batches (``lod.props.select.WorldBatch``)
name a chain level by ``index_range``; their instance data are the
camera-relative model rows of ``lod.drawlist``, gathered into one per-frame
buffer and re-bound at each batch's offset (as the renderer's own batches).

Shading lives in ``shaders/world/world_light.glsl``, shared by ``world_mesh`` (props,
solids) and ``world_ground``: the scene's directional light (``render.world.light``:
``u_light_dir``, ``u_light_color``, ``u_ambient``), its direct term multiplied by
the shadow map's visibility (``shaders/world/shadow.glsl``, ``[render] shadows = "map"``).
Every uniform of the light and the map is set by the renderer's
:class:`render.world.shadows.Lighting` (``apply``), as for the characters, so
``[render] light_*`` shades the world and the characters alike.

Shadows: the ground and the meshes receive the shadow map; the meshes cast into
it (:meth:`Drawer.cast_shadows`, called by ``Lighting.shadow_pass`` before the
frame is drawn); the ground only receives. The world gets no blob shadows
(:attr:`Drawer.blob_shadows`): blobs are the agents'. The ground is drawn first,
then the meshes, before the cluster and point drawers and the blob shadows (``order`` 5: decals on the ground),
which depth-test against them.
"""
from __future__ import annotations

import numpy as np

from lod.drawlist import INSTANCE_FLOATS
from render.context import release_all, track

#: bytes per instance in the world's instance buffer
_INSTANCE_BYTES = INSTANCE_FLOATS * 4
_INSTANCE_ATTRS = ("i_m0", "i_m1", "i_m2", "i_anim")


class Drawer:
    """Draws world representations (see the module docstring); the light is the renderer's
    (``renderer.lighting``)."""

    order = -10  # before the blob shadows, the point splats and clusters (they depth-test against the world)
    #: the world's statics get no blob shadow (render.world.shadows.Lighting.draw): they cast into the map
    blob_shadows = False

    def __init__(self, renderer):
        self.r = renderer
        self.ctx = renderer.ctx
        self._objects: list = []
        self._reps: dict = {}  # key -> dict(vao, locs, n_indices, objects) or ("ground", rep)
        self._buf = None
        self._cap = 0
        self.ground_vao = None  # one quad for every ground rep (made on the first upload of one)

    def _track(self, obj, label: str):
        return track(self._objects, obj, label)  # render.context.track

    def _forget(self, key):
        old = self._reps.pop(key, None)
        if old and "objects" in old:
            for o in reversed(old["objects"]):
                o.release()
                self._objects.remove(o)

    def upload(self, rep) -> None:
        self._forget(rep.key)
        ctx = self.ctx
        if not hasattr(rep, "indices"):  # the ground
            prog = self.r.program("world_ground")
            if self.ground_vao is None or self.ground_vao.program is not prog:  # new, or its program recompiled
                if self.ground_vao is not None:  # (render.renderer.Renderer.reprogram)
                    for o in (self.ground_vao, self._ground_vbo):
                        o.release()
                        self._objects.remove(o)
                quad = np.array([[-1, -1], [1, -1], [-1, 1], [1, 1]], np.float32)
                self._ground_vbo = vbo = self._track(ctx.buffer(quad.tobytes()), "world.ground.vbo")
                self.ground_vao = self._track(ctx.vertex_array(prog, [(vbo, "2f", "in_corner")]), "world.ground.vao")
            self._reps[rep.key] = {"ground": rep}
            return
        prog = self.r.program("world_mesh")
        objs = []

        def buf(a, label):
            data = np.ascontiguousarray(a).tobytes()
            b = ctx.buffer(data) if data else ctx.buffer(reserve=16)
            b.label = f"{rep.key}.{label}"
            objs.append(b)
            self._objects.append(b)
            return b

        for name in ("positions", "normals", "colors"):
            a = np.asarray(getattr(rep, name))
            if not np.isfinite(a).all():
                raise ValueError(f"world representation {rep.key!r}: {name} hold NaN or Inf")
        content = [(buf(np.asarray(rep.positions, np.float32), "positions"), "3f", "in_position"),
                   (buf(np.asarray(rep.normals, np.float32), "normals"), "3f", "in_normal"),
                   (buf(np.asarray(rep.colors, np.float32), "colors"), "4f", "in_color")]
        content = [c for c in content if c[2] in prog]
        ibo = buf(np.asarray(rep.indices, np.uint32), "indices")
        vao = ctx.vertex_array(prog, content, index_buffer=ibo, index_element_size=4)
        vao.label = f"{rep.key}.vao"
        objs.append(vao)
        self._objects.append(vao)
        locs = {a: prog[a].location for a in _INSTANCE_ATTRS if a in prog}
        self._reps[rep.key] = {"vao": vao, "locs": locs, "n_indices": int(np.asarray(rep.indices).size),
                               "objects": objs, "rep": rep}  # rep: the compute rasteriser reads its arrays

    def _uniforms(self, prog, view_proj):
        """View-projection, and the scene's light and shadow-map uniforms (``renderer.lighting.apply``)."""
        prog["u_view_proj"].write(np.ascontiguousarray(np.asarray(view_proj, np.float64).T, np.float32).tobytes())
        self.r.lighting.apply(prog)

    def _meshes(self, batches) -> list:
        return [b for b in batches if b.rep in self._reps and "vao" in self._reps[b.rep]]

    def draw(self, batches, drawlist, view_proj) -> None:
        ctx = self.ctx
        ground = [b for b in batches if "ground" in self._reps.get(b.rep, {})]
        for b in ground:
            rep = self._reps[b.rep]["ground"]
            d = np.asarray(b.instance_data, np.float64).reshape(-1, INSTANCE_FLOATS)[0]
            prog = self.r.program("world_ground")
            self._uniforms(prog, view_proj)
            prog["u_extent"].value = float(d[12])
            prog["u_plane_y"].value = float(d[7])
            # phase (camera xz mod 100 at selection) minus the translation a re-framed (frozen) selection
            # adds (crowd.fly.reframe): the grid stays put in the world when the camera moves
            if "u_grid_phase" in prog:
                prog["u_grid_phase"].value = (float(d[13] - d[3]), float(d[14] - d[11]))
            prog["u_ground_color"].value = tuple(float(c) for c in rep.color)
            self.ground_vao.render(ctx.TRIANGLE_STRIP, vertices=4)
        # small props and solids to the compute rasteriser (render/raster/hook.py; drawn after the plug-ins)
        from render.raster.hook import split_world

        meshes, work = split_world(self.r, self._meshes(batches), drawlist)
        self.r.raster_work.extend(work)
        self._draw_meshes(meshes, view_proj, tinted=True)

    def cast_shadows(self, batches, drawlist, light_vp) -> None:
        """Draw the depth of the props and obstacle solids of ``batches`` with the light's view-projection
        ``light_vp`` (camera-relative positions, as the camera pass) into the bound shadow-map framebuffer
        (``render.world.shadows.Lighting.shadow_pass``, which sets the polygon offset). The ground never casts."""
        self._draw_meshes(self._meshes(batches), light_vp, tinted=False)

    def _draw_meshes(self, meshes, view_proj, tinted: bool) -> None:
        if not meshes:
            return
        ctx = self.ctx
        data = np.concatenate([np.asarray(b.instance_data, np.float32).reshape(-1, INSTANCE_FLOATS)
                               for b in meshes])
        if not np.isfinite(data).all():
            raise FloatingPointError("world batches: instance data hold NaN or Inf")
        if data.nbytes > self._cap:
            if self._buf is not None:
                self._buf.release()
                self._objects.remove(self._buf)
            self._cap = max(data.nbytes, 2 * self._cap, 64 * _INSTANCE_BYTES)
            self._buf = self._track(ctx.buffer(reserve=self._cap, dynamic=True), "world.instances")
        self._buf.orphan(self._cap)
        self._buf.write(data.tobytes())
        prog = self.r.program("world_mesh")
        self._uniforms(prog, view_proj)
        offset = 0
        for b in meshes:
            g = self._reps[b.rep]
            tint = getattr(b, "tint", None) if tinted else None
            prog["u_tint"].value = tuple(float(c) for c in tint) if tint is not None else (0.0, 0.0, 0.0, 0.0)
            for i, name in enumerate(_INSTANCE_ATTRS):
                loc = g["locs"].get(name)
                if loc is not None:
                    g["vao"].bind(loc, "f", self._buf, "4f", offset=offset + 16 * i, stride=_INSTANCE_BYTES,
                                  divisor=1)
            first, count = b.index_range if b.index_range is not None else (0, g["n_indices"])
            if not (0 <= first and 0 <= count and first + count <= g["n_indices"]):
                raise ValueError(f"world batch {b.rep!r}: index_range {b.index_range} outside the "
                                 f"{g['n_indices']} indices of the representation")
            g["vao"].render(ctx.TRIANGLES, vertices=int(count), first=int(first), instances=b.n_instances)
            offset += b.n_instances * _INSTANCE_BYTES

    def release(self) -> None:
        release_all(self._objects)  # render.context: reverse order, each once
        self._reps.clear()
        self.ground_vao, self._buf, self._cap = None, None, 0
