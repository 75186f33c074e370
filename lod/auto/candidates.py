"""Candidates of LOD mode ``"auto"``: one plug-in per representation family.

Mode "auto" (:mod:`lod.auto.mode`) culls and packs instances once, as the
full-detail mode does (the *master* draw list: one batch per (character,
clip) or (character, segment), the instances inside the view frustum), and
then asks every candidate, per master batch, what each of its options would
cost and how much error it would show for every instance of the batch. The
selector picks per instance the cheapest option within the bound and hands
every candidate the instances it won, which the candidate turns into its own
draw batches. A candidate never sees another one, so a new representation
plugs in by adding a class here, without touching the others (the per-object
cost/benefit choice of Funkhouser & Séquin, SIGGRAPH 1993, §4, with the
accuracy as a hard bound).

The protocol (:class:`Candidate`):

``name`` : str, for telemetry
``reps`` : representations to upload to the renderer (their keys are their own)
``options(frame, group)`` -> :class:`Options` or None
    per instance of ``group`` (a master batch) the predicted cost (seconds)
    and projected error (pixels) of each of the candidate's ``m`` options,
    plus an opaque ``plan`` the candidate may reuse in ``emit``. None: the
    candidate has nothing for this group (no representation of the
    character, or the bound excludes it).
``emit(frame, group, options, rows, choice)`` -> list of DrawBatch
    the batches drawing instances ``rows`` (indices into the group) with
    their chosen option ``choice`` (indices into the candidate's options).
``finish(frame, drawlist)``
    frame-wide settings after all batches exist (e.g. the splat size).
``frame_cost(frame)`` -> float
    seconds the candidate adds to the frame once, when it draws anything
    (the point splatting pass, the cluster drawer's pre-pass); the selector drops a candidate for the whole
    frame when the per-instance savings it brings do not pay for it, and prices it in every frame plan
    that uses it (:mod:`lod.auto.mode`, "Plans").
``cost_lower_bound(frame, group)`` -> (k,) float64 or None (optional)
    seconds none of the candidate's options can undercut, cheap to compute; the selector then asks
    ``options(frame, group, need)`` only for the instances where the bound could win (the cluster cut).

Costs come from :class:`lod.auto.cost_model.CostModel` (per triangle, splat,
cluster and instance; the per-draw-call cost is shared by a batch and left
out of the per-instance choice). Errors are in pixels: the projected
geometric error for triangle levels (Luebke et al. 2003, §4.1) and cluster
cuts (VDR-AM §5.1), the splat size for point hierarchies (Wand & Straßer
2002, §3.2: a node is drawn as points when its sample spacing projects to at
most the splat size).

Three candidates exist:

- :class:`TrianglesCandidate` (mandatory, first): the levels of a
  character's discrete chain (:mod:`lod.chains.mode`); option 0 is the
  full mesh and is the fallback of every instance. Characters without a
  chain have only option 0: their full-detail batch unchanged.
- :class:`ClustersCandidate`: the character's VDR-AM cut at the bound
  (:func:`lod.clusters.cut.cut`, then :func:`lod.clusters.mode.cull_clusters`),
  computed for every instance so that its cost is exact.
- :class:`PointsCandidate`: the Wand & Straßer point/triangle octree of the
  instance's keyframe segment traversed at the largest splat size (1 to 3
  pixels) not above the bound (half the bound when a keyframe deviation
  must fit too, :meth:`PointsCandidate.splat_size`) (:func:`lod.points.jobs.traverse_instances`),
  so that its cost is exact too. A skinned character's point hierarchies
  are built over poses baked at a few keyframes (Wand & Straßer §3:
  keyframe animations) and interpolated linearly between them, which
  departs from the skinned pose; that departure
  (:func:`keyframe_deviation`, metres) is projected like a geometric error
  and added to the splat size, so near instances whose interpolated pose
  would show are not given points.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from lod.auto.projected import _axis_scale, projected_errors, projected_errors_numpy  # noqa: F401 (re-exported)
from lod.chains import chain as tm_chain
from lod.clusters import cut as cluster_cut
from lod.drawlist import DrawBatch
from lod.points.config import POINTS_MAX_POSES, POINTS_POSE_ERROR


@dataclass
class Frame:
    """What every candidate may read about the frame being selected.

    state : the CrowdState (``anim_time``, ``clip`` are read)
    camera : lod.view.Camera; size : (w, h) pixels
    planes : (6, 4) float64 camera-relative frustum planes
    scale_px : float, pixels per metre at unit distance
    bound : float >= 0, pixels of error allowed this frame
    model : lod.auto.cost_model.CostModel
    cull : bool, frustum culling on
    """

    state: object
    camera: object
    size: tuple
    planes: np.ndarray
    scale_px: float
    bound: float
    model: object
    cull: bool = True


@dataclass
class Group:
    """One master batch: instances of one character at one clip (skinned) or
    segment (keyframed), all inside the frustum.

    char : int, index into CrowdState.character (and every candidate's rep list)
    batch : lod.drawlist.DrawBatch of the master (full-detail) selection
    rows : (k, 3, 4) float64 camera-relative model rows
    """

    char: int
    batch: DrawBatch
    rows: np.ndarray

    @property
    def k(self) -> int:
        return int(self.rows.shape[0])


@dataclass
class Options:
    """A candidate's options for one group.

    cost : (k, m) float64 predicted seconds, finite >= 0 (may be a read-only broadcast view)
    error : (k, m) float64 pixels (inf: not usable)
    plan : anything the candidate needs again in ``emit``
    labels : (m,) str names of the options for telemetry (e.g. "L3", "cut", "splat2")
    """

    cost: np.ndarray
    error: np.ndarray
    plan: object = None
    labels: tuple = ()


class Candidate:
    """Base class of the protocol (module docstring); subclasses override."""

    name = "candidate"

    def __init__(self):
        self.reps: list = []

    def options(self, frame: Frame, group: Group) -> Options | None:  # pragma: no cover - interface
        raise NotImplementedError

    def emit(self, frame: Frame, group: Group, options: Options, rows: np.ndarray, choice: np.ndarray) -> list:
        raise NotImplementedError  # pragma: no cover - interface

    def finish(self, frame: Frame, drawlist) -> None:
        return None

    def frame_cost(self, frame: Frame) -> float:
        return 0.0

    def wholes(self, frame: Frame):
        """Draws of whole groups of instances chosen before the per-instance
        choice (Wand & Straßer §3.6: a far block of hierarchical instances
        drawn from its super-hierarchy for a few points, cheaper than any
        per-instance option of its members): ``(batches, taken, seconds)``
        with ``taken`` an (n,) bool mask of the agents they represent (these
        get no per-instance option) and ``seconds`` their predicted cost;
        default ``([], None, 0.0)``: none."""
        return [], None, 0.0

    def cost_lower_bound(self, frame: Frame, group: Group):
        """(k,) float64 seconds no option of this candidate can undercut for
        the group's instances, computed without the candidate's expensive
        per-instance work; None (default): no bound, :meth:`options` is
        always called for every instance. A candidate that returns a bound
        must accept ``options(frame, group, need)`` with ``need`` a (k,) bool
        mask: only those instances need exact options; the others get
        ``cost`` = the bound and ``error`` = inf."""
        return None


def _sub(batch: DrawBatch, rows: np.ndarray):
    return batch.instance_ids[rows], batch.instance_data[rows]


# ---------------------------------------------------------------------------- triangles
class TrianglesCandidate(Candidate):
    """Levels of the discrete triangle chains (:mod:`lod.chains.mode`).

    Parameters
    ----------
    reps : the master reps, aligned with CrowdState.character:
        :class:`lod.chains.chain.TrianglesRep` (chained) or full-detail reps
    """

    name = "triangles"

    def __init__(self, reps):
        super().__init__()
        self.reps = list(reps)
        self._chains = {r.key: r for r in self.reps if isinstance(r, tm_chain.TrianglesRep)}

    def options(self, frame, group):
        r = self._chains.get(group.batch.rep)
        c = frame.model.coefficients
        if r is None:  # no chain: full detail only
            tri = float(group.batch.triangles) / max(group.k, 1)
            cost = np.full((group.k, 1), c["triangles"] * tri + c["instances"])
            return Options(cost, np.zeros((group.k, 1)), None, ("L0",))
        err = projected_errors(r.level_error, group.rows, r.clip_sphere[group.batch.part], frame.scale_px)
        cost = c["triangles"] * r.level_count.astype(np.float64) + c["instances"]
        return Options(np.broadcast_to(cost, err.shape), err, r,
                       tuple(f"L{i}" for i in range(r.n_levels)))

    def emit(self, frame, group, options, rows, choice):
        b = group.batch
        r = options.plan
        if r is None:
            ids, data = _sub(b, rows)
            return [DrawBatch(b.rep, b.part, ids, data, triangles=int(b.triangles // max(group.k, 1)) * rows.size,
                              points=0, level=0, tint=b.tint)]
        out = []
        order = np.argsort(choice, kind="stable")
        ls = choice[order]
        for L in np.unique(ls).tolist():
            sel = rows[order[ls == L]]
            n_t = int(r.level_count[L])
            ids, data = _sub(b, sel)
            out.append(tm_chain.TriangleDrawBatch(b.rep, b.part, ids, data, triangles=n_t * int(sel.size), level=int(L),
                                            tint=b.tint, index_range=(3 * int(r.level_first[L]), 3 * n_t)))
        return out


# ---------------------------------------------------------------------------- clusters
def sub_csr(offsets: np.ndarray, clusters: np.ndarray, rows: np.ndarray):
    """The CSR cuts of instances ``rows`` (in that order).

    Parameters
    ----------
    offsets : (k+1,) int64; clusters : (offsets[-1],) int32; rows : (n,) int64

    Returns
    -------
    offsets (n+1,) int64, clusters int32
    """
    rows = np.asarray(rows, np.int64)
    k = offsets.shape[0] - 1
    if rows.shape[0] == k and (k == 0 or (rows[0] == 0 and rows[-1] == k - 1 and (np.diff(rows) == 1).all())):
        return np.asarray(offsets, np.int64), np.asarray(clusters, np.int32)  # every instance, in order
    a, e = offsets[rows], offsets[rows + 1]
    n = e - a
    off = np.concatenate([[0], np.cumsum(n)]).astype(np.int64)
    if off[-1] == 0:
        return off, np.zeros(0, np.int32)
    idx = np.repeat(a - off[:-1], n) + np.arange(off[-1])
    return off, np.asarray(clusters, np.int32)[idx]


@njit(cache=True)
def _spheres_inside_kernel(rows, sph, planes, out):  # pragma: no cover - compiled
    for i in range(rows.shape[0]):
        s = _axis_scale(rows, i)
        ok = True
        for q in range(sph.shape[0]):
            rad = sph[q, 3] * s
            c0 = rows[i, 0, 0] * sph[q, 0] + rows[i, 0, 1] * sph[q, 1] + rows[i, 0, 2] * sph[q, 2] + rows[i, 0, 3]
            c1 = rows[i, 1, 0] * sph[q, 0] + rows[i, 1, 1] * sph[q, 1] + rows[i, 1, 2] * sph[q, 2] + rows[i, 1, 3]
            c2 = rows[i, 2, 0] * sph[q, 0] + rows[i, 2, 1] * sph[q, 1] + rows[i, 2, 2] * sph[q, 2] + rows[i, 2, 3]
            for p in range(planes.shape[0]):
                if not (planes[p, 0] * c0 + planes[p, 1] * c1 + planes[p, 2] * c2 + planes[p, 3] >= rad):
                    ok = False
        out[i] = ok


def spheres_inside(rows, spheres, planes) -> np.ndarray:
    """(k,) bool: every one of ``spheres`` (model space, (R, 4) centre and
    radius, scaled by the largest axis scale) lies wholly inside every
    plane (inside: n.x + d >= radius) for each instance's rows (numba).

    rows : (k, 3, 4) float64 camera-relative model rows; planes : (P, 4) float64
    """
    rows = np.ascontiguousarray(rows, np.float64).reshape(-1, 3, 4)
    out = np.empty(rows.shape[0], np.bool_)
    _spheres_inside_kernel(rows, np.ascontiguousarray(spheres, np.float64).reshape(-1, 4),
                           np.ascontiguousarray(planes, np.float64), out)
    return out


class ClustersCandidate(Candidate):
    """VDR-AM cluster cuts (:mod:`lod.clusters.mode`) at the frame's bound.

    Parameters
    ----------
    reps : list aligned with CrowdState.character: a
        :class:`lod.clusters.mode.ClustersRep` or None per character
    error_scale : float >= 1, the cut is taken at ``bound / error_scale``
        pixels (default 1: VDR-AM's own measure). Measured here, a cut at
        PoE p shows silhouette errors up to about 2-3 p against the skinned
        full-detail mesh (scripts/bench_auto.md, "Image error"), while the
        triangle chains stay at 0.25-0.8 p; a scale of 2-3 makes the
        cluster candidate's image error comparable to its bound.
    """

    name = "clusters"

    def __init__(self, reps, error_scale: float = 1.0):
        super().__init__()
        if not (math.isfinite(error_scale) and error_scale >= 1.0):
            raise ValueError(f"[lod] cluster_error_scale: expected a finite number >= 1, got {error_scale}")
        self.error_scale = float(error_scale)
        self.by_char = {i: r for i, r in enumerate(reps) if r is not None and getattr(r, "kind", "") == "clusters"}
        self.reps = list(self.by_char.values())
        self._ws = cluster_cut.CutWorkspace()
        self.clusters_drawn = 0
        self._lb = None  # (frame, group, bound array) of the last cost_lower_bound call (identity-compared)

    def cost_lower_bound(self, frame, group):
        """Seconds no cut of an instance can undercut: one skinned instance
        and one cluster record; when the spheres of the hierarchy's roots
        lie wholly inside the frustum, the roots' clusters and triangles too.

        Why the root cut bounds every cut (VDR-AM §4.3): a parent never has
        more triangles than its children together (it is their merge,
        simplified), so by induction every cut covering the mesh has at
        least the roots' triangles and one cluster per root; and no cluster
        of an instance whose root spheres are inside every plane is culled,
        since each cluster's sphere meets its root's. A partly visible
        instance may cull every triangle, hence no triangle term there."""
        r = self.by_char.get(group.char)
        if r is None or not frame.bound > 0.0 or group.k == 0:
            return None
        if self._lb is not None and self._lb[0] is frame and self._lb[1] is group:
            return self._lb[2]  # options() asks again for the same frame and group
        c = frame.model.coefficients
        lb = np.full(group.k, c["instances"] + c["clusters"])
        h = r.hierarchy
        roots = np.asarray(h.roots, np.int64)
        if roots.size == 0:
            return lb
        inside = spheres_inside(group.rows, r.sphere64[roots], frame.planes)
        root_tris = h.__dict__.get("_root_triangles")
        if root_tris is None:
            root_tris = h.__dict__["_root_triangles"] = float(h.triangle_counts()[roots].sum())
        # one cluster record is in the base already
        root_cost = c["clusters"] * (roots.size - 1) + c["triangles"] * root_tris
        lb[inside] += root_cost
        self._lb = (frame, group, lb)
        return lb

    def options(self, frame, group, need=None):
        r = self.by_char.get(group.char)
        if r is None or not frame.bound > 0.0 or group.k == 0:
            return None
        from lod.clusters.mode import cull_clusters

        h = r.hierarchy
        c = frame.model.coefficients
        sub = np.arange(group.k) if need is None else np.flatnonzero(need)
        rows = group.rows[sub]
        offsets, clusters = cluster_cut.cut(h, rows, np.zeros(3), frame.scale_px, frame.bound / self.error_scale,
                                            self._ws)
        if frame.cull and sub.size:
            offsets, clusters = cull_clusters(r.sphere64, rows, offsets, clusters, frame.planes)
        if sub.size != group.k:  # instances not asked for get an empty cut (never emitted: their error is inf)
            n = np.zeros(group.k, np.int64)
            n[sub] = np.diff(offsets)
            offsets = np.concatenate([[0], np.cumsum(n)]).astype(np.int64)
        tris = cluster_cut.cut_triangle_count(h, offsets, clusters).astype(np.float64)
        ncl = np.diff(offsets).astype(np.float64)
        cost = c["triangles"] * tris + c["clusters"] * ncl + c["instances"]
        # every drawn cluster's error projects strictly below the bound (§5.1)
        err = np.full(group.k, frame.bound)
        if sub.size != group.k:
            skip = np.ones(group.k, bool)
            skip[sub] = False
            cost[skip] = self.cost_lower_bound(frame, group)[skip]
            err[skip] = np.inf
        return Options(cost[:, None], err[:, None], (r, offsets, clusters, tris), ("cut",))

    def emit(self, frame, group, options, rows, choice):
        from lod.clusters.mode import ClusterDrawBatch

        r, offsets, clusters, tris = options.plan
        off, cl = sub_csr(offsets, clusters, rows)
        ids, data = _sub(group.batch, rows)
        self.clusters_drawn += int(cl.shape[0])
        return [ClusterDrawBatch(r.key, group.batch.part, ids, data, triangles=int(tris[rows].sum()), points=0,
                                 level=0, tint=group.batch.tint, offsets=off, clusters=cl)]

    def frame_cost(self, frame):
        return float(frame.model.coefficients["cluster_frames"])

    def finish(self, frame, drawlist):
        drawlist.stats["clusters"] = int(drawlist.stats.get("clusters", 0) or 0) + self.clusters_drawn
        self.clusters_drawn = 0
        self._lb = None


# ---------------------------------------------------------------------------- points
#: splat sizes the point renderer accepts (pixels)
SPLAT_SIZES = (1, 2, 3)


def splat_for_bound(bound: float, max_splat: int = 3) -> int:
    """The largest splat size (pixels, 1..``max_splat``) not above ``bound``; 0 when bound < 1."""
    if not bound >= 1.0:  # also NaN
        return 0
    return int(max_splat) if math.isinf(bound) else int(min(max_splat, math.floor(bound)))


class PointsCandidate(Candidate):
    """Wand & Straßer point/triangle octrees (:mod:`lod.points.mode`) at a
    splat size within the bound.

    Parameters
    ----------
    reps : list aligned with CrowdState.character: a
        :class:`lod.points.rep.PointsRep` or None per character
    master_kinds : list aligned with it: the master rep's kind per character
        ("skinned": the instance's segment and u come from its clip and
        animation time; "keyframed": the master batch part is the segment)
    max_splat : int 1..3, the largest splat size used
    deviation : list aligned with it of metres (model space), the keyframe
        interpolation's departure from the skinned pose (:func:`keyframe_deviation`;
        default 0)
    spheres : list aligned with it of (clips, 4) float64 clip bounding spheres
        (model space) the deviation is projected with (None: not needed)
    instancing : :class:`lod.points.instancing.InstancingPlan` or None: the
        super-hierarchies of the simulation's instancing groups (§3.6); far
        nodes are drawn from them as a whole (:meth:`wholes`), as mode
        points does. Only with ``points_error = "splat"`` semantics: a node
        is used when the splat size alone is within the bound (the keyframe
        deviation is not projected per node).
    """

    name = "points"

    def __init__(self, reps, master_kinds, max_splat: int = 3, deviation=None, spheres=None, instancing=None):
        super().__init__()
        self.instancing = instancing
        if int(max_splat) not in SPLAT_SIZES:
            raise ValueError(f"[lod] max_splat: expected 1, 2 or 3 pixels, got {max_splat}")
        self.by_char = {i: r for i, r in enumerate(reps) if r is not None and getattr(r, "kind", "") == "points"}
        self.reps = list(self.by_char.values())
        self.kinds = list(master_kinds)
        self.max_splat = int(max_splat)
        self.deviation = [0.0] * len(self.kinds) if deviation is None else [float(d) for d in deviation]
        self.spheres = [None] * len(self.kinds) if spheres is None else list(spheres)
        self._used = 0
        self.points_drawn = 0
        self.super_nodes = 0

    def splat_size(self, bound: float) -> int:
        """The frame's splat size at ``bound`` pixels: the largest within the
        bound, or within half of it when some character's keyframe deviation
        must fit in the other half (at least 1 when bound >= 1); 0 = none."""
        if not bound >= 1.0:
            return 0
        share = 0.5 if any(d > 0.0 for d in self.deviation) else 1.0
        return max(1, splat_for_bound(bound * share, self.max_splat))

    def options(self, frame, group):
        from lod.points.jobs import traverse_instances
        from lod.points.traverse import viewport_scale

        r = self.by_char.get(group.char)
        p = self.splat_size(frame.bound)
        if r is None or p == 0 or group.k == 0:
            return None
        b = group.batch
        if getattr(r, "follow", False):  # samples that follow the animation (lod.points.follow_select)
            return self._follow_options(frame, group, r, p)
        data = np.array(b.instance_data, np.float32)  # a copy: column 12 becomes the segment's u
        if self.kinds[group.char] == "keyframed":
            seg = np.full(group.k, int(b.part), np.int64)
        else:
            t = np.asarray(frame.state.anim_time, np.float64)[np.asarray(b.instance_ids, np.int64)]
            seg, u = r.keyframed.locate(int(b.part), t)
            data[:, 12] = u
        vs = viewport_scale(max(1, int(frame.size[1])), frame.camera.fov_y)
        ids = np.asarray(b.instance_ids)
        if seg.size and seg[0] == seg[-1] and (seg == seg[0]).all():
            order, starts, segs = None, np.array([0, group.k]), seg[:1]
        else:  # the group's rows grouped by segment (stable: each segment's rows in group order)
            order = np.argsort(seg, kind="stable")
            data, ids, seg = data[order], ids[order], seg[order]
            cut = np.flatnonzero(seg[1:] != seg[:-1]) + 1
            starts = np.concatenate([[0], cut, [group.k]])
            segs = seg[starts[:-1]]
        pts, tris = np.empty(group.k, np.int64), np.empty(group.k, np.int64)
        jobs = {}  # segment -> (first, end) of its rows in the grouped order, point jobs, triangle jobs (local rows)
        for j, s in enumerate(segs.tolist()):
            a, e = int(starts[j]), int(starts[j + 1])
            pj, tj, pts[a:e], tris[a:e] = traverse_instances(r.hierarchies[s], data[a:e], frame.planes, vs, p,
                                                             totals=True)
            jobs[s] = (a, e, pj, tj)
        if order is not None:  # totals back to group rows
            pts[order], tris[order] = pts.copy(), tris.copy()
        c = frame.model.coefficients
        cost = c["points"] * pts + c["triangles"] * tris + c["point_instances"]
        err = np.full(group.k, float(p))
        dev = self.deviation[group.char] if group.char < len(self.deviation) else 0.0
        if dev > 0.0 and self.spheres[group.char] is not None:
            err = err + projected_errors(np.array([dev]), group.rows, self.spheres[group.char][b.part],
                                         frame.scale_px)[:, 0]
        return Options(cost[:, None], err[:, None], (r, data, ids, order, jobs, pts, tris, p), (f"splat{p}",))

    def _follow_options(self, frame, group, r, p: int, traverse=None):
        """Options of a character whose samples follow the animation: its hierarchy at each copy's own pose
        (no keyframe deviation: the samples follow the skinned animation exactly). ``traverse``: the
        traversal :func:`lod.points.follow_select.follow_batch` runs (default its own)."""
        from dataclasses import replace

        from lod.points.follow_select import follow_batch
        from lod.points.traverse import viewport_scale

        b = group.batch
        data = np.array(b.instance_data, np.float32)
        if self.kinds[group.char] != "keyframed":  # the master's frame coordinate in this rep's joint table
            t = np.asarray(frame.state.anim_time, np.float64)[np.asarray(b.instance_ids, np.int64)]
            data[:, 12] = r.base.frame_coordinate(np.full(group.k, int(b.part)), t)
        vs = viewport_scale(max(1, int(frame.size[1])), frame.camera.fov_y)
        fb = follow_batch(r, replace(b, rep=r.key, instance_data=data), frame.planes, vs, p, traverse=traverse)
        c = frame.model.coefficients
        cost = c["points"] * fb.inst_points + c["triangles"] * fb.inst_triangles + c["point_instances"]
        err = np.full(group.k, float(p))
        return Options(cost[:, None], err[:, None], ("follow", r, fb, p), (f"splat{p}",))

    def emit(self, frame, group, options, rows, choice):
        from lod.points.rep import PointsBatch

        if options.plan[0] == "follow":
            from lod.points.follow_select import subset

            _, r, fb, p = options.plan
            out = subset(r, fb, rows)
            if out is None:
                return []
            out.tint = group.batch.tint
            self.points_drawn += out.points
            self._used = max(self._used, int(p))
            return [out]
        r, data, ids, order, jobs, pts, tris, p = options.plan
        b = group.batch
        every = rows.shape[0] == group.k  # rows are distinct: all chose points (a far crowd), no mask needed
        if not every:
            take = np.zeros(group.k, bool)
            take[rows] = True
            if order is not None:
                take = take[order]  # in the grouped order of data and ids
        out = []
        for s, (a, e, pj, tj) in sorted(jobs.items()):
            sel = None if every else take[a:e]
            if every or sel.all():  # every instance of the segment chose points: its rows and jobs as they are
                d, i = data[a:e], ids[a:e]
            else:
                if not sel.any():
                    continue
                d, i = data[a:e][sel], ids[a:e][sel]
                local = np.cumsum(sel) - 1  # segment row -> row among the chosen ones
                pj = pj[sel[pj[:, 0]]].copy()
                tj = tj[sel[tj[:, 0]]].copy()
                pj[:, 0] = local[pj[:, 0]]
                tj[:, 0] = local[tj[:, 0]]
            n_p = int(pj[:, 2].sum()) if pj.size else 0
            n_t = int(tj[:, 2].sum()) if tj.size else 0
            self.points_drawn += n_p
            out.append(PointsBatch(r.key, int(s), i, d, triangles=n_t, points=n_p, level=0, tint=b.tint,
                                   point_jobs=pj, tri_jobs=tj))
        self._used = max(self._used, int(p))
        return out

    def frame_cost(self, frame):
        from lod.auto.cost_model import pass_cost

        p = self.splat_size(frame.bound)
        return pass_cost(frame.model, frame.size, p) if p else 0.0

    def wholes(self, frame):
        """The far nodes of the instancing groups that mode points at this
        splat size draws from their super-hierarchies (§3.6,
        :meth:`lod.points.instancing.InstancingPlan.select`)."""
        from lod.points.mode import super_batches
        from lod.points.traverse import viewport_scale

        p = self.splat_size(frame.bound)
        st = frame.state
        if self.instancing is None or p == 0 or not getattr(st, "n", 0) or any(d > 0.0 for d in self.deviation):
            return [], None, 0.0
        vs = viewport_scale(max(1, int(frame.size[1])), frame.camera.fov_y)
        draws, flat = self.instancing.select(st, np.asarray(frame.camera.position, np.float64), frame.planes, vs, p)
        if not draws:
            return [], None, 0.0
        out = super_batches(draws, frame.planes, vs, p)
        c = frame.model.coefficients
        pts = sum(b.points for b in out)
        self.points_drawn += pts
        self.super_nodes += sum(b.n_instances for b in out)
        self._used = max(self._used, int(p))
        seconds = c["points"] * pts + c["point_instances"] * sum(b.n_instances for b in out) + c["batches"] * len(out)
        return out, ~np.asarray(flat, bool), float(seconds)

    def finish(self, frame, drawlist):
        if self._used:
            drawlist.options["splat_size"] = self._used
        drawlist.stats["points"] = int(drawlist.stats.get("points", 0) or 0) + self.points_drawn
        if self.super_nodes:
            drawlist.stats["super_nodes"] = int(self.super_nodes)
        self._used = 0
        self.points_drawn = 0
        self.super_nodes = 0


def keyframe_deviation(character, keyframes: int, pose_error: float = POINTS_POSE_ERROR,
                       max_keyframes: int = POINTS_MAX_POSES) -> float:
    """Metres (model space) by which linear interpolation between the poses
    mode "points" bakes per clip departs from the skinned animation: the
    largest pose error over every clip (:func:`lod.points.poses.clip_poses`,
    sampled densely in time; a clip's own jump at its loop point is not
    counted).

    Parameters
    ----------
    character : sim.character.SkinnedCharacter (0.0 for any other kind)
    keyframes : int >= 0, poses baked per clip (0: the fewest within ``pose_error``)
    pose_error, max_keyframes : the bound and cap of ``keyframes = 0``

    Returns
    -------
    float >= 0, finite
    """
    if getattr(character, "kind", "") != "skinned" or not character.mesh.is_skinned:
        return 0.0
    from lod.points.poses import clip_poses

    worst = max((cp.error for cp in clip_poses(character, keyframes, pose_error, max_keyframes).values()),
                default=0.0)
    return worst if np.isfinite(worst) else 0.0


@dataclass
class Telemetry:
    """Per-frame counts: instances per (candidate, option label)."""

    counts: dict = field(default_factory=dict)

    def add(self, name: str, label: str, n: int) -> None:
        if n:
            key = f"{name}:{label}"
            self.counts[key] = self.counts.get(key, 0) + int(n)


__all__ = ["Candidate", "ClustersCandidate", "Frame", "Group", "Options", "PointsCandidate", "SPLAT_SIZES",
           "Telemetry", "TrianglesCandidate", "keyframe_deviation", "projected_errors", "projected_errors_numpy",
           "splat_for_bound", "sub_csr"]
