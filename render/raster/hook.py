"""The renderer's side of the compute rasteriser: which instances of the built-in triangle batches (modes
none and triangles: static, keyframed and skinned representations, LOD chain levels) it takes.

:func:`split` reorders every eligible batch so that the instances the hardware path draws come first (the
camera pass draws only those; the shadow map still draws every instance, its casters) and returns the others
as compute work (``render.raster.frame.Work``). Not eligible, drawn by the hardware as before: a renderer with
MSAA (the visibility buffer has one sample per pixel), geomorphed chain levels, batches in a screen-door
transition, and representations of other kinds.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from render.raster.frame import Work
from lod.poses.table import SLOT_FLOAT
from lod.raster_route import MAX_THRESHOLD, compute_mask, near_distance
from render.tint import batch_words


def triangle_range(g, b) -> tuple[int, int]:
    """(first triangle, triangles) batch ``b`` draws of the renderer's uploaded rep ``g``."""
    if g.kind == "keyframed":
        return int(g.seg_first[b.part]) // 3, int(g.seg_count[b.part]) // 3
    if getattr(b, "index_range", None) is not None:
        f, c = (int(v) for v in b.index_range)
        return f // 3, c // 3
    return 0, int(g.default_count) // 3


def _routing(renderer, items, drawlist):
    """(raster, threshold, proj, near distance, height) of this frame's routing, or None when the compute path
    takes nothing (switched off, threshold 0, MSAA, nothing to draw, the shadow map's pass, or a frame whose
    per-pixel buffers would pass the storage-buffer binding limit)."""
    threshold = float(renderer.raster_threshold)
    if (not renderer.compute_raster or renderer.samples or not items or threshold <= 0.0
            or getattr(renderer.lighting, "_casting", False)):  # the shadow map's pass: every caster drawn there
        return None
    raster = renderer.raster
    if not raster.fits():
        return None
    raster.threshold = min(threshold, MAX_THRESHOLD)
    proj = np.asarray(drawlist.proj, np.float64)
    return raster, raster.threshold, proj, near_distance(proj), int(renderer.size[1])


def _mask(raster, m, data, route, extent=None) -> np.ndarray:
    """(k,) bool: the copies (rows ``data``) of mesh ``m`` the compute path takes (``extent``: of the drawn
    triangles, default the whole mesh's)."""
    _, threshold, proj, near, height = route
    if raster.route_all:
        return np.ones(data.shape[0], bool)
    return compute_mask(data, m.extent if extent is None else extent, m.radius, m.centre, proj, height, threshold,
                        near)


def split(renderer, batches: list, drawlist) -> tuple[list, dict, list]:
    """(batches, hardware counts, work): the batches with each eligible one's hardware instances first, batch
    index -> how many instances the hardware draws (eligible batches only), and the compute work."""
    route = _routing(renderer, batches, drawlist)
    if route is None:
        return batches, {}, []
    raster = route[0]
    out, hw, work = list(batches), {}, []
    for i, b in enumerate(batches):
        g = renderer._reps[b.rep]
        if g.n_indices == 0 or g.kind not in ("static", "keyframed", "skinned") or getattr(g, "source", None) is None:
            continue
        if getattr(b, "morph", None) is not None or getattr(b, "fade", None) is not None:
            continue
        m = raster.mesh(g.source, g.cull, g)
        if m is None:
            continue
        data = np.asarray(b.instance_data, np.float32).reshape(-1, 16)
        first, count = triangle_range(g, b)
        mask = _mask(raster, m, data, route, m.extent_of(first, count))
        # a skinned copy reads its pose from the pose cache (none this frame: the hardware path); asked only when
        # the compute path takes a copy, and for those copies' slots only, since asking poses the mesh in them
        if not mask.any() or (g.kind == "skinned"
                              and renderer.poses.posed(b.rep, slots=data[mask, SLOT_FLOAT]) is None):
            continue
        ids = np.asarray(b.instance_ids)
        order = np.concatenate([np.flatnonzero(~mask), np.flatnonzero(mask)])
        h = int((~mask).sum())
        nb = replace(b, instance_ids=ids[order], instance_data=data[order])
        out[i] = nb
        hw[i] = h
        sub = replace(b, instance_ids=ids[mask], instance_data=data[mask])
        work.append(Work(m, data[mask], batch_words([sub], renderer.tint_table), first, count))
    return out, hw, work


def hardware_pieces(pieces, n_instances: int, h: int) -> list:
    """The (first instance, count, palette chunk, item) pieces of a batch cut to its first ``h`` instances
    (``pieces`` None: one piece of all ``n_instances``, no palette)."""
    pieces = pieces or [(0, n_instances, -1, 0)]
    out = []
    for f, k, c, j in pieces:
        k = min(k, h - f)
        if k > 0:
            out.append((f, k, c, j))
    return out


def split_world(renderer, batches: list, drawlist) -> tuple[list, list]:
    """Props and obstacle solids (the world drawer's mesh batches, ``lod.props``): (the batches the hardware
    draws, each cut to its hardware instances, batches left with none dropped; the compute work, shaded as the
    world: world_light.glsl, the batch's debug colour, no variation)."""
    route = _routing(renderer, batches, drawlist)
    if route is None:
        return batches, []
    from render.tint import debug_word

    raster = route[0]
    out, work = [], []
    for b in batches:
        rep = renderer.drawer("world")._reps[b.rep].get("rep")
        m = raster.mesh(rep, False) if rep is not None and getattr(b, "fade", None) is None else None
        data = np.asarray(b.instance_data, np.float32).reshape(-1, 16)
        if m is None:
            out.append(b)
            continue
        first, count = ((int(b.index_range[0]) // 3, int(b.index_range[1]) // 3)
                        if getattr(b, "index_range", None) is not None else (0, m.tris))
        mask = _mask(raster, m, data, route, m.extent_of(first, count))
        ids = np.asarray(b.instance_ids)
        if (~mask).any():
            out.append(replace(b, instance_ids=ids[~mask], instance_data=data[~mask]) if mask.any() else b)
        if mask.any():
            tints = np.zeros((int(mask.sum()), 2), np.uint32)
            tints[:, 1] = debug_word(getattr(b, "tint", None))
            work.append(Work(m, data[mask], tints, first, count, world=True))
    return out, work


def cluster_extents(st, m) -> np.ndarray:
    """(N,) float64 per cluster of ``st.hierarchy`` (VDR-AM): the routing summary
    (:func:`lod.raster_route.triangle_extent`'s percentile of its triangles' largest extent) over mesh ``m``'s
    bind positions; 0 for a cluster without triangles. Computed once per hierarchy (kept on ``st``)."""
    ext = getattr(st, "_raster_cluster_extents", None)
    if ext is None:
        from lod.raster_route import EXTENT_PERCENTILE

        ts = np.asarray(st.hierarchy.tri_start, np.int64)
        tris = np.asarray(st.flat, np.int64).reshape(-1, 3)
        pos = np.asarray(m.rep.positions, np.float64).reshape(-1, 3)
        c = pos[tris]
        tri_ext = (c.max(axis=1) - c.min(axis=1)).max(axis=1)
        ext = np.zeros(ts.shape[0] - 1)
        for k in range(ext.shape[0]):
            if ts[k + 1] > ts[k]:
                ext[k] = np.percentile(tri_ext[ts[k]:ts[k + 1]], EXTENT_PERCENTILE)
        st._raster_cluster_extents = ext
    return ext


def cut_extents(offsets, clusters, ext) -> np.ndarray:
    """(k,) float64 per CSR cut (rows of ``offsets``/``clusters``): the largest routing extent of its clusters
    (``ext``, :func:`cluster_extents`): a coarse cut's triangles are larger than the full mesh's, and it is
    routed by them (0 for an empty cut)."""
    offsets = np.asarray(offsets, np.int64)
    clusters = np.asarray(clusters, np.int64)
    out = np.zeros(offsets.shape[0] - 1)
    if clusters.size:
        per = ext[clusters]
        nonempty = offsets[1:] > offsets[:-1]
        out[nonempty] = np.maximum.reduceat(per, offsets[:-1][nonempty])
    return out


#: the compute path's cluster copies must draw at least this many triangles per vertex the pose cache would skin
#: for them (a full mesh in each pose they read): skinning a vertex costs about as much as drawing a triangle
#: on the hardware path on llvmpipe (~10 M vertices/s against ~8 M triangles/s), so fewer triangles are cheaper
#: drawn where they are
POSE_PAYS_TRIANGLES = 1.0


def _pose_pays(renderer, it, mesh_key: str, mask, slots) -> bool:
    """Whether posing ``it``'s full mesh for the compute path in ``slots`` (its masked copies'; nothing when
    posed this frame already) costs no more than drawing those copies' cut triangles on the hardware path."""
    cost = renderer.poses.posing_cost(it.key, mesh_key, slots=slots)
    if cost is None or cost == 0:
        return cost == 0
    from lod.clusters.cut import cut_triangle_count
    from render.clusters.cuts import _sub_csr

    tris = int(cut_triangle_count(it.st.hierarchy, *_sub_csr(it.offsets, it.clusters, np.flatnonzero(mask))).sum())
    return tris >= POSE_PAYS_TRIANGLES * cost


def split_clusters(renderer, items: list, drawlist) -> tuple[list, list]:
    """VDR-AM cluster cuts (the clusters drawer's collected items, ``render/clusters/draw.py``): (the items the
    hardware draws, their compute rows removed; the compute work: per distinct cut of the compute rows, its
    gathered triangles). Geomorphed rows, screen-door transitions and items with occlusion culling stay on
    the hardware path."""
    route = _routing(renderer, items, drawlist)
    if route is None:
        return items, []
    from types import SimpleNamespace

    from render.clusters.cuts import PALETTE_SLOT_FLOAT, _sub_csr, gather, group_cuts

    raster = route[0]
    out, work = [], []
    for it in items:
        g = it.st.skin
        src = getattr(g, "source", None)
        if (it.program != "clusters" or tuple(it.fade) != (0.0, 0.0) or it.st.occlusion or src is None
                or getattr(it, "slots", None) is None or renderer.poses.palette(it.key) is None):
            out.append(it)  # the compute path reads poses from the pose cache: none this frame, hardware path
            continue
        m = raster.mesh(src, g.cull, g)
        # each copy routed by its own cut's triangles (a coarse cut's are larger than the mesh's: routed by the
        # mesh's, coarse cuts of a far crowd went to the compute path, ~100x slower there than drawn by hardware)
        mask = _mask(raster, m, it.data, route, cut_extents(it.offsets, it.clusters, cluster_extents(it.st, m)))
        # the compute path draws a cut from the full mesh posed in its copies' poses: a pass priced before it
        # is asked for (asked first, the coarse cuts the hardware draws paid it: 4 M vertices a frame on the
        # office; a few far copies routed here paid 30-50 ms on the stampede for a hundred triangles each)
        slots = np.asarray(it.slots)[mask]
        if not mask.any() or not _pose_pays(renderer, it, src.key, mask, slots) \
                or renderer.poses.posed(it.key, src.key, slots=slots) is None:
            out.append(it)
            continue
        sub = np.flatnonzero(mask)
        offsets, clusters = _sub_csr(it.offsets, it.clusters, sub)
        order, counts, first = group_cuts(offsets, clusters)
        co = np.zeros(first.shape[0] + 1, np.int64)
        np.cumsum(offsets[first + 1] - offsets[first], out=co[1:])
        cc = _sub_csr(offsets, clusters, first)[1]
        idx, ifirst = gather(it.st.flat, it.st.hierarchy.tri_start, co, cc)
        tris = np.asarray(idx, np.uint32).reshape(-1, 3)
        starts = np.concatenate([[0], np.cumsum(counts)])
        for gi in range(counts.shape[0]):
            rows = sub[order[starts[gi]:starts[gi + 1]]]
            t = tris[ifirst[gi] // 3:ifirst[gi + 1] // 3]
            if t.shape[0]:
                work.append(Work(m, it.data[rows], it.words[rows], 0, t.shape[0], tris=t, pose_key=it.key,
                                 slots=it.slots[rows]))
        keep = np.flatnonzero(~mask)
        if keep.shape[0]:
            offsets, clusters = _sub_csr(it.offsets, it.clusters, keep)
            data = it.data[keep].copy()
            data[:, PALETTE_SLOT_FLOAT] = np.arange(keep.shape[0], dtype=np.float32)
            out.append(SimpleNamespace(**{**vars(it), "k": int(keep.shape[0]), "data": data, "words": it.words[keep],
                                          "offsets": offsets, "clusters": clusters, "ids": it.ids[keep],
                                          "part": it.part[keep], "first_row": it.first_row[keep],
                                          "slots": None if getattr(it, "slots", None) is None else it.slots[keep]}))
    return out, work
