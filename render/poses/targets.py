"""GPU tables of the morph targets of skinned representations (glTF 2.0 §3.7.2.2).

A :class:`lod.full.targets.TargetTable` becomes three textures that
``shaders/poses/targets.glsl`` reads in the ``MORPH_TARGETS`` variants of the skinned
programs (palette, direct, and the geomorphed chain levels), where every vertex
is moved by its targets before it is skinned (``skin ∘ morph``):

- ``index`` (RG32I, :data:`TARGETS_WIDTH` wide): per vertex its first sparse
  entry and entry count;
- ``delta`` (RGBA32F, :data:`TARGETS_WIDTH` wide): per entry two texels,
  (position delta, target column) and (normal delta, 0);
- ``weight`` (R32F, targets x baked frames): ``weight - default weight`` of every
  kept target at every row of the joint table, blended between the two rows
  around the instance's frame coordinate like the joint matrices.

Memory: 32 bytes per (vertex, target) pair with a non-zero delta, 8 bytes per
vertex and 4 bytes per target and baked frame (rows padded to the width);
characters without animated targets have no table and draw the plain skinned
program (no texture, no extra shader work).
"""
from __future__ import annotations

import moderngl
import numpy as np

#: texture units of the target tables (0, 1: joint table and palette; 2, 3: geomorph tables)
TARGETS_INDEX_UNIT = 4
TARGETS_DELTA_UNIT = 5
TARGETS_WEIGHT_UNIT = 6
#: width of the index and delta textures (``targets.glsl`` addresses texel t at (t & 4095, t >> 12))
TARGETS_WIDTH = 4096
#: the preprocessor name of the shader variants with morph targets
TARGETS_DEFINE = "MORPH_TARGETS"


def _rows(ctx, arr: np.ndarray, components: int, dtype: str, label: str):
    W = TARGETS_WIDTH
    flat = np.ascontiguousarray(arr).reshape(-1, components)
    rows = max(1, -(-flat.shape[0] // W))
    limit = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
    if rows > limit:
        raise ValueError(f"{label}: {flat.shape[0]} texels need {rows} rows of {W}, above the GL limit {limit}")
    full = np.zeros((rows * W, components), flat.dtype)
    full[:flat.shape[0]] = flat
    tex = ctx.texture((W, rows), components, full.tobytes(), dtype=dtype)
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    tex.label = label
    return tex


def target_textures(ctx, table, n_frames: int, label: str) -> tuple:
    """(index, delta, weight) textures of a ``lod.full.targets.TargetTable``.

    n_frames : rows of the representation's joint table (the weight table must match)
    label : prefix of the GL labels. Raises ValueError for tables beyond the GL limits
    or non-finite values (nothing non-finite reaches the GPU).
    """
    w = np.ascontiguousarray(table.weights, np.float32)
    M = int(w.shape[1])
    limit = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
    if w.shape[0] != int(n_frames):
        raise ValueError(f"{label}: morph weights have {w.shape[0]} rows, the joint table {n_frames} frames")
    if M > limit or w.shape[0] > limit:
        raise ValueError(f"{label}: {M} morph targets x {w.shape[0]} frames exceed the GL texture limit {limit}")
    if M >= 1 << 24:  # the column is stored in a float texel
        raise ValueError(f"{label}: {M} morph targets, at most {1 << 24}")
    index = np.stack([np.asarray(table.first, np.int32), np.asarray(table.count, np.int32)], axis=1)
    delta = np.zeros((table.n_entries, 2, 4), np.float32)
    delta[:, 0, :3] = table.dpos
    delta[:, 0, 3] = np.asarray(table.column, np.float32)
    delta[:, 1, :3] = table.dnrm
    if not (np.isfinite(w).all() and np.isfinite(delta).all()):
        raise ValueError(f"{label}: morph targets hold NaN or Inf")
    ti = _rows(ctx, index, 2, "i4", f"{label}.targets_index")
    td = _rows(ctx, delta, 4, "f4", f"{label}.targets_delta")
    tw = ctx.texture((M, w.shape[0]), 1, w.tobytes(), dtype="f4")
    tw.filter = (moderngl.NEAREST, moderngl.NEAREST)
    tw.label = f"{label}.targets_weight"
    return ti, td, tw


def use_targets(prog, textures) -> None:
    """Bind a rep's target textures to their units and point ``prog``'s samplers at
    them; nothing when ``textures`` is None (a rep without morph targets)."""
    if textures is None:
        return
    for tex, unit, name in zip(textures, (TARGETS_INDEX_UNIT, TARGETS_DELTA_UNIT, TARGETS_WEIGHT_UNIT),
                               ("u_targets_index", "u_targets_delta", "u_targets_weight")):
        tex.use(unit)
        if name in prog:
            prog[name].value = unit
