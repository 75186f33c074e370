"""Posed vertices of skinned instances for the compute rasteriser: the adapter that stands for the pose cache.

Until the pose cache (lod/pose_table.py, render/pose_cache.py: each distinct pose skinned once into a
[slot][vertex] table) lands, every skinned instance the compute path draws is its own pose slot: a compute
pass (``shaders/raster_pose.glsl``) skins its vertices from the representation's baked joint table at the
instance's frame coordinate, as ``skinned_direct.vert`` does (morph targets first), into the posed table that
the rasteriser's vertex and shading passes read (``shaders/raster_common.glsl``).
"""
from __future__ import annotations

import numpy as np

from render.raster import tables as tb


def skin_table(ctx, rep, track):
    """RGBA32UI texture of a skinned rep's joints and weights, 2 texels per vertex (weights as float bits)."""
    j = np.asarray(rep.joints, np.uint32).reshape(-1, 4)
    w = tb._bits(np.asarray(rep.weights, np.float32).reshape(-1, 4))
    data = np.stack([j, w], axis=1).reshape(-1, 4)
    rows = tb.rows_for(data.shape[0])
    full = np.zeros((rows * tb.WIDTH, 4), np.uint32)
    full[:data.shape[0]] = data
    import moderngl

    tex = track(ctx.texture((tb.WIDTH, rows), 4, full.tobytes(), dtype="u4"), f"raster.{rep.key}.skin")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex


def pose_slots(posed, mesh, frame, vfirst, vcount, share: bool = True) -> tuple:
    """Pose slots of a window's instances: (first posed vertex of each instance (its slot's base: the slot
    holds the instance's vertex range), posed vertices per slot (k,) with 0 for all but the first instance of a
    slot, the instances that represent the slots). Instances of one mesh at the very same frame coordinate and
    vertex range share a slot (``share`` False: every instance its own slot); ``posed`` (k,) bool marks the
    skinned instances."""
    k = posed.shape[0]
    base = np.zeros(k, np.int64)
    n = np.zeros(k, np.int64)
    sel = np.flatnonzero(posed)
    if not sel.shape[0]:
        return base, n, sel
    key = np.stack([np.asarray(mesh, np.int64)[sel], np.ascontiguousarray(frame, np.float32)[sel].view(np.uint32),
                    np.asarray(vfirst, np.int64)[sel], np.asarray(vcount, np.int64)[sel]]
                   + ([] if share else [sel]), 1)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    reps = sel[np.sort(first)]
    order = np.argsort(np.argsort(first))  # unique rows in order of first appearance
    sizes = np.asarray(vcount, np.int64)[reps]
    starts = np.zeros(reps.shape[0], np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    base[sel] = starts[order[inv]]
    n[reps] = sizes
    return base, n, reps


def pose_pass(raster, meshes, wi, rows, vcount, vfirst, reps) -> None:
    """Skin the window's pose slots (``reps``: the instance standing for each slot, its record naming the
    slot) into the posed table, one dispatch per mesh."""
    from render.raster.frame import UNITS, VERTEX_JOB, VERTS_PER_THREAD, _vertex_jobs
    from render.targets import TARGETS_DEFINE, use_targets

    raster.posed_table.texture.bind_to_image(1, read=False, write=True)
    frame = np.ascontiguousarray(rows[:, 12], np.float32).view(np.uint32)
    for b in np.unique(wi[reps]):
        m = meshes[b]
        sel = reps[wi[reps] == b]
        jobs = _vertex_jobs(vcount[sel], vfirst[sel])
        jobs[:, 3] = frame[sel][jobs[:, 0]]
        jobs[:, 0] = sel[jobs[:, 0]]
        skin, joints, targets = m.skin
        cs = raster._compute("raster_pose", (f"RS_VERTS_PER_THREAD {VERTS_PER_THREAD}",)
                             + ((TARGETS_DEFINE,) if targets is not None else ()))
        raster._samplers(cs)
        joints.use(0)
        cs["u_joints"].value = 0
        skin.use(UNITS["u_skin"])
        use_targets(cs, targets)
        cs["u_njobs"].value = int(jobs.shape[0])
        raster._buffer("pose_jobs", jobs).bind_to_storage_buffer(5)
        raster._dispatch(cs, int(jobs.shape[0]))
    raster.ctx.memory_barrier()
    assert VERTEX_JOB == 8 * VERTS_PER_THREAD
