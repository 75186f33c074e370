"""LOD mode ``"none"``: every visible instance at full detail, selected per frame.

This is the fair baseline every LOD speed-up is measured against: every
instance in the view frustum is drawn with its complete mesh
(:mod:`lod.full.reps`), skinned on the GPU from joint matrices baked once per
clip.

:class:`NoLodSelector` turns a ``CrowdState`` and a ``Camera`` into a
``DrawList``: camera-relative model matrices, animation coordinates, frustum
culling with whole-animation bounds (:mod:`lod.full.bounds`), and grouping
into instanced batches. The per-instance work is two numba passes
(:func:`lod.full.pack.instance_batches`: cull + count, then a stable counting
sort that packs instance data) beside a plain numpy reference
(:func:`lod.full.pack.instance_batches_numpy`); no per-instance Python loops,
a few milliseconds for 100K instances. The other modes reuse this selector's
cull-and-pack pass.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lod.cull import cull_spheres
from lod.drawlist import INSTANCE_FLOATS, DrawBatch, DrawList
from lod.full.pack import instance_batches, instance_batches_numpy
from lod.full.reps import build_rep


@dataclass
class _Groups:
    rep_index: np.ndarray  # (G,) int
    part: np.ndarray  # (G,) int
    sphere: np.ndarray  # (G, 4) float64
    tris: np.ndarray  # (G,) int64
    offset: np.ndarray  # (R,) int64 first group of each rep


class NoLodSelector:
    """Select every visible instance at full detail.

    Parameters
    ----------
    reps : sequence of representations aligned with ``CrowdState.character``
        (``reps[i]`` draws agents whose character is i). A :class:`StaticRep`
        in this list draws its agents unanimated (used by benchmarks).
    static_reps : extra :class:`StaticRep` objects that ``statics`` may name.
    cull : frustum culling on (default) or off.
    use_kernel : per-instance work in the numba kernel (default) or in the
        numpy reference (:func:`instance_batches_numpy`; tests compare them).
    """

    def __init__(self, reps, static_reps=(), cull: bool = True, use_kernel: bool = True):
        self.use_kernel = bool(use_kernel)
        self.reps = list(reps)
        self.by_key = {r.key: r for r in list(self.reps) + list(static_reps)}
        self.cull = bool(cull)
        rep_index, part, sph, tris, offs = [], [], [], [], []
        g = 0
        for i, r in enumerate(self.reps):
            offs.append(g)
            n = r.n_parts
            rep_index.append(np.full(n, i, np.int64))
            part.append(np.arange(n, dtype=np.int64))
            sph.append(np.asarray(r.part_sphere(), np.float64).reshape(n, 4))
            tris.append(r.part_triangles())
            g += n
        cat = (lambda xs, shape, dt: np.concatenate(xs) if xs else np.zeros(shape, dt))
        self._g = _Groups(cat(rep_index, (0,), np.int64), cat(part, (0,), np.int64), cat(sph, (0, 4), np.float64),
                          cat(tris, (0,), np.int64), np.asarray(offs, np.int64))
        self._is_static = np.array([r.kind == "static" for r in self.reps] or [False])
        self._any_static = bool(self._is_static.any())
        # skinned clip tables per group, for the vectorised frame coordinate
        G = self._g.part.shape[0]
        self._g_off = np.zeros(G)
        self._g_fps = np.zeros(G)
        self._g_dur = np.zeros(G)
        self._g_loop = np.zeros(G, bool)
        self._g_last = np.zeros(G)
        self._g_skinned = np.zeros(G, bool)
        for i, r in enumerate(self.reps):
            if r.kind == "skinned":
                self._g_skinned[offs[i]:offs[i] + r.n_parts] = True
                sl = slice(offs[i], offs[i] + r.n_parts)
                self._g_off[sl] = r.clip_offset
                self._g_fps[sl] = r.clip_fps
                self._g_dur[sl] = r.clip_duration
                self._g_loop[sl] = r.clip_loop
                self._g_last[sl] = r.clip_offset + r.clip_frames - 1
        self._n_clips = np.array([(r.n_clips if r.kind == "keyframed" else r.n_parts) for r in self.reps] or [0])

    # -------------------------------------------------------------------------
    def select(self, state, camera, size, statics=(), agents=None) -> DrawList:
        """Build the frame's DrawList.

        Parameters
        ----------
        state : sim.state.CrowdState
        camera : lod.view.Camera
        size : (width, height) pixels
        statics : sequence of (StaticRep key, (4, 4) float64 world matrix),
            each drawn as a single-instance batch (instance id -1).
        agents : None (every agent) or (m,) increasing int agent indices: only
            these are culled and packed (instance ids stay the state's); e.g. the
            agents no super-hierarchy node draws (Wand & Straßer §3.6)

        Returns
        -------
        DrawList with batches sorted by (representation, part), instances in
        agent order within a batch; ``stats`` holds "instances", "culled",
        "triangles", "points", "batches".
        """
        w, h = int(size[0]), int(size[1])
        aspect = w / max(1, h)
        origin = np.asarray(camera.position, np.float64).copy()
        planes = camera.frustum_planes(aspect)
        sel = None if agents is None else np.asarray(agents, np.int64)

        def pick(a, dtype):
            a = np.asarray(a, dtype)
            return a if sel is None else a[sel]

        n = state.n if sel is None else int(sel.shape[0])
        char = pick(state.character, np.int64)
        clip = pick(state.clip, np.int64)
        nreps = len(self.reps)
        if n and (char.min() < 0 or char.max() >= nreps):
            raise ValueError(f"CrowdState.character: expected indices in 0..{nreps - 1}, got {char.min()}..{char.max()}")
        if self._any_static and n:
            clip = np.where(self._is_static[char], 0, clip)
        if n and (clip.min() < 0 or (clip >= self._n_clips[char]).any()):
            bad = int(np.flatnonzero((clip < 0) | (clip >= self._n_clips[char]))[0])
            raise ValueError(f"CrowdState.clip[{bad if sel is None else int(sel[bad])}] = {clip[bad]}: expected a "
                             f"clip index below {self._n_clips[char[bad]]} for character {char[bad]}")

        gid = self._g.offset[char] + clip if nreps else np.zeros(0, np.int64)
        t = pick(state.anim_time, np.float64)
        anim = np.zeros(n, np.float64)
        for ri, r in enumerate(self.reps):
            if r.kind != "keyframed":
                continue
            mr = np.flatnonzero(char == ri)
            for a in range(r.n_clips):
                ma = mr[clip[mr] == a]
                if ma.size == 0:
                    continue
                seg, u = r.locate(a, t[ma])
                gid[ma] = self._g.offset[ri] + seg
                anim[ma] = u
        pos = pick(state.position, np.float64)
        scale = pick(state.scale, np.float64)
        if n and not (np.isfinite(pos).all() and np.isfinite(scale).all()):
            raise FloatingPointError("CrowdState.position/scale hold NaN or Inf; refusing to draw them")
        heading = pick(state.heading, np.float64)
        args = (pos, origin, heading, scale, gid, t, anim, self._g.sphere, self._g_skinned, self._g_off, self._g_fps,
                self._g_dur, self._g_loop, self._g_last, planes, self.cull)
        if self.use_kernel:
            ids, data, counts = instance_batches(*args)
        else:
            ids, data, counts = instance_batches_numpy(*args)
        if sel is not None:
            ids = sel[ids].astype(np.int32)
        batches = []
        a = 0
        for g in np.flatnonzero(counts).tolist():
            b = a + int(counts[g])
            r = self.reps[int(self._g.rep_index[g])]
            batches.append(DrawBatch(r.key, int(self._g.part[g]), ids[a:b], data[a:b],
                                     triangles=int(self._g.tris[g]) * (b - a)))
            a = b
        n_drawn = int(ids.shape[0])
        n_static = 0
        for skey, mat in statics:
            r = self.by_key.get(skey)
            if r is None or r.kind != "static":
                raise KeyError(f"statics: unknown StaticRep key {skey!r}; known: {sorted(k for k, v in self.by_key.items() if v.kind == 'static')}")
            m = np.asarray(mat, np.float64).reshape(4, 4).copy()
            if not np.isfinite(m).all():
                raise FloatingPointError(f"statics: matrix of {skey!r} holds NaN or Inf")
            m[:3, 3] -= origin
            if self.cull:
                c = m[:3, :3] @ r.sphere[:3] + m[:3, 3]
                rad = r.sphere[3] * float(np.linalg.norm(m[:3, :3], axis=0).max())
                if not cull_spheres(c[None], np.array([rad]), planes)[0]:
                    continue
            d = np.zeros((1, INSTANCE_FLOATS), np.float32)
            d[0, :12] = m[:3, :].reshape(12)
            batches.append(DrawBatch(skey, 0, np.array([-1], np.int32), d, triangles=r.n_triangles))
            n_static += 1
        tri = sum(b.triangles for b in batches)
        stats = {"instances": n_drawn, "culled": int(n - n_drawn), "triangles": int(tri), "points": 0,
                 "batches": len(batches), "statics": n_static}
        return DrawList(origin=origin, view=camera.view_matrix().astype(np.float32),
                        proj=camera.projection(aspect).astype(np.float32), size=(w, h), batches=batches, stats=stats)


# --------------------------------------------------------------------------------------------------------------------
# LOD mode "none" (lod.modes protocol)
# --------------------------------------------------------------------------------------------------------------------

#: ``[lod]`` keys of mode "none": full detail has no parameters
PARAMS: dict = {}


def build(characters, names, fps, params, static_reps=(), progress=None):
    """Mode "none" for ``lod.modes``: a full-detail rep per character and a NoLodSelector."""
    items = list(zip(characters, names, fps))
    if callable(progress):
        items = progress(items, "representations")
    reps = [build_rep(ch, fps=f, key=f"none:{n}") for ch, n, f in items]
    return reps, NoLodSelector(reps, static_reps=static_reps)
