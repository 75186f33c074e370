"""The renderer's draws of skinned batches from the pose cache (``render/poses/cache.py``; moved out of
``render/renderer.py``): the vertex arrays of the pose-sharing programs and the draw of a batch's copies from
the posed vertices (``shaders/poses/posed.vert``, one draw per run of copies whose slots lie in one window) or from
the pose palettes (the skinned programs' ``POSE_SLOT`` variants)."""
from __future__ import annotations

from lod.drawlist import INSTANCE_FLOATS
from lod.poses.table import SLOT_FLOAT

#: bytes per instance in the renderer's instance buffer
INSTANCE_BYTES = INSTANCE_FLOATS * 4
#: the renderer's per-copy attributes (render/renderer.py _DRAW_ATTRS)
_DRAW_ATTRS = ("i_m0", "i_m1", "i_m2", "i_anim", "i_tint")


def morph_vao(r, g, extra: tuple = ()) -> tuple:
    """(vertex array, instance locations) of the geomorph program of renderer ``r``'s LOD chain rep ``g``
    (compiled with the ``extra`` defines too), its collapse tables bound to their texture units (made on first
    use; ``render/clusters/morph.py``)."""
    from render.clusters.morph import MORPH_FLOAT_UNIT, MORPH_INT_UNIT, morph_textures

    if extra not in g.morph:
        if g.morph_source is None:
            raise ValueError(f"DrawBatch of {g.key!r} asks for a geomorph, but the representation has no "
                             f"vertex collapses (a lod.chains.mode chain built with them)")
        src = g.morph_source
        prog = r.program("skinned_direct_morph" if r.skinning == "direct" else "skinned_morph",
                         defines=g.defines + tuple(extra))
        vao = r.ctx.vertex_array(prog, [c for c in g.content if c[2] in prog], index_buffer=g.vao.index_buffer,
                                 index_element_size=4)
        vao.label = f"{g.key}.morph_vao"
        have = next(iter(g.morph.values()), None)
        tex = have[2] if have is not None else morph_textures(r.ctx, src.collapse_next, src.collapse_level, src,
                                                              g.key, r.packed_vertices)
        new = [vao] if have is not None else [vao, *tex]
        g.objects.extend(new)
        r._objects.extend(new)
        g.morph[extra] = (vao, {a: prog[a].location for a in _DRAW_ATTRS if a in prog}, tex)
    vao, locs, (ti, tf) = g.morph[extra]
    ti.use(MORPH_INT_UNIT)
    tf.use(MORPH_FLOAT_UNIT)
    vao.program["u_morph_i"].value = MORPH_INT_UNIT
    vao.program["u_morph_f"].value = MORPH_FLOAT_UNIT
    return vao, locs


def pose_vao(r, g, how: str, morph: bool) -> tuple:
    """(vertex array, instance locations) drawing ``g`` from the pose cache: ``"posed"``, the posed
    vertices (``shaders/poses/posed.vert``: colours from the rep's buffer, positions and normals from the pose's
    slot); ``"palette"``, the skinned program reading the pose palettes by slot (``POSE_SLOT``), the
    geomorph one for a geomorphed chain level. Made on first use."""
    if how == "palette" and morph:
        return morph_vao(r, g, ("POSE_SLOT",))
    if how not in g.pose_vaos:
        from render.shaders import prog_name

        prog = r.program("posed") if how == "posed" else \
            r.program(prog_name(g.kind, r.skinning), defines=g.defines + ("POSE_SLOT",))
        vao = r.ctx.vertex_array(prog, [c for c in g.content if c[2] in prog], index_buffer=g.vao.index_buffer,
                                 index_element_size=4)
        vao.label = f"{g.key}.vao_{how}"
        g.objects.append(vao)
        r._objects.append(vao)
        g.pose_vaos[how] = (vao, {a: prog[a].location for a in _DRAW_ATTRS if a in prog})
    return g.pose_vaos[how]


def draw_shared(r, g, prog, vao, locs, shared, b, offset: int, count: int, first: int, pieces=None) -> None:
    """Draw the copies of batch ``b`` (those of ``pieces``, (first instance, count, ...) each; default all)
    from the pose cache: ``shared`` = ``("posed", PosedVertices)`` (one draw per run of copies in one
    window) or ``("palette", PosePalette)``."""
    how, src = shared
    if how == "palette":
        src.use(prog)
        if g.joints is not None:
            g.joints.use(0)  # its row count bounds the frame pairs of the morph weights (targets.glsl)
    (r.ctx.enable if g.cull else r.ctx.disable)(r.ctx.CULL_FACE)  # single-sided reps
    slots = b.instance_data[:, SLOT_FLOAT]
    for f0, k0 in [(p[0], p[1]) for p in pieces] if pieces else [(0, b.n_instances)]:
        for f, k, w in src.runs(slots, f0, k0) if how == "posed" else [(f0, k0, None)]:
            if w is not None:
                src.bind(w, prog)
            off = offset + f * INSTANCE_BYTES
            r._bind_instances(vao, locs, r._instances, off)
            r._render_instanced(g, prog, None, off, count, first, k, vao, locs)
