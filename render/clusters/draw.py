"""Drawer of ``"clusters"`` representations: per-instance cuts of VDR-AM cluster
hierarchies (Claudio, Kim, Kim, Yoon, *VDR-AM*, §3.1, §5.1), skinned on the GPU.

GPU resources per character (:class:`lod.clusters.mode.ClustersRep`):

- the character's full-detail skinned representation, uploaded through the
  renderer's own path (vertex buffers, the baked joint-table texture, the
  palette pre-pass), so clusters skin exactly like the full-detail mesh;
- the index buffer of the whole hierarchy (every cluster's triangles, indexing
  the original vertex buffer);
- a vertex array of the ``clusters`` program (``shaders/clusters/clusters.vert``: the
  palette skinning of ``skinned.vert`` with the palette slot taken from the
  instance data, since multi-draw commands start at a base instance).

Per frame, the instances of one character (all its clips) are grouped by
identical cut and sorted so that every group is a contiguous instance range;
the skinning palette is built for all of them (the renderer's pre-pass, in
chunks that fit the palette texture: ``render/poses/palette.py``);
then ONE ``glMultiDrawElementsIndirect`` (moderngl ``render_indirect``) per
character draws every group instanced. Two command layouts
(``Drawer.strategy``):

- ``"indices"`` (default): the triangles of each distinct cut are gathered on
  the CPU (numba) into a per-frame index buffer; one command per distinct cut.
- ``"ranges"``: no per-frame index data; one command per run of consecutive
  clusters of a distinct cut, pointing into the hierarchy's index buffer.

``scripts/bench_clusters.py --strategy`` compares them.

Occlusion culling (§5.2, when the representation asks for it): the previous
frame's potentially visible set is drawn first as occluders, the other
instances are tested with GL samples-passed queries on boxes that hold every
pose they can be drawn in, the visible ones are drawn and join the set, and
every ``occlusion_every`` frames the set is rebuilt front to back. Departure
from the paper: the query unit is an instance (its whole cut), not each
cluster of the cut -- on llvmpipe a query costs a draw call and a round trip,
so per-cluster queries (100+ per instance) would cost more than they save.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np

from lod.clusters.morph import collapse_table
from lod.drawlist import INSTANCE_FLOATS, fade_uniform
from render.clusters.cuts import (  # noqa: F401 (re-exported: the drawer's CPU side)
    PALETTE_SLOT_FLOAT,
    _cut_arrays,
    _gather_kernel,
    _range_kernel,
    _slice_item,
    _sub_csr,
    gather,
    gather_numpy,
    group_cuts,
    range_commands,
    range_commands_numpy,
    split_morph_rows,
)
from render.clusters.morph import MORPH_FLOAT_UNIT, MORPH_INT_UNIT, morph_textures
from render.tint import TintStream, instance_words

#: bytes of one DrawElementsIndirectCommand (count, instanceCount, firstIndex, baseVertex, baseInstance)
COMMAND_BYTES = 20
#: command layouts (module docstring)
STRATEGIES = ("indices", "ranges")
#: floats of a geomorphed row's instance data: height of the ancestor its vertices blend towards (i_anim.z,
#: negative = none) and the blend weight (i_anim.w); ``shaders/clusters/clusters_morph.vert``
MORPH_HEIGHT_FLOAT = 14
MORPH_WEIGHT_FLOAT = 15
#: occlusion culling: a camera closer to an instance's box than this many
#: near-plane distances draws the instance without a query (the box could be clipped)
OCCLUSION_NEAR_MARGIN = 2.0
#: occlusion culling: instances drawn untested when the visible set is rebuilt (at least)
OCCLUSION_FIRST_CHUNK = 16


# ---------------------------------------------------------------------------- GPU side
@dataclass
class _ClusterGpu:
    key: str
    skin: object  # the renderer's _GpuRep of the skinned vertex buffer
    hierarchy: object
    flat: np.ndarray
    ibo: object  # the hierarchy's index buffer ("ranges" commands point into it)
    skinned: object = None  # the lod.full.reps.SkinnedRep (vertex arrays of the geomorph textures)
    objects: list = field(default_factory=list)
    content: list = field(default_factory=list)  # the skinned vertex buffers (buffer, format, attribute)
    occlusion: bool = False
    occlusion_every: int = 8
    clip_aabb: np.ndarray | None = None  # (C, 2, 3) model-space bounds of each clip over all baked frames
    vaos: dict = field(default_factory=dict)  # (program, per-frame indices?) -> (vao, its index buffer, locations)
    morph_tex: tuple | None = None  # (integer texture, float texture) of the geomorph chains, made on first use


class Drawer:
    """Plug-in drawer of ``"clusters"`` representations (``render.renderer.PLUGIN_KINDS``).

    Attributes
    ----------
    order : 0 (opaque triangles, before point splats)
    strategy : "indices" or "ranges" (module docstring)
    last_stats : dict of the last draw: "commands", "draws", "groups"
        (distinct cuts), "instances" (drawn), "triangles", "index_bytes"
        (per-frame index data uploaded), "queries" and "occluded" (§5.2)
    """

    order = 0

    def __init__(self, renderer, strategy: str = "indices"):
        if strategy not in STRATEGIES:
            raise ValueError(f"clusters Drawer strategy: expected one of {STRATEGIES}, got {strategy!r}")
        self.renderer = renderer
        self.ctx = renderer.ctx
        self.strategy = strategy
        self._reps: dict = {}
        self._objects: list = [TintStream(self.ctx, "clusters.instance_tints")]
        self._tints = self._objects[0]  # colour words beside _inst (render/tint.py)
        self._inst = None
        self._inst_cap = 0
        self._ind = None
        self._ind_cap = 0
        self._ibo = None
        self._ibo_cap = 0
        self._pal = None
        self._pal_cap = 0
        self._box = None
        self._box_cap = 0
        self._box_vao = None
        self._box_vao_buffer = None
        self._queries: list = []
        self._pvs: dict = {}  # rep key -> agent ids of the potentially visible set (§5.2)
        self._near = 0.1
        #: frames drawn (drives the rebuild of the occlusion PVS every ``occlusion_every`` frames)
        self.frame = 0
        self.last_stats: dict = {}

    # ------------------------------------------------------------------ resources
    def _grow(self, attr: str, nbytes: int, label: str):
        cap = getattr(self, attr + "_cap")
        buf = getattr(self, attr)
        if buf is not None and nbytes <= cap:
            return buf
        cap = max(4096, cap)
        while cap < nbytes:
            cap *= 2
        if buf is not None:
            buf.release()
            self._objects.remove(buf)
        buf = self.ctx.buffer(reserve=cap, dynamic=True)
        buf.label = label
        self._objects.append(buf)
        setattr(self, attr, buf)
        setattr(self, attr + "_cap", cap)
        return buf

    @property
    def uses_queries(self) -> bool:
        """True when a representation asks for occlusion culling: the renderer then
        calls :meth:`draw` outside its own samples query (GL allows one at a time)."""
        return any(st.occlusion for st in self._reps.values())

    def set_occlusion(self, on: bool) -> None:
        """Occlusion culling (VDR-AM §5.2) on or off for every uploaded representation
        (the fly-through's live toggle). A visible set left from before only orders the
        draws: every instance outside it is still tested, so nothing visible is lost."""
        for st in self._reps.values():
            st.occlusion = bool(on)

    def upload(self, rep) -> None:
        """GPU resources of a :class:`lod.clusters.mode.ClustersRep` (re-upload replaces)."""
        old = self._reps.pop(rep.key, None)
        if old is not None:
            self._release_rep(old)
        r = self.renderer
        skin_key = f"{rep.key}#skin"
        r.upload(replace(rep.skinned, key=skin_key))
        g = r._reps[skin_key]
        h = rep.hierarchy
        flat = np.ascontiguousarray(np.asarray(h.indices).reshape(-1))
        ibo = self.ctx.buffer(flat.tobytes() if flat.size else bytes(16))
        ibo.label = f"{rep.key}.cluster_indices"
        st = _ClusterGpu(rep.key, g, h, flat, ibo, skinned=rep.skinned, objects=[ibo], content=list(g.content),
                         occlusion=bool(getattr(rep, "occlusion", False)),
                         occlusion_every=int(getattr(rep, "occlusion_every", 8)),
                         clip_aabb=np.asarray(rep.skinned.clip_aabb, np.float64))
        self._reps[rep.key] = st

    def _vao(self, st: _ClusterGpu, program: str):
        """Vertex array of ``program`` over the character's vertex buffers, indexed by the
        hierarchy's index buffer ("ranges") or this frame's gathered one ("indices"), with the
        program's instanced attribute locations."""
        prog = self.renderer.program(program)
        frame = self.strategy == "indices"
        ibo = self._ibo if frame else st.ibo
        key = (program, frame)
        have = st.vaos.get(key)
        if have is not None and have[1] is ibo:
            return have[0], have[2]
        if have is not None:
            have[0].release()
            st.objects.remove(have[0])
        es = 4 if frame else st.flat.dtype.itemsize
        vao = self.ctx.vertex_array(prog, [c for c in st.content if c[2] in prog], index_buffer=ibo,
                                    index_element_size=es)
        vao.label = f"{st.key}.vao_{program}_{'frame' if frame else 'ranges'}"
        locs = {a: prog[a].location for a in ("i_m0", "i_m1", "i_m2", "i_anim", "i_tint") if a in prog}
        st.vaos[key] = (vao, ibo, locs)
        st.objects.append(vao)
        return vao, locs

    def _morph_textures(self, st: _ClusterGpu) -> tuple:
        """(integer, float) textures of the geomorph chains (``shaders/clusters/clusters_morph.vert``):
        per vertex (next vertex, removed-at height), joints / position, normal, colour, weights."""
        if st.morph_tex is None:
            st.morph_tex = morph_textures(self.ctx, *collapse_table(st.hierarchy), st.skinned, st.key,
                                          self.renderer.packed_vertices)
            st.objects.extend(st.morph_tex)
        return st.morph_tex

    def _release_rep(self, st: _ClusterGpu) -> None:
        for o in reversed(st.objects):
            o.release()
        st.objects.clear()

    def release(self) -> None:
        """Release this drawer's GL objects (the skinned vertex buffers belong to the renderer)."""
        for st in self._reps.values():
            self._release_rep(st)
        self._reps.clear()
        for o in reversed(self._objects):
            o.release()
        self._objects.clear()
        self._queries.clear()  # moderngl queries have no release(); the context owns them
        self._inst = self._ind = self._ibo = self._pal = self._box = self._box_vao = None
        self._inst_cap = self._ind_cap = self._ibo_cap = self._pal_cap = self._box_cap = 0

    # ------------------------------------------------------------------ drawing
    def _collect(self, batches) -> list:
        """Per (representation, tint, fade, geomorph or not): instance data (palette slot set), CSR
        cuts, agent ids, clips. A geomorphed batch's instances are split into one row per (morph
        height, weight) of their union entries (:func:`split_morph_rows`), each a copy of the
        instance's data with ``i_anim.z`` = height and ``i_anim.w`` = weight."""
        groups: dict = {}
        for b in batches:
            if b.rep not in self._reps:
                raise KeyError(f"DrawList batch names clusters representation {b.rep!r}, which was not uploaded; "
                               f"uploaded: {sorted(self._reps)}")
            tint = tuple(float(c) for c in b.tint) if b.tint is not None else (0.0, 0.0, 0.0, 0.0)
            fade = fade_uniform(getattr(b, "fade", None))  # screen-door transition (lod.temporal.selection)
            morph = getattr(b, "morph_height", None) is not None
            groups.setdefault((b.rep, tint, fade, morph), []).append(b)
        items = []
        for (key, tint, fade, morph), bs in groups.items():
            st = self._reps[key]
            n_leaves = st.hierarchy.n_leaves
            offs, cls, data, ids, part, first = [], [], [], [], [], []
            base = 0
            for b in bs:
                o, c = _cut_arrays(b, n_leaves)
                d = np.asarray(b.instance_data, np.float32).reshape(-1, INSTANCE_FLOATS)
                i = np.asarray(b.instance_ids, np.int64)
                p = np.full(b.n_instances, int(b.part), np.int64)
                f = np.ones(b.n_instances, bool)
                if morph:
                    o, c, rows, hz, wz = split_morph_rows(o, c, b.morph_height, b.morph_weight)
                    d = d[rows]
                    d[:, MORPH_HEIGHT_FLOAT] = hz
                    d[:, MORPH_WEIGHT_FLOAT] = wz
                    i, p = i[rows], p[rows]
                    f = np.ones(rows.shape[0], bool)
                    f[1:] = rows[1:] != rows[:-1]
                offs.append(o[:-1] + base)
                base += int(o[-1])
                cls.append(c)
                data.append(d)
                ids.append(i)
                part.append(p)
                first.append(f)
            k = sum(d.shape[0] for d in data)
            if k == 0:
                continue
            data = np.concatenate(data)
            slots = data[:, PALETTE_SLOT_FLOAT].copy()  # the pose slots (lod.poses), when the frame has a pose table
            data[:, PALETTE_SLOT_FLOAT] = np.arange(k, dtype=np.float32)
            words = instance_words(self.renderer.tint_table, np.concatenate(ids), tint)
            items.append(SimpleNamespace(st=st, key=key, tint=tint, fade=fade, k=k, data=data, words=words, slots=slots,
                                         offsets=np.concatenate(offs + [np.array([base], np.int64)]),
                                         clusters=np.concatenate(cls), ids=np.concatenate(ids),
                                         part=np.concatenate(part), first_row=np.concatenate(first),
                                         program="clusters_morph" if morph else "clusters"))
        return items

    def _plan(self, it, sub: np.ndarray, n_idx: int):
        """Instance data (grouped by cut), commands and gathered indices of the subset ``sub`` of item ``it``."""
        st, h = it.st, it.st.hierarchy
        offsets, clusters = _sub_csr(it.offsets, it.clusters, sub)
        order, counts, first = group_cuts(offsets, clusters)
        data = it.data[sub[order]]
        starts = np.zeros(counts.shape[0], np.int64)
        np.cumsum(counts[:-1], out=starts[1:])
        co = np.zeros(first.shape[0] + 1, np.int64)
        np.cumsum(offsets[first + 1] - offsets[first], out=co[1:])
        cc = _sub_csr(offsets, clusters, first)[1]
        idx = None
        if self.strategy == "indices":
            idx, ifirst = gather(st.flat, h.tri_start, co, cc)
            cmd = np.zeros((counts.shape[0], 5), np.uint32)
            cmd[:, 0] = np.diff(ifirst)
            cmd[:, 1] = counts
            cmd[:, 2] = ifirst[:-1] + n_idx
            cmd[:, 4] = starts
            cmd = cmd[cmd[:, 0] > 0]
        else:
            cmd = range_commands(h.tri_start, co, cc, counts, starts)
        return data, it.words[sub[order]], cmd, idx, counts.shape[0]

    def _submit(self, items, subsets, pbases, stats) -> None:
        """Draw ``subsets[j]`` (instance indices) of every item: one multi-draw-indirect per item."""
        r, ctx = self.renderer, self.ctx
        plans, datas, cmds, idxs, words = [], [], [], [], []
        n_cmd = n_idx = n_inst = 0
        for it, sub, pb in zip(items, subsets, pbases):
            if sub.size == 0:
                continue
            data, w, cmd, idx, n_groups = self._plan(it, sub, n_idx)
            words.append(w)
            plans.append((it, pb, n_inst, data.shape[0], n_cmd, cmd.shape[0]))
            datas.append(data)
            cmds.append(cmd)
            if idx is not None:
                idxs.append(idx)
                n_idx += idx.shape[0]
            n_inst += data.shape[0]
            n_cmd += cmd.shape[0]
            stats["groups"] += n_groups
            stats["triangles"] += int((cmd[:, 0].astype(np.int64) * cmd[:, 1]).sum()) // 3
            stats["instances"] += int(np.count_nonzero(it.first_row[sub]))
            if it.program == "clusters_morph":
                stats["morph_rows"] += int(sub.size)
        stats["commands"] += n_cmd
        stats["index_bytes"] += 4 * n_idx
        if n_cmd == 0:
            return
        # each submission gets fresh buffers (orphaned), so draws still pending keep their data
        all_data = np.concatenate(datas)
        inst = self._grow("_inst", all_data.nbytes, "clusters.instances")
        inst.orphan(self._inst_cap)
        inst.write(all_data)
        self._tints.write(np.concatenate(words))
        all_cmd = np.ascontiguousarray(np.concatenate(cmds), np.uint32)
        ind = self._grow("_ind", all_cmd.nbytes, "clusters.indirect")
        ind.orphan(self._ind_cap)
        ind.write(all_cmd)
        if idxs:
            all_idx = np.concatenate(idxs)
            ibo = self._grow("_ibo", all_idx.nbytes, "clusters.frame_indices")
            ibo.orphan(self._ibo_cap)
            ibo.write(all_idx)
        for it, pb, off, k, c0, nc in plans:
            if nc == 0:
                continue
            st = it.st
            prog = r.program(it.program)
            vao, locs = self._vao(st, it.program)
            st.skin.joints.use(0)
            if it.program == "clusters_morph":
                ti, tf = self._morph_textures(st)
                ti.use(MORPH_INT_UNIT)
                tf.use(MORPH_FLOAT_UNIT)
                prog["u_morph_i"].value = MORPH_INT_UNIT
                prog["u_morph_f"].value = MORPH_FLOAT_UNIT
            prog["u_palette_base"].value = int(pb)
            prog["u_palette_stride"].value = 3 * st.skin.n_joints
            if "u_fade" in prog:
                prog["u_fade"].value = getattr(it, "fade", (0.0, 0.0))
            r._bind_instances(vao, locs, inst, off * INSTANCE_FLOATS * 4, self._tints)
            (ctx.enable if st.skin.cull else ctx.disable)(ctx.CULL_FACE)  # single-sided as the full mesh
            vao.render_indirect(ind, mode=ctx.TRIANGLES, count=nc, first=c0)
            stats["draws"] += 1
        ctx.disable(ctx.CULL_FACE)

    def draw(self, batches, drawlist, view_proj) -> None:
        """Draw the cuts of ``batches`` (``lod.clusters.mode.ClusterDrawBatch``; a
        plain DrawBatch of a clusters rep draws every leaf, i.e. full detail).

        With occlusion culling on (:class:`lod.clusters.mode.ClustersRep`
        ``occlusion``), see :meth:`_draw_occlusion`.
        """
        r = self.renderer
        items = self._collect(batches)
        # instances whose cut's triangles are small on screen to the compute rasteriser (render/raster/hook.py)
        from render.raster.hook import split_clusters

        items, work = split_clusters(r, items, drawlist)
        r.raster_work.extend(work)
        stats = {"commands": 0, "draws": 0, "groups": 0, "instances": 0, "triangles": 0, "index_bytes": 0,
                 "queries": 0, "occluded": 0, "morph_rows": 0}
        self.last_stats = stats
        if not items:
            return
        pals = [r.poses.palette(it.key) for it in items]  # pose sharing (render/poses/cache.py)
        if all(p is not None for p in pals):
            self._draw_posed(items, pals, drawlist, view_proj, stats)
            return
        # the skinning palette of every instance (the renderer's pre-pass over a buffer of its own), in chunks
        # that fit the palette (render.poses.palette.plan_chunks); one chunk is the whole frame unless it is huge
        all_data = np.concatenate([it.data for it in items])
        pal = self._grow("_pal", all_data.nbytes, "clusters.palette_instances")
        pal.orphan(self._pal_cap)
        pal.write(all_data)
        offs = np.concatenate([[0], np.cumsum([it.k for it in items])[:-1]])
        chunks = r._palette_chunks([(it.st.skin, pal, int(o) * INSTANCE_FLOATS * 4, it.k)
                                    for it, o in zip(items, offs)])
        for name in {it.program for it in items}:
            r._set_uniforms(r.program(name), view_proj)
        self._near_of(drawlist)
        occlusion = any(it.st.occlusion for it in items)
        prev, merged = self._pvs, {}
        for ch in chunks:
            sub = items if len(chunks) == 1 else [_slice_item(items[d], f, n) for _, _, _, n, d, f in ch]
            pbases = r._build_palette([p[:4] for p in ch])
            r.fbo.use()
            if occlusion:
                self._pvs = prev  # every chunk reads the previous frame's visible set
                self._draw_occlusion(sub, pbases, view_proj, stats)
                for k, v in self._pvs.items():
                    merged[k] = np.union1d(merged[k], v) if k in merged else v
            else:
                self._submit(sub, [np.arange(it.k) for it in sub], pbases, stats)
        if occlusion:
            self._pvs = merged
        stats["palette_chunks"] = len(chunks)
        self.frame += 1

    def _draw_posed(self, items, pals, drawlist, view_proj, stats) -> None:
        """:meth:`draw` with the pose cache's palettes: every instance reads the palette of its pose slot
        (``i_anim.y``) in its character's block; no per-instance pre-pass, no chunks."""
        r = self.renderer
        for it in items:
            it.data[:, PALETTE_SLOT_FLOAT] = it.slots
        for name in {it.program for it in items}:
            r._set_uniforms(r.program(name), view_proj)
        self._near_of(drawlist)
        pals[0].texture.use(1)  # one texture holds every character's pose palettes
        pbases = [p.base for p in pals]
        r.fbo.use()
        if any(it.st.occlusion for it in items):
            self._draw_occlusion(items, pbases, view_proj, stats)
        else:
            self._submit(items, [np.arange(it.k) for it in items], pbases, stats)
        stats["palette_chunks"] = 0
        self.frame += 1

    def _near_of(self, drawlist) -> None:
        P = np.asarray(drawlist.proj, np.float64)
        if P[2, 2] != 1.0 and np.isfinite(P[2, 3] / (P[2, 2] - 1.0)):
            self._near = abs(float(P[2, 3] / (P[2, 2] - 1.0)))

    # ------------------------------------------------------------------ occlusion culling (§5.2)
    def _boxes(self, it) -> tuple:
        """Camera-relative world corners (k, 8, 3) float32 of each instance's box (its clip's
        bounds over every baked frame, which hold every rendered pose) and whether the
        camera is inside a box (grown by a near-plane margin), where a query cannot be trusted."""
        aabb = np.asarray(it.st.clip_aabb, np.float64)[it.part]  # (k, 2, 3)
        M = it.data[:, :12].astype(np.float64).reshape(-1, 3, 4)
        sel = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)])  # (8, 3) 0/1
        corners = np.where(sel[None] == 1, aabb[:, None, 1, :], aabb[:, None, 0, :])  # (k, 8, 3)
        world = np.einsum("kij,kcj->kci", M[:, :, :3], corners) + M[:, None, :, 3]
        lin = M[:, :, :3]
        eye = np.linalg.solve(lin, -M[:, :, 3][..., None])[..., 0]  # camera (origin) in model space
        margin = (OCCLUSION_NEAR_MARGIN * self._near) / np.maximum(np.linalg.norm(lin, axis=1).min(axis=1), 1e-12)
        inside = np.all((eye >= aabb[:, 0] - margin[:, None]) & (eye <= aabb[:, 1] + margin[:, None]), axis=1)
        return world.astype(np.float32), inside

    def _query(self, corners: np.ndarray, view_proj) -> np.ndarray:
        """(n,) bool: does any sample of each box (n, 8, 3) pass the depth test? One
        GL_SAMPLES_PASSED query per box (moderngl reads no other kind), colour and depth writes off."""
        n = corners.shape[0]
        if n == 0:
            return np.zeros(0, bool)
        tri = corners[:, _BOX_TRIANGLES.reshape(-1)]  # (n, 36, 3)
        buf = self._grow("_box", tri.nbytes, "clusters.occlusion_boxes")
        buf.orphan(self._box_cap)
        buf.write(np.ascontiguousarray(tri, np.float32))
        if self._box_vao is None or self._box_vao_buffer is not buf:
            if self._box_vao is not None:
                self._box_vao.release()
                self._objects.remove(self._box_vao)
            self._box_vao = self.ctx.vertex_array(self.renderer.program("clusters_box"), [(buf, "3f", "in_position")])
            self._box_vao.label = "clusters.occlusion_box_vao"
            self._box_vao_buffer = buf
            self._objects.append(self._box_vao)
        prog = self._box_vao.program
        prog["u_view_proj"].write(np.ascontiguousarray(np.asarray(view_proj, np.float32).T).tobytes())
        while len(self._queries) < n:
            self._queries.append(self.ctx.query(samples=True))
        fbo = self.renderer.fbo
        fbo.color_mask = (False, False, False, False)
        fbo.depth_mask = False
        fbo.use()  # moderngl applies a framebuffer's write masks when it is bound
        try:
            for i in range(n):
                with self._queries[i]:
                    self._box_vao.render(self.ctx.TRIANGLES, vertices=36, first=36 * i)
        finally:
            fbo.color_mask = (True, True, True, True)
            fbo.depth_mask = True
            fbo.use()
        return np.array([self._queries[i].samples > 0 for i in range(n)], bool)

    def _draw_occlusion(self, items, pbases, view_proj, stats) -> None:
        """§5.2 with instances as the occlusion unit (their cut's box over all poses):
        the instances of the previous frame's potentially visible set (PVS) are
        drawn first as occluders; the others are tested with occlusion queries on
        their boxes against that depth, and those found visible are drawn and join
        the PVS. Every ``occlusion_every`` frames the PVS is rebuilt from scratch:
        instances are taken front to back, the nearest chunk is drawn untested,
        each following chunk is tested against the depth drawn so far.

        Never removes a visible instance: a skipped instance's box, which holds
        every pose it can be drawn in, has no sample in front of geometry that
        is part of the final image (the camera inside a box always draws)."""
        every = min(int(it.st.occlusion_every) for it in items)
        rebuild = self.frame % max(1, every) == 0
        boxes = [self._boxes(it) for it in items]
        drawn = [np.zeros(it.k, bool) for it in items]
        if rebuild:
            dist = [np.linalg.norm(b[0].mean(axis=1), axis=1) for b in boxes]
            order = np.argsort(np.concatenate(dist), kind="stable")
            owner = np.repeat(np.arange(len(items)), [it.k for it in items])
            local = np.concatenate([np.arange(it.k) for it in items])
            n = order.shape[0]
            edges = [0, min(n, max(OCCLUSION_FIRST_CHUNK, n // 16))]
            while edges[-1] < n:
                edges.append(min(n, edges[-1] + max(OCCLUSION_FIRST_CHUNK, (n - edges[-1]) // 2)))
            chunks = [order[a:b] for a, b in zip(edges[:-1], edges[1:])]
            first = [[local[c[owner[c] == j]] for j in range(len(items))] for c in chunks]
            self._submit(items, first[0], pbases, stats)
            for j, s in enumerate(first[0]):
                drawn[j][s] = True
            tests = first[1:]
        else:
            pvs = [np.flatnonzero(np.isin(it.ids, self._pvs.get(it.key, np.zeros(0, np.int64)))) for it in items]
            # an instance whose box holds the camera is always drawn first
            pvs = [np.union1d(p, np.flatnonzero(b[1])) for p, b in zip(pvs, boxes)]
            self._submit(items, pvs, pbases, stats)
            for j, s in enumerate(pvs):
                drawn[j][s] = True
            tests = [[np.flatnonzero(~d) for d in drawn]]
        for chunk in tests:
            visible = []
            for j, s in enumerate(chunk):
                s = s[~drawn[j][s]]
                inside = boxes[j][1][s]
                res = np.ones(s.shape[0], bool)
                q = s[~inside]
                res[~inside] = self._query(boxes[j][0][q], view_proj)
                stats["queries"] += int(q.shape[0])
                stats["occluded"] += int((~res).sum())
                visible.append(s[res])
            self.renderer.fbo.use()
            self._submit(items, visible, pbases, stats)
            for j, s in enumerate(visible):
                drawn[j][s] = True
        pvs: dict = {}  # several items share a rep (fades, geomorphs): their visible agents together
        for it, d in zip(items, drawn):
            pvs.setdefault(it.key, []).append(it.ids[d])
        self._pvs = {k: np.unique(np.concatenate(v)) for k, v in pvs.items()}


#: 12 triangles of a box whose corner c has coordinates ((c >> 0) & 1, (c >> 1) & 1, (c >> 2) & 1)
_BOX_TRIANGLES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                           [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], np.int64)
