"""Keyframed view-dependent selection for the crowd's LOD modes, blended in between.

:class:`KeyframedSelector` wraps the selector of any LOD mode (``lod.modes``:
``none``, ``triangles``, ``points``, ``clusters``, ``auto``) and runs its
view-dependent selection only at every n-th displayed frame (a *keyframe*).
Every frame in between draws the instances with their current transforms and
animation (a cheap full-detail pack: the mode's own culling and packing pass,
:class:`lod.full.mode.NoLodSelector`) and the representation the keyframe
selections chose for them:

- an instance whose representation (rep, level, cluster cut, point/triangle
  jobs) is the same in the two keyframe selections i and i+1 between which the
  frame lies is drawn once, unfaded;
- an instance whose representation differs is drawn by *both*, as a
  transition with the frame's weight ``t = r / n`` (``r`` = frames since the
  keyframe): selection i's batch with ``DrawBatch.fade = (t, FADE_OUT)`` and
  selection i+1's with ``(t, FADE_IN)``. The renderer turns these into
  complementary screen-door (dither) patterns, so every pixel the instance
  covers is drawn by exactly one of the two and the switch is spread evenly
  over the n frames instead of popping;
- an instance with two different *cluster cuts* of one hierarchy, or two
  *levels* of one LOD chain, is instead geomorphed (``geomorph``, default):
  one batch draws the finer representation (for cuts, the union of the two:
  the finer cluster over every part of the mesh, :mod:`lod.clusters.morph`;
  for levels, the finer level) with its vertices blended by ``t`` towards the
  vertices they have collapsed into in the coarser one, so the image moves
  continuously from selection i to selection i+1 as the paper's interpolated
  hierarchies do (an instance whose cuts the frustum clipped so that one
  lacks part of the other's region is faded);
- an instance only one keyframe selected (it was culled in the other) is drawn
  with that one, unfaded;
- an instance neither keyframe selected with a representation valid for its
  current animation part is selected on the spot by the inner selector, alone
  with the other such instances: instances are never dropped. A clip change
  keeps a chain level or a cluster cut (drawn with the new clip); point jobs
  belong to one keyframe segment's octree (:func:`part_dependent`), so a
  segment change needs a new selection. Keyframe selections cull with a
  frustum opened by ``cull_margin`` degrees (:class:`MarginCamera`), so
  instances entering the view between keyframes rarely need one.

Which camera the keyframe selections use is the §4.1 choice of
``lod.temporal.terrain_keyframes`` (:data:`lod.temporal.terrain_keyframes.TEMPORAL_MODES`): ``"delayed"`` and
``"current"`` select for the camera at the keyframe and blend from the
previous keyframe's selection to it over the following interval (one interval
late; ``"delayed"`` also draws with the camera of n frames ago), while
``"extrapolated"`` selects the next keyframe's representation for a camera
extrapolated n frames ahead (:func:`lod.temporal.terrain_keyframes.extrapolate_camera`), so the
blend reaches it when the camera does.

Unknown attributes are forwarded to the inner selector (reading and, for
attributes it has, setting), so the engine's live controls (``poe``,
``splat_size``, ``observe``, ...) reach it.

Notes
-----
Friedrich, Polthier & Schmies, *Smooth View-Dependent Rendering in
Animations*, §3 (the view-dependent selection at keyframes only, the union of
two keyframe selections drawn in between with a global per-frame weight) and
§4.1 (camera extrapolation). Departure: the paper interpolates vertex
positions of two conforming triangle hierarchies; cluster cuts and chain
levels, whose coarser representations keep a subset of the finer ones'
vertices, are geomorphed the same way, but point sets have no common
vertices, so their blend is a per-pixel choice between the two (screen-door
transparency with a global weight ``t``), as is the switch between two
different representation families (mode auto).
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from lod.clusters.morph import morph_batch
from lod.drawlist import FADE_IN, FADE_OUT, INSTANCE_FLOATS, DrawList
from lod.full.mode import NoLodSelector
from lod.poses.table import POSE_PARAMS
from lod.temporal.rows import _is_csr, part_dependent, row_counts, row_signatures, subset_state, take_rows  # noqa: F401
from lod.temporal.terrain_keyframes import TEMPORAL_CULL_MARGIN, TEMPORAL_MODES, extrapolate_camera
from lod.view import Camera
from sim.params import Param

#: default frames per keyframe of the crowd's LOD: 1 = per-frame selection (no keyframing)
KEYFRAME_EVERY_DEFAULT = 1
#: default camera handling between keyframes (lod.temporal.terrain_keyframes.TEMPORAL_MODES)
KEYFRAME_EXTRAPOLATION_DEFAULT = "extrapolated"

#: ``[lod]`` keys valid for every mode (validated by crowd/scene.py beside the mode's own PARAMS)
LOD_COMMON_PARAMS: dict = {
    "keyframe_every": Param("int", KEYFRAME_EVERY_DEFAULT, min=1, max=1000,
                            doc="frames per view-dependent selection of the crowd's LOD; in between the two "
                                "keyframe selections are blended (1 = every frame, off)"),
    "keyframe_extrapolation": Param("str", KEYFRAME_EXTRAPOLATION_DEFAULT, choices=TEMPORAL_MODES,
                                    doc="camera of the keyframe selections (Friedrich et al. §4.1)"),
    "keyframe_geomorph": Param("bool", True,
                               doc="blend two keyframe cluster cuts or LOD chain levels by geomorphing their "
                                   "vertices (else by a screen-door fade, as point sets are)"),
    **POSE_PARAMS,  # pose_rate: copies in the same quantised pose skinned once per frame (lod.poses)
}



def base_selector_of(selector) -> NoLodSelector:
    """The full-detail cull-and-pack selector a mode's selector builds on.

    Looks for a :class:`lod.full.mode.NoLodSelector` as the selector itself or its
    attribute ``base``, ``_inner`` or ``_base`` (the modes' selectors keep one).
    Raises TypeError when there is none (the mode cannot be keyframed).
    """
    if isinstance(selector, NoLodSelector):
        return selector
    for name in ("base", "_inner", "_base"):
        b = getattr(selector, name, None)
        if isinstance(b, NoLodSelector):
            return b
    raise TypeError(f"{type(selector).__name__}: no full-detail NoLodSelector (attribute 'base', '_inner' or "
                    f"'_base') to pack instances between keyframes; this selector cannot be keyframed")


@dataclass
class MarginCamera(Camera):
    """A :class:`lod.view.Camera` whose *culling* frustum is opened by
    ``margin`` degrees on every side; projection, view and the field of view
    the LOD error is measured with stay the camera's own.

    Keyframe selections cull with it, so instances entering the view between
    two keyframes already have a keyframe representation (as the terrain's
    ``cull_margin``, :data:`lod.temporal.terrain_keyframes.TEMPORAL_CULL_MARGIN`).
    """

    margin: float = 0.0

    @classmethod
    def of(cls, camera: Camera, margin: float) -> "MarginCamera":
        return cls(camera.position, camera.rotation, camera.fov_y, camera.near, camera.far, float(margin))

    def frustum_planes(self, aspect: float) -> np.ndarray:
        if not self.margin > 0:
            return super().frustum_planes(aspect)
        m = math.radians(self.margin)
        hy = min(math.atan(math.tan(math.radians(self.fov_y) * 0.5)) + m, math.radians(89.0))
        hx = min(math.atan(float(aspect) * math.tan(math.radians(self.fov_y) * 0.5)) + m, math.radians(89.0))
        wide = Camera(self.position, self.rotation, math.degrees(2.0 * hy), self.near, self.far)
        return wide.frustum_planes(math.tan(hx) / math.tan(hy))


# ---------------------------------------------------------------------------- keyframes
@dataclass
class _Key:
    """One keyframe selection, indexed by agent.

    frame : int; camera : the camera it was selected with
    drawlist : DrawList of the inner selector
    batch, row : (N,) int64 batch index / row per agent (-1 = not selected)
    group : (N,) int64 base group (rep, part) per agent at the keyframe (-1 = unknown)
    sig : (N,) uint64 row signature per agent; tri, pts : (N,) float64 counts per agent
    dep : (B,) bool, batch b's payload is :func:`part_dependent`
    """

    frame: int
    camera: object
    drawlist: DrawList
    batch: np.ndarray
    row: np.ndarray
    group: np.ndarray
    sig: np.ndarray
    tri: np.ndarray
    pts: np.ndarray
    dep: np.ndarray


class KeyframedSelector:
    """Run a mode's view-dependent selection every n-th frame, blend in between (module docstring).

    Parameters
    ----------
    inner : a mode's selector (``select(state, camera, size, statics=()) -> DrawList``)
    n : int >= 1, frames per keyframe; 1 calls ``inner.select`` every frame and
        returns its DrawList unchanged
    mode : one of :data:`lod.temporal.terrain_keyframes.TEMPORAL_MODES`
    base : the full-detail packer (default :func:`base_selector_of` ``(inner)``)
    cull_margin : degrees the keyframe selections' culling frustum is opened by
        on every side (:class:`MarginCamera`), so that instances entering the
        view between keyframes rarely need a selection on the spot
    geomorph : blend two cluster cuts or two chain levels of an instance by geomorphing
        (default) rather than by a screen-door fade (needs ``inner.cluster_hierarchies()``
        / ``inner.chain_reps()``)

    Attributes
    ----------
    n_selections : int, calls of ``inner.select`` for keyframes
    n_fresh_selections : int, calls of ``inner.select`` for instances no keyframe covered
    last_keyframe : bool, the last ``select`` ran a keyframe selection
    last_selection_seconds : float, time the last ``select`` spent in ``inner.select``
    last_pack_seconds : float, time it spent in the full-detail pack
    """

    _OWN = frozenset({"inner", "n", "mode", "base", "frame", "history", "keys", "n_selections",
                      "n_fresh_selections", "last_keyframe", "last_selection_seconds", "last_pack_seconds",
                      "cull_margin", "geomorph", "_groups", "_group_rep", "_group_part", "_reps"})

    def __init__(self, inner, n: int = KEYFRAME_EVERY_DEFAULT, mode: str = KEYFRAME_EXTRAPOLATION_DEFAULT,
                 base=None, cull_margin: float = TEMPORAL_CULL_MARGIN, geomorph: bool = True):
        if not (np.isfinite(cull_margin) and 0.0 <= float(cull_margin) < 60.0):
            raise ValueError(f"keyframed selection cull_margin: expected degrees in [0, 60), got {cull_margin!r}")
        self.cull_margin = float(cull_margin)
        self.geomorph = bool(geomorph)
        if isinstance(n, bool) or int(n) != n or int(n) < 1:
            raise ValueError(f"[lod] keyframe_every: expected an integer >= 1, got {n!r}")
        if mode not in TEMPORAL_MODES:
            raise ValueError(f"[lod] keyframe_extrapolation: expected one of {', '.join(TEMPORAL_MODES)}, got {mode!r}")
        self.inner = inner
        self.n = int(n)
        self.mode = mode
        self.base = base if base is not None else (base_selector_of(inner) if self.n > 1 else None)
        self.reset()

    def reset(self) -> None:
        """Forget the keyframes (the next ``select`` is a keyframe)."""
        self.frame = 0
        self.history = deque(maxlen=self.n + 2)
        self.keys = {}
        self.n_selections = 0
        self.n_fresh_selections = 0
        self.last_keyframe = False
        self.last_selection_seconds = 0.0
        self.last_pack_seconds = 0.0
        self._groups = {}
        self._group_rep = []
        self._group_part = []
        self._reps = {}

    def set_interval(self, n: int) -> None:
        """Change n (live control); keyframing restarts at the next ``select``."""
        if isinstance(n, bool) or int(n) != n or int(n) < 1:
            raise ValueError(f"keyframe interval: expected an integer >= 1, got {n!r}")
        if int(n) != self.n:
            self.n = int(n)
            if self.n > 1 and self.base is None:
                self.base = base_selector_of(self.inner)
            self.reset()

    def remap_agents(self, src: np.ndarray, state=None) -> None:
        """Agents left or entered since the last frame (``sim.population``: ``src`` (n,) each agent's index
        before, -1 = entered): the keyframes keep the selections of the agents that stayed, under their new
        indices; an entered agent has none, so it is selected on the spot until the next keyframe."""
        from sim.population import remap_rows

        fills = {"batch": -1, "row": -1, "group": -1, "sig": 0, "tri": 0.0, "pts": 0.0}
        for key in self.keys.values():
            for name, fill in fills.items():
                setattr(key, name, remap_rows(getattr(key, name), src, fill))

    # -- attribute forwarding ------------------------------------------------------------------------------------------
    def __getattr__(self, name):
        if name.startswith("__") or name in KeyframedSelector._OWN:
            raise AttributeError(name)
        return getattr(self.__dict__["inner"], name)

    def __setattr__(self, name, value):
        if name in KeyframedSelector._OWN or "inner" not in self.__dict__ or not hasattr(self.inner, name):
            object.__setattr__(self, name, value)
        else:
            setattr(self.inner, name, value)

    # -- keyframes ----------------------------------------------------------------------------------------------------
    def _gid(self, rep: str, part: int) -> int:
        key = (rep, int(part))
        g = self._groups.get(key)
        if g is None:
            g = self._groups[key] = len(self._groups)
            self._group_rep.append(self._reps.setdefault(rep, len(self._reps)))
            self._group_part.append(int(part))
        return g

    def _groups_of(self, state, camera, size) -> np.ndarray:
        """(N,) base group of every agent (no culling)."""
        cull = self.base.cull
        self.base.cull = False
        try:
            dl = self.base.select(state, camera, size)
        finally:
            self.base.cull = cull
        g = np.full(state.n, -1, np.int64)
        for b in dl.batches:
            ids = np.asarray(b.instance_ids, np.int64)
            g[ids[ids >= 0]] = self._gid(b.rep, b.part)
        return g

    def _keyframe(self, state, camera, size, frame: int) -> _Key:
        t0 = time.perf_counter()
        dl = self.inner.select(state, camera, size)
        self.last_selection_seconds += time.perf_counter() - t0
        self.n_selections += 1
        N = state.n
        batch = np.full(N, -1, np.int64)
        row = np.full(N, -1, np.int64)
        sig = np.zeros(N, np.uint64)
        tri = np.zeros(N)
        pts = np.zeros(N)
        dep = np.array([part_dependent(b) for b in dl.batches] or [False], bool)
        for bi, b in enumerate(dl.batches):
            ids = np.asarray(b.instance_ids, np.int64)
            ok = (ids >= 0) & (ids < N)
            if not ok.any():
                continue
            r = np.flatnonzero(ok)
            batch[ids[r]] = bi
            row[ids[r]] = r
            sig[ids[r]] = row_signatures(b)[r]
            bt, bp = row_counts(b)
            tri[ids[r]] = bt[r]
            pts[ids[r]] = bp[r]
        t1 = time.perf_counter()
        group = self._groups_of(state, camera, size)
        self.last_pack_seconds += time.perf_counter() - t1
        return _Key(frame, camera, dl, batch, row, group, sig, tri, pts, dep)

    # -- selection ----------------------------------------------------------------------------------------------------
    def select(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList (module docstring).

        ``stats`` hold "instances", "culled", "triangles", "points", "batches",
        "statics" as the inner selector's, plus "keyframe" (bool: a keyframe
        selection ran this frame), "transitions" (instances between two
        representations: faded, drawn twice, or geomorphed), "geomorphs" (those
        geomorphed), "fresh" (instances selected on the spot) and "fade_t" (the
        frame's transition weight).
        """
        self.last_selection_seconds = 0.0
        self.last_pack_seconds = 0.0
        if self.n == 1:
            self.frame += 1
            self.last_keyframe = True
            self.n_selections += 1
            t0 = time.perf_counter()
            dl = self.inner.select(state, camera, size, statics)
            self.last_selection_seconds = time.perf_counter() - t0
            return dl
        f = self.frame
        self.frame += 1
        self.history.append(camera)
        n = self.n
        i, r = divmod(f, n)
        self.last_keyframe = r == 0
        if r == 0:
            if self.mode == "extrapolated":
                if i not in self.keys:  # first keyframe: nothing was extrapolated yet
                    self.keys[i] = self._keyframe(state, MarginCamera.of(camera, self.cull_margin), size, f)
                prev = self.history[-2] if len(self.history) >= 2 else camera
                ahead = MarginCamera.of(extrapolate_camera(prev, camera, n), self.cull_margin)
                self.keys[i + 1] = self._keyframe(state, ahead, size, f + n)
            else:
                self.keys[i] = self._keyframe(state, MarginCamera.of(camera, self.cull_margin), size, f)
            for k in [k for k in self.keys if k < i - 1]:
                del self.keys[k]
        t = r / n
        draw_cam = camera
        if self.mode == "extrapolated":
            A, B = self.keys[i], self.keys[i + 1]
        else:
            A, B = self.keys.get(i - 1, self.keys[i]), self.keys[i]
            if self.mode == "delayed" and i > 0:
                lag = min(n, f)
                draw_cam = self.history[-1 - lag] if lag < len(self.history) else self.history[0]
        return self._blend(state, draw_cam, size, statics, A, B, t)

    def _morphables(self) -> tuple[dict, dict]:
        """({rep key: ClusterHierarchy}, {rep key: TrianglesRep}) the inner selector's cluster cuts
        and chain levels refer to, where geomorphs are possible (``cluster_hierarchies()`` and
        ``chain_reps()`` of the inner selector; {} without)."""
        out = []
        for name in ("cluster_hierarchies", "chain_reps"):
            f = getattr(self.inner, name, None)
            out.append(f() if callable(f) else {})
        return out[0], out[1]

    def _geomorphs(self, A: _Key, B: _Key, ids, data, gid, trans, t: float):
        """Geomorphed batches of the transitions whose two keyframe rows are cluster cuts of one
        hierarchy (:func:`lod.clusters.morph.morph_batch`: the union of the cuts) or two levels of
        one LOD chain (the finer level, its vertices blended towards the coarser one,
        ``TriangleDrawBatch.morph``); returns (positions into ``ids`` morphed, batches)."""
        hier, chains = self._morphables()
        morphed = np.zeros(ids.shape[0], bool)
        if not hier and not chains:
            return morphed, []
        p = np.flatnonzero(trans)
        ab, bb = A.batch[ids[p]], B.batch[ids[p]]
        nB = max(len(B.drawlist.batches), 1)
        key = (ab * nB + bb) * (len(self._group_part) + 1) + gid[p]
        order = np.argsort(key, kind="stable")
        p, key, ab, bb = p[order], key[order], ab[order], bb[order]
        cut = np.flatnonzero(np.diff(key)) + 1
        out = []
        for lo, hi in zip(np.r_[0, cut], np.r_[cut, p.shape[0]]):
            ka, kb = A.drawlist.batches[int(ab[lo])], B.drawlist.batches[int(bb[lo])]
            if ka.rep != kb.rep:
                continue
            q = p[lo:hi]
            agents = ids[q]
            part = self._group_part[int(gid[q[0]])]
            h = hier.get(ka.rep)
            if h is not None and _is_csr(ka) and _is_csr(kb):
                a = take_rows(ka, A.row[agents], agents.astype(np.int32), data[q],
                              part=None if part == ka.part else part)
                b = take_rows(kb, B.row[agents], agents.astype(np.int32), data[q])
                mb, ok = morph_batch(h, a, b, t)
                if mb is not None:
                    out.append(mb)
                    morphed[q[ok]] = True
                continue
            r = chains.get(ka.rep)
            if (r is not None and getattr(ka, "index_range", None) is not None
                    and getattr(kb, "index_range", None) is not None and int(ka.level) != int(kb.level)):
                # the finer level morphs: towards B's coarser level (weight t), or from A's coarser one (1 - t)
                a_fine = int(ka.level) < int(kb.level)
                fine, K = (ka, A) if a_fine else (kb, B)
                coarse = max(int(ka.level), int(kb.level))
                mb = take_rows(fine, K.row[agents], agents.astype(np.int32), data[q],
                               triangles=int(r.level_count[int(fine.level)]) * int(q.size),
                               part=None if part == fine.part else part)
                mb.morph = (coarse, float(t) if a_fine else 1.0 - float(t))
                out.append(mb)
                morphed[q] = True
        return morphed, out

    def _blend(self, state, camera, size, statics, A: _Key, B: _Key, t: float) -> DrawList:
        t0 = time.perf_counter()
        cur = self.base.select(state, camera, size, statics)
        self.last_pack_seconds += time.perf_counter() - t0
        N = state.n
        static_batches, ids_l, data_l, gid_l = [], [], [], []
        for b in cur.batches:
            ids = np.asarray(b.instance_ids, np.int64)
            if ids.size and int(ids[0]) < 0:
                static_batches.append(b)
                continue
            ids_l.append(ids)
            data_l.append(np.asarray(b.instance_data, np.float32).reshape(-1, INSTANCE_FLOATS))
            gid_l.append(np.full(ids.shape[0], self._gid(b.rep, b.part), np.int64))
        ids = np.concatenate(ids_l) if ids_l else np.zeros(0, np.int64)
        data = np.concatenate(data_l) if data_l else np.zeros((0, INSTANCE_FLOATS), np.float32)
        gid = np.concatenate(gid_l) if gid_l else np.zeros(0, np.int64)

        grep = np.asarray(self._group_rep, np.int64)

        def valid(K: _Key):
            """Agents K selected with a payload valid for their current part."""
            if K.batch.shape[0] != N:
                return np.zeros(ids.shape[0], bool)
            kb, kg = K.batch[ids], K.group[ids]
            loose = ~K.dep[np.maximum(kb, 0)] & (kg >= 0) & (grep[np.maximum(kg, 0)] == grep[gid])
            return (kb >= 0) & ((kg == gid) | loose)

        va = valid(A)
        same = A is B
        vb = va if same else valid(B)
        if same:
            eq = np.ones(ids.shape[0], bool)
        else:
            eq = A.sig[ids] == B.sig[ids]
        use_a = va & (~vb | eq)  # unfaded from A (same in both, or only A has it)
        use_b = vb & ~va  # unfaded from B
        trans = va & vb & ~eq  # drawn by both: geomorphed or faded
        fresh = ~(va | vb)
        batches = []
        tri_total = pts_total = 0.0
        n_morph = 0
        if self.geomorph and trans.any():
            morphed, mb = self._geomorphs(A, B, ids, data, gid, trans, t)
            trans &= ~morphed
            n_morph = int(morphed.sum())
            batches.extend(mb)
            tri_total += sum(b.triangles for b in mb)
        fade_out, fade_in = (float(t), FADE_OUT), (float(t), FADE_IN)
        # (source key, batch, fade) groups of positions into ids
        nA = len(A.drawlist.batches)
        src = np.concatenate([np.where(use_a, A.batch[ids], -1), np.where(use_b, nA + B.batch[ids], -1),
                              np.where(trans, A.batch[ids], -1), np.where(trans, nA + B.batch[ids], -1)])
        role = np.repeat(np.arange(4), ids.shape[0])
        pos = np.tile(np.arange(ids.shape[0]), 4)
        keep = src >= 0
        src, role, pos = src[keep], role[keep], pos[keep]
        cg = gid[pos]  # current part group: a clip change keeps the representation, drawn with the new part
        order = np.lexsort((pos, cg, src, role))
        src, role, pos, cg = src[order], role[order], pos[order], cg[order]
        if src.shape[0]:
            cut = np.flatnonzero((np.diff(src) != 0) | (np.diff(role) != 0) | (np.diff(cg) != 0)) + 1
            for a, b in zip(np.r_[0, cut], np.r_[cut, src.shape[0]]):
                s, ro, part = int(src[a]), int(role[a]), self._group_part[int(cg[a])]
                K = A if s < nA else B
                kb = K.drawlist.batches[s if s < nA else s - nA]
                p = pos[a:b]
                agents = ids[p]
                fade = None if ro < 2 else (fade_out if ro == 2 else fade_in)
                tri = float(K.tri[agents].sum())
                pt = float(K.pts[agents].sum())
                batches.append(take_rows(kb, K.row[agents], agents.astype(np.int32), data[p], fade=fade,
                                         triangles=int(round(tri)), points=int(round(pt)),
                                         part=None if part == kb.part else part))
                tri_total += tri  # both halves of a transition are submitted
                pts_total += pt
        options = dict(B.drawlist.options)
        n_fresh = int(fresh.sum())
        if n_fresh:
            sub_ids = ids[fresh]
            sub = subset_state(state, sub_ids)
            t1 = time.perf_counter()
            dl = self.inner.select(sub, camera, size)
            self.last_selection_seconds += time.perf_counter() - t1
            self.n_fresh_selections += 1
            options.update(dl.options)
            for b in dl.batches:
                bid = np.asarray(b.instance_ids, np.int64)
                if bid.size and int(bid[0]) < 0:
                    continue
                b.instance_ids = sub_ids[bid].astype(np.int32)
                batches.append(b)
                tri_total += b.triangles
                pts_total += b.points
        batches.extend(static_batches)
        tri_total += sum(b.triangles for b in static_batches)
        drawn = int(ids.shape[0])
        stats = {"instances": drawn, "culled": int(N - drawn), "triangles": int(round(tri_total)),
                 "points": int(round(pts_total)), "batches": len(batches), "statics": len(static_batches),
                 "keyframe": bool(self.last_keyframe), "transitions": int(trans.sum()) + n_morph,
                 "geomorphs": n_morph, "fresh": n_fresh, "fade_t": float(t)}
        return DrawList(origin=cur.origin, view=cur.view, proj=cur.proj, size=cur.size, batches=batches,
                        stats=stats, options=options)


def keyframed(selector, n: int, mode: str = KEYFRAME_EXTRAPOLATION_DEFAULT):
    """``selector`` itself when ``n == 1``, else a :class:`KeyframedSelector` around it."""
    return selector if int(n) == 1 else KeyframedSelector(selector, n, mode)


__all__ = ["KEYFRAME_EVERY_DEFAULT", "KEYFRAME_EXTRAPOLATION_DEFAULT", "LOD_COMMON_PARAMS", "MarginCamera",
           "part_dependent", "KeyframedSelector", "base_selector_of",
           "keyframed", "row_counts", "row_signatures", "subset_state", "take_rows"]
