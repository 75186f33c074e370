"""GPU tables of geomorphs: the collapse chains the morph shaders follow (``shaders/clusters/morph.glsl``).

A geomorph draws a fine representation with every vertex blended towards the
vertex it has become in a coarser one: a VDR-AM cluster's ancestor
(:mod:`lod.clusters.morph`, drawn by ``shaders/clusters/clusters_morph.vert``) or a
later level of a discrete LOD chain (:mod:`lod.chains.mode`,
``shaders/poses/skinned_morph.vert`` / ``skinned_direct_morph.vert``). Both collapse
onto existing vertices, so one table per character serves every pair of
representations: per vertex, the vertex it collapses onto and the height (or
level) at which that happens, plus the vertex's bind-pose attributes and skin
for the shader to skin the target like the vertex itself (Friedrich, Polthier
& Schmies §3: the in-between frames interpolate vertex positions).
"""
from __future__ import annotations

import moderngl
import numpy as np

from render.vertex_format import PACKED_VERTICES, drawn

#: texture units of the geomorph tables (0 and 1 hold the joint table and the skinning palette)
MORPH_INT_UNIT = 2
MORPH_FLOAT_UNIT = 3
#: width of the geomorph textures (``morph.glsl`` addresses texel t at (t & 4095, t >> 12))
MORPH_TEXTURE_WIDTH = 4096


def morph_textures(ctx, nxt: np.ndarray, removed_at: np.ndarray, skinned, label: str,
                   packed: bool = PACKED_VERTICES) -> tuple:
    """The two textures ``shaders/clusters/morph.glsl`` reads, width :data:`MORPH_TEXTURE_WIDTH`.

    Parameters
    ----------
    ctx : moderngl.Context
    nxt, removed_at : (V,) int32 collapse chains (:func:`lod.clusters.morph.collapse_table`,
        ``TrianglesRep.collapse_next`` / ``collapse_level``)
    skinned : the character's ``lod.full.reps.SkinnedRep`` (positions, normals, colours, joints, weights)
    label : prefix of the textures' GL labels
    packed : the vertex attributes are packed (render/vertex_format.py): the targets' normals, colours
        and weights then hold the very values the vertex shader reads for a vertex

    Returns
    -------
    (integer texture, float texture): RGBA32I, 2 texels per vertex: (next vertex, removed-at
    height or level, 0, 0) and the joints; RGBA32F, 4 texels per vertex: position, normal,
    colour, weights.
    """
    V = int(np.asarray(nxt).shape[0])
    W = MORPH_TEXTURE_WIDTH
    ti = np.zeros((V, 2, 4), np.int32)
    ti[:, 0, 0] = nxt
    ti[:, 0, 1] = removed_at
    ti[:, 1, :] = np.asarray(skinned.joints, np.int64)[:V]
    tf = np.zeros((V, 4, 4), np.float32)
    tf[:, 0, :3] = np.asarray(skinned.positions)[:V]
    tf[:, 0, 3] = 1.0
    tf[:, 1, :3] = drawn(np.asarray(skinned.normals)[:V], 3, packed)
    tf[:, 2, :] = drawn(np.asarray(skinned.colors)[:V], 4, packed)
    tf[:, 3, :] = drawn(np.asarray(skinned.weights)[:V], 4, packed)
    out = []
    for arr, dtype in ((ti.reshape(-1, 4), "i4"), (tf.reshape(-1, 4), "f4")):
        rows = max(1, -(-arr.shape[0] // W))
        if rows > int(ctx.info["GL_MAX_TEXTURE_SIZE"]):
            raise ValueError(f"{label}: {V} vertices need a {W} x {rows} geomorph table, above the GL limit")
        full = np.zeros((rows * W, 4), arr.dtype)
        full[:arr.shape[0]] = arr
        tex = ctx.texture((W, rows), 4, full.tobytes(), dtype=dtype)
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.label = f"{label}.morph_{'int' if dtype == 'i4' else 'float'}"
        out.append(tex)
    return tuple(out)
