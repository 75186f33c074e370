"""Hierarchical instantiation of point hierarchies (Wand & Straßer 2002, §3.6).

"We construct multi-resolution hierarchies out of a set of multi-resolution
sub-hierarchies [...] We allow not only triangles to be inserted in the data
structure but also sample points [...] each sample point is assigned a weight
proportional to the area it represents [...] the area of the original model
[...] divided by the amount of sample points."

The simulation describes a crowd as a tree (``sim.instancing.Hierarchy``:
levels innermost first, any depth); a node at depth d >= 1 holds
``prod(counts[:d])`` instances of one animated character, and every node of a
depth is the same arrangement with the same relative phase pattern, shifted in
time by the node's offset (``sim.instancing``: child i of a level is offset
by ``i * phase_step`` mod the period). So one *super-hierarchy* per (group,
depth) serves every node of that depth:

Build (:func:`build_super`), per depth d = 1 .. depth:

1. Source points. Every instance of one node (node-local transforms of
   ``levels[:d]``) contributes ``k`` random area-proportional surface samples
   of the character (§3.4.1 sampling, barycentric, so they follow the
   animation), ``k`` chosen so that the source spacing is a quarter of the
   finest spacing the super-hierarchy needs; weight = instance area / k (§3.6).
   Each source takes its instance's colours under that agent's colour-variation
   word (``lod.variation``; the words of the group's first node), so a node's
   filtered colour is the mean of the agents it stands for (§3.5 over every
   instance), not the colours of the one agent whose word its draw would carry.
2. Time. The node's pattern is periodic with the group's period P (a multiple
   of the clip's duration). It is cut into S super-segments (S = the clip's
   keyframe segments times P / duration); at the super-keyframe times
   T_s = s P / S every source point's position, normal and colour are those
   of its instance at clip time ``T_s + offset_i`` (the character's keyframes
   interpolated there). Within a super-segment the points move linearly (the
   paper's super-hierarchy is a keyframe animation with its own, possibly
   larger, number of keyframes).
3. Octree per super-segment (:func:`build_point_octree`): the build of
   ``lod.points.octree`` with weighted points in place of triangles: spacing
   ``r = min(fraction * max side, r_parent / 2)`` (§3.1, §3.3), candidates
   drawn with probability proportional to weight (§3.4.1, n ln n times the
   safety factor, all sources when that is more), stratification (§3.4.2,
   ``lod.points.stratify``; one time interval by default, :data:`SUPER_INTERVALS`),
   attributes Gaussian-filtered
   over the node's weighted sources at both ends (§3.5,
   ``lod.points.filter.gaussian_filter``). Subdivision stops at ``r <= 1.5 r_stop``
   (the coarsest spacing of the representation one depth below: the children's
   super-hierarchy, or the character's octree roots for d = 1); those leaves
   keep their stratified points.

Selection (:class:`InstancingPlan`), per frame, top-down over each group's
tree, vectorised over the nodes of a depth: a node whose box (the union over
all super-segments of its super-hierarchy's root box, transformed) is outside
the frustum is culled; if the projected spacing of its finest leaves is at
most the splat size it is drawn from its super-hierarchy (the octree traversed
as usual at the node's super-segment and u, with the node's model matrix);
else its children are visited, and at depth 0 the instances go to the
per-instance path of ``lod.points.mode``. Before that, the group's agents in
the CrowdState are checked against the tree (positions, headings, scales,
character, clip, and the relative phase pattern); a group that the simulation
has moved away from its tree is drawn flat.

Departures: the sources are fresh random samples on the instances' triangles,
not the stratified points of their octrees (the octrees of different segments
hold different points; surface samples can be evaluated at any clip time);
the paper's text leaves the choice open. Inside a super-segment a source point
moves linearly even where its instance passes a keyframe.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import numpy as np
from numba import njit

from lod.full.pack import model_rows
from lod.full.reps import KeyframedRep
from lod.points import config as C
from lod.points.filter import gaussian_filter
from lod.points.octree import ATTR_DTYPE, PointHierarchy
from lod.points.sampling import candidate_count, max_area, sample_triangles, triangle_vertices
from lod.points.stratify import interval_times, stratify
from lod.variation import vary

#: version of the super-hierarchy build (part of its cache key)
SUPER_FORMAT = 3  # 3: source colours under their agents' variation words; principal-axis normals
#: a super-octree node with at most this many source points is a leaf keeping them all
LEAF_POINTS = 8
#: a super-octree node with spacing r <= LEAF_SLACK * r_stop is a leaf (a level more would go below r_stop)
LEAF_SLACK = 1.5
#: source spacing as a fraction of the finest spacing the super-hierarchy needs
SOURCE_FRACTION = 0.25
#: largest number of source points per instance
MAX_SOURCE_PER_INSTANCE = 4096
#: largest number of source points of one super-hierarchy node (a guard; more instances get fewer each)
MAX_SOURCE_POINTS = 400_000
#: stratification time intervals of a super-hierarchy's segment: the sources are
#: animated characters, whose area hardly changes (§5.1: "For animated characters,
#: time discretization is not necessary"); one interval stores a third of the points of three
SUPER_INTERVALS = 1
#: at most this many super-segments per period
MAX_SUPER_SEGMENTS = 64
#: tolerance (metres, radians, seconds) of the per-frame check of a group's agents against its tree
CHECK_TOL = 1e-3


# ---------------------------------------------------------------------------- weighted point octree
def build_point_octree(p0, p1, c0, c1, n0, n1, weights, *, r_stop: float,
                       spacing_fraction: float = C.POINTS_SPACING_FRACTION, safety: float = C.POINTS_SAFETY_FACTOR,
                       intervals: int = C.POINTS_TIME_INTERVALS, filter_sigma: float = C.POINTS_FILTER_SIGMA,
                       max_depth: int = C.POINTS_MAX_DEPTH, seed: int = 0) -> PointHierarchy:
    """Octree of stratified, filtered samples of weighted moving points (§3.6
    with §3.1, §3.3-§3.5).

    Parameters
    ----------
    p0, p1 : (N, 3) float positions of the source points at u = 0 and u = 1
    c0, c1 : (N, 4) float colours; n0, n1 : (N, 3) float unit normals at u = 0, 1
    weights : (N,) float >= 0, area each source point represents (m^2)
    r_stop : float > 0, a node with spacing r <= ``LEAF_SLACK * r_stop`` is a
        leaf (keeps its stratified points, at least ``min(r_stop, r_parent / 2)``
        apart); so is a node of at most :data:`LEAF_POINTS` sources (keeps them
        all, spacing ``min(r, r_stop)``)
    spacing_fraction, safety, intervals, filter_sigma, max_depth : as in
        ``lod.points.octree.build_hierarchy``
    seed : int, all randomness derives from it

    Returns
    -------
    PointHierarchy with points at inner nodes *and* leaves, no triangles
    (``tri``, ``bary``, ``indices`` and ``tri_order`` empty: the points refer
    to no triangle).

    Raises
    ------
    ValueError for mismatched shapes, non-finite input, r_stop <= 0 or intervals < 1.
    """
    p0 = np.asarray(p0, np.float64).reshape(-1, 3)
    p1 = np.asarray(p1, np.float64).reshape(-1, 3)
    N = p0.shape[0]
    c0 = np.asarray(c0, np.float64).reshape(N, 4)
    c1 = np.asarray(c1, np.float64).reshape(N, 4)
    n0 = np.asarray(n0, np.float64).reshape(N, 3)
    n1 = np.asarray(n1, np.float64).reshape(N, 3)
    w = np.asarray(weights, np.float64).reshape(-1)
    if p1.shape != p0.shape or w.shape != (N,):
        raise ValueError(f"build_point_octree: p0, p1 (N, 3) and weights (N,) must agree, got {p0.shape}, "
                         f"{p1.shape}, {w.shape}")
    if not all(np.isfinite(a).all() for a in (p0, p1, c0, c1, n0, n1, w)) or (w < 0).any():
        raise ValueError("build_point_octree: inputs must be finite and weights >= 0")
    if not r_stop > 0.0 or int(intervals) < 1 or not 0.0 < spacing_fraction <= 1.0:
        raise ValueError(f"build_point_octree: need r_stop > 0, intervals >= 1, spacing_fraction in (0, 1], got "
                         f"{r_stop}, {intervals}, {spacing_fraction}")
    m = int(intervals)
    rng = np.random.default_rng([int(seed), 0x3606])
    times = interval_times(m)
    keep_ids = w > 0.0
    ids0 = np.flatnonzero(keep_ids)
    if ids0.size:
        root_lo = p0[ids0].min(0)
        side = float((p0[ids0].max(0) - root_lo).max())
    else:
        root_lo, side = np.zeros(3), 0.0
    root_side = max(side, 1e-9)
    eps_len = C.POINTS_EPS ** 0.5 * root_side

    nodes = []
    chunks = []  # (interval, ids, col0, col1, nrm0, nrm1)
    queue = [(ids0, root_lo, root_side, 0, np.inf, -1)]
    head = 0
    n_points = 0
    while head < len(queue):
        ids, cube_lo, cube_side, depth, r_parent, parent = queue[head]
        me = head
        head += 1
        nd = dict(parent=parent, depth=depth, child_start=0, child_count=0,
                  point_start=np.zeros(m, np.int64), point_count=np.zeros(m, np.int64))
        if ids.size:
            b0 = np.stack([p0[ids].min(0), p0[ids].max(0)])
            b1 = np.stack([p1[ids].min(0), p1[ids].max(0)])
        else:
            b0 = np.stack([cube_lo, cube_lo])
            b1 = b0.copy()
        nd["box0"], nd["box1"] = b0, b1
        maxside = float(max((b0[1] - b0[0]).max(), (b1[1] - b1[0]).max()))
        r = min(spacing_fraction * maxside, 0.5 * r_parent)
        few = ids.size <= LEAF_POINTS or r <= eps_len or depth >= max_depth
        leaf = few or r <= LEAF_SLACK * r_stop
        if few:
            # keep every source point (nothing finer exists); spacing at most r_stop
            nd["spacing"] = float(min(max(r, 0.0), r_stop))
            for j in range(m):
                chunks.append((me, j, ids, c0[ids], c1[ids], n0[ids], n1[ids]))
        else:
            if leaf:  # nothing finer below: stratify as coarsely as the level below allows
                r = max(r, min(r_stop, 0.5 * r_parent))
            nd["spacing"] = r
            ww = w[ids]
            ncand = candidate_count(float(ww.sum()), r, safety)
            if ncand >= ids.size:
                cand = ids
            else:
                cand = np.unique(rng.choice(ids, size=ncand, p=ww / ww.sum()))
            pos = (1.0 - times)[:, None, None] * p0[cand][None] + times[:, None, None] * p1[cand][None]
            keep = stratify(pos, r, rng.permutation(cand.size))
            anyk = np.flatnonzero(keep.any(0))
            sig = filter_sigma * r
            rep = cand[anyk]
            fc0, fn0 = gaussian_filter(p0[rep], p0[ids], c0[ids], n0[ids], ww, sig, c0[rep], n0[rep])
            fc1, fn1 = gaussian_filter(p1[rep], p1[ids], c1[ids], n1[ids], ww, sig, c1[rep], n1[rep])
            slot = np.full(cand.size, -1, np.int64)
            slot[anyk] = np.arange(anyk.size)
            for j in range(m):
                sel = np.flatnonzero(keep[j])
                s = slot[sel]
                chunks.append((me, j, cand[sel], fc0[s], fc1[s], fn0[s], fn1[s]))
        if not leaf:
            half = 0.5 * cube_side
            mid = cube_lo + half
            oct_ = ((p0[ids] >= mid) * np.array([4, 2, 1])).sum(1)
            children = []
            for o in range(8):
                sel = ids[oct_ == o]
                if sel.size:
                    clo = cube_lo + half * np.array([(o >> 2) & 1, (o >> 1) & 1, o & 1])
                    children.append((sel, clo, half, depth + 1, r, me))
            nd["child_start"] = len(queue)
            nd["child_count"] = len(children)
            queue.extend(children)
        nodes.append(nd)

    # points grouped by node, then interval (chunks are appended in that order)
    src, cols0, cols1, nrms0, nrms1, owner = [], [], [], [], [], []
    for me, j, sel, a0, a1, b0_, b1_ in chunks:
        nodes[me]["point_start"][j] = n_points
        nodes[me]["point_count"][j] = sel.size
        n_points += sel.size
        src.append(sel)
        cols0.append(a0)
        cols1.append(a1)
        nrms0.append(b0_)
        nrms1.append(b1_)
        owner.append(np.full(sel.size, me, np.int32))

    def cat(xs, shape):
        return np.concatenate(xs) if xs else np.zeros(shape)

    sidx = cat(src, (0,)).astype(np.int64)
    Nn = len(nodes)

    def col(key, dtype):
        return np.array([nd[key] for nd in nodes], dtype)

    return PointHierarchy(
        child_start=col("child_start", np.int32), child_count=col("child_count", np.int32),
        parent=col("parent", np.int32), depth=col("depth", np.int32),
        box0=np.array([nd["box0"] for nd in nodes], np.float64).reshape(Nn, 2, 3),
        box1=np.array([nd["box1"] for nd in nodes], np.float64).reshape(Nn, 2, 3),
        spacing=col("spacing", np.float64),
        point_start=np.array([nd["point_start"] for nd in nodes], np.int64).reshape(Nn, m),
        point_count=np.array([nd["point_count"] for nd in nodes], np.int64).reshape(Nn, m),
        tri_start=np.zeros(Nn, np.int64), tri_count=np.zeros(Nn, np.int64),
        pos0=p0[sidx].astype(np.float32), pos1=p1[sidx].astype(np.float32),
        nrm0=cat(nrms0, (0, 3)).astype(ATTR_DTYPE), nrm1=cat(nrms1, (0, 3)).astype(ATTR_DTYPE),
        col0=cat(cols0, (0, 4)).astype(ATTR_DTYPE), col1=cat(cols1, (0, 4)).astype(ATTR_DTYPE),
        tri=np.zeros(0, np.int32), bary=np.zeros((0, 2), np.float32),  # no triangle references
        node=cat(owner, (0,)).astype(np.int32), tri_order=np.zeros(0, np.int32),
        indices=np.zeros((0, 3), np.int64), intervals=m,
        params=dict(kind="super", r_stop=float(r_stop), spacing_fraction=float(spacing_fraction),
                    safety=float(safety), intervals=m, filter_sigma=float(filter_sigma), max_depth=int(max_depth),
                    seed=int(seed)),
    )


# ---------------------------------------------------------------------------- the character's surface over a clip
@dataclass
class ClipSurface:
    """The triangles of one looping clip of a keyframed character, evaluable at
    any clip time (all segments must share one triangle list).

    kf : KeyframedRep; clip : int
    tris : (T, 3) int64 segment-local corner indices (the same in every segment)
    vbase : (S,) int64 first vertex of each segment of the clip
    areas : (T,) float64 largest area of each triangle over the clip (m^2)
    """

    kf: KeyframedRep
    clip: int
    tris: np.ndarray
    vbase: np.ndarray
    areas: np.ndarray

    @property
    def area(self) -> float:
        return float(self.areas.sum())

    def evaluate(self, t, tri, bary):
        """Positions (n, 3), unit normals (n, 3) and colours (n, 4), float64,
        of surface samples (tri (n,), bary (n, 2)) at clip times t (n,)."""
        kf = self.kf
        seg, u = kf.locate(self.clip, np.asarray(t, np.float64))
        a0 = int(kf.anim_first_seg[self.clip])
        v = self.vbase[seg - a0][:, None] + self.tris[tri]  # (n, 3) vertex rows
        u = u[:, None, None]
        b = np.asarray(bary, np.float64)
        wts = np.stack([1.0 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)[:, :, None]

        def at(a0_, a1_):
            x = (1.0 - u) * a0_[v].astype(np.float64) + u * a1_[v].astype(np.float64)
            return (wts * x).sum(1)

        pos = at(kf.positions0, kf.positions1)
        nrm = at(kf.normals0, kf.normals1)
        ln = np.linalg.norm(nrm, axis=1, keepdims=True)
        nrm = np.where(ln > 1e-12, nrm / np.where(ln > 1e-12, ln, 1.0), np.array([0.0, 1.0, 0.0]))
        col = np.clip(at(kf.colors0, kf.colors1), 0.0, 1.0)
        return pos, nrm, col


def clip_surface(kf: KeyframedRep, clip: int) -> ClipSurface | None:
    """The :class:`ClipSurface` of ``clip``, or None when the clip's segments
    differ in triangles (then its instances cannot share a super-hierarchy)."""
    if not 0 <= clip < kf.n_clips:
        return None
    a0, ns = int(kf.anim_first_seg[clip]), int(kf.anim_n_segs[clip])
    tris, vbase, areas = None, [], None
    for s in range(a0, a0 + ns):
        f, c = int(kf.seg_first[s]) // 3, int(kf.seg_count[s]) // 3
        idx = kf.indices[f:f + c].astype(np.int64)
        if idx.size == 0:
            return None
        lo = int(idx.min())
        loc = idx - lo
        if tris is None:
            tris = loc
        elif loc.shape != tris.shape or not np.array_equal(loc, tris):
            return None
        vbase.append(lo)
        p0 = np.asarray(kf.positions0, np.float64)
        p1 = np.asarray(kf.positions1, np.float64)
        a, _ = max_area(triangle_vertices(p0, idx), triangle_vertices(p1, idx))
        areas = a if areas is None else np.maximum(areas, a)
    if tris is None or not np.isfinite(areas).all() or areas.sum() <= 0.0:
        return None
    return ClipSurface(kf, int(clip), tris, np.asarray(vbase, np.int64), areas)


# ---------------------------------------------------------------------------- super-hierarchies
@dataclass
class SuperHierarchy:
    """The super-hierarchy of every node at one depth of one instancing group.

    rep : lod.points.rep.PointsRep, one octree per super-segment (its
        ``keyframed`` holds no vertices); drawn like any point rep
    group, depth : int; period : float seconds; segments : int (S)
    r_leaf : float, largest spacing of a leaf over all super-segments (node frame)
    r_root : float, smallest root spacing over all super-segments
    box : (2, 3) float64 union of the root boxes over all super-segments (node frame)
    n_source : int, source points per super-segment
    """

    rep: object
    group: int
    depth: int
    period: float
    segments: int
    r_leaf: float
    r_root: float
    box: np.ndarray
    n_source: int


def _sub_transforms(levels, depth: int, period: float):
    """Node-local translation (n, 3), yaw (n,), scale (n,), offset (n,) of the
    instances of one node at ``depth`` (the levels below it)."""
    from sim.instancing import Hierarchy

    return Hierarchy(list(levels[:depth]), period=period).node_transforms(0)


def empty_keyframed(key: str, parts: int) -> KeyframedRep:
    """A KeyframedRep with no vertices and ``parts`` empty segments (super reps
    draw points only; the drawer asks each part for its triangles)."""
    z3 = np.zeros((0, 3), np.float32)
    z4 = np.zeros((0, 4), np.float32)
    zp = np.zeros(int(parts), np.int64)
    return KeyframedRep(key=key, positions0=z3, positions1=z3.copy(), normals0=z3.copy(), normals1=z3.copy(),
                        colors0=z4, colors1=z4.copy(), indices=np.zeros((0, 3), np.uint32), seg_first=zp,
                        seg_count=zp.copy(), seg_start=np.zeros(int(parts)), seg_end=np.zeros(int(parts)),
                        seg_aabb=np.zeros((int(parts), 2, 3), np.float32), seg_sphere=np.zeros((int(parts), 4)),
                        anim_names=[], anim_first_seg=np.zeros(0, np.int64), anim_n_segs=np.zeros(0, np.int64),
                        anim_duration=np.zeros(0), anim_loop=np.zeros(0, bool), anim_t0=np.zeros(0))


def super_key(surface: ClipSurface, levels, depth: int, period: float, segments: int, r_stop: float,
              params: dict, variation=None) -> str:
    """sha256 content key of one super-hierarchy (inputs, parameters and the instances' variation words)."""
    h = hashlib.sha256()
    h.update(f"points-super/{SUPER_FORMAT}".encode())
    kf = surface.kf
    for a in (kf.positions0, kf.positions1, kf.normals0, kf.normals1, kf.colors0, kf.colors1, kf.indices,
              kf.seg_start, kf.seg_end, surface.tris, surface.vbase):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    for lv in levels[:depth]:
        for a in (lv.translation, lv.yaw, lv.scale, lv.time_offset):
            h.update(np.ascontiguousarray(a, np.float64).tobytes())
    h.update(json.dumps(dict(params, clip=surface.clip, depth=depth, period=period, segments=segments,
                             r_stop=float(r_stop)), sort_keys=True).encode())
    if variation is not None:
        h.update(b"variation")
        h.update(np.ascontiguousarray(variation, np.uint32).tobytes())
    return h.hexdigest()


def build_super(surface: ClipSurface, levels, depth: int, period: float, r_stop: float, *, group: int = 0,
                name: str = "crowd", intervals: int = SUPER_INTERVALS,
                spacing_fraction: float = C.POINTS_SPACING_FRACTION, segments: int | None = None, cache=None,
                seed: int = 0, splat_size: int = 2, renderer: str = "compute", variation=None) -> SuperHierarchy:
    """Super-hierarchy of the nodes at ``depth`` of a tree (§3.6; see the module docstring).

    Parameters
    ----------
    surface : ClipSurface of the leaf character's clip
    levels : list of sim.instancing.Level, innermost first (``levels[:depth]``
        arrange one node)
    depth : int >= 1
    period : float seconds, the tree's period (a multiple of the clip's duration)
    r_stop : float > 0, the coarsest spacing one depth below (node frame)
    group, name : label the representation key ``points:super:<name>:g<group>:d<depth>``
    intervals : stratification intervals per super-segment (§3.4.2; default
        :data:`SUPER_INTERVALS`); spacing_fraction : §3.1
    segments : super-segments per period (default: the clip's segments x period / duration)
    cache : lod.points.rep.HierarchyCache or None
    seed : int
    variation : None or (n,) uint32, the colour-variation word (``lod.variation``) of each of a node's
        n instances: every source point takes its instance's varied colour (and a variation mask of 0),
        so a node's filtered colours are the mean of the agents it stands for, not one agent's
        (its draws get no word of their own: ``render.tint.PREVARIED``)

    Returns
    -------
    SuperHierarchy
    """
    from lod.points.rep import PointsRep

    kf = surface.kf
    dur = float(kf.anim_duration[surface.clip])
    if segments is None:
        reps_ = max(1, int(round(period / dur))) if dur > 0 else 1
        segments = min(MAX_SUPER_SEGMENTS, int(kf.anim_n_segs[surface.clip]) * reps_)
    S = max(1, int(segments))
    params = dict(intervals=int(intervals), spacing_fraction=float(spacing_fraction), seed=int(seed),
                  source_fraction=SOURCE_FRACTION)
    t, yaw, sc, off = _sub_transforms(levels, depth, period)
    n_inst = t.shape[0]
    if variation is not None:
        variation = np.ascontiguousarray(variation, np.uint32).reshape(-1)
        if variation.shape[0] != n_inst:
            raise ValueError(f"build_super: variation holds {variation.shape[0]} words for {n_inst} instances")
        if not variation.any():
            variation = None
    key = super_key(surface, levels, depth, period, S, r_stop, params, variation)
    hs = None
    if cache is not None:
        got = [cache.load(f"{key}-{s}") for s in range(S)]
        if all(g is not None for g in got):
            hs = got
            cache.hits += 1
    s_src = SOURCE_FRACTION * r_stop
    k = int(np.clip(np.ceil(surface.area / (s_src * s_src)), 1, MAX_SOURCE_PER_INSTANCE))
    k = int(max(1, min(k, MAX_SOURCE_POINTS // max(1, n_inst))))
    if hs is None:
        if cache is not None:
            cache.misses += 1
        rng = np.random.default_rng([int(seed), 0x36, depth])
        tri, bary = sample_triangles(surface.areas, k * n_inst, rng)
        perm = rng.permutation(tri.size)  # the samples come sorted by triangle: deal them out at random
        tri, bary = tri[perm], bary[perm]
        inst = np.repeat(np.arange(n_inst), k)
        wts = surface.area * sc[inst] ** 2 / k
        c, s_ = np.cos(yaw[inst]), np.sin(yaw[inst])
        src_words = None if variation is None else variation[inst]  # each source's agent's word
        frames = []
        for q in range(S + 1):
            p, nrm, col = surface.evaluate(q * period / S + off[inst], tri, bary)
            x, z = p[:, 0].copy(), p[:, 2].copy()
            p = np.stack([c * x + s_ * z, p[:, 1], -s_ * x + c * z], 1) * sc[inst][:, None] + t[inst]
            nx, nz = nrm[:, 0].copy(), nrm[:, 2].copy()
            nrm = np.stack([c * nx + s_ * nz, nrm[:, 1], -s_ * nx + c * nz], 1)
            if src_words is not None:  # each source in its own agent's colours, varied once (mask 0 after)
                col = np.concatenate([vary(col, src_words), np.zeros((col.shape[0], 1))], 1)
            frames.append((p, nrm, col))
        hs = []
        for q in range(S):
            (pa, na, ca), (pb, nb, cb) = frames[q], frames[q + 1]
            h = build_point_octree(pa, pb, ca, cb, na, nb, wts, r_stop=r_stop, intervals=intervals,
                                   spacing_fraction=spacing_fraction, seed=int(seed) * 1000 + q)
            hs.append(h)
            if cache is not None:
                try:
                    cache.store(f"{key}-{q}", h)
                except OSError:
                    pass
    rkey = f"points:super:{name}:g{group}:d{depth}"
    rep = PointsRep(rkey, empty_keyframed(rkey, S), hs, int(splat_size), str(renderer))
    leaf = [h.spacing[h.child_count == 0].max() if (h.child_count == 0).any() else 0.0 for h in hs]
    box = np.stack([np.stack([np.minimum(h.box0[0, 0], h.box1[0, 0]) for h in hs]).min(0),
                    np.stack([np.maximum(h.box0[0, 1], h.box1[0, 1]) for h in hs]).max(0)])
    return SuperHierarchy(rep, int(group), int(depth), float(period), S, float(max(leaf)),
                          float(min(h.spacing[0] for h in hs)), box, k * n_inst)


# ---------------------------------------------------------------------------- per-frame plan
@dataclass
class _Group:
    first: int
    hier: object  # sim.instancing.Hierarchy
    supers: list  # SuperHierarchy per depth 1..D
    flat: object  # CrowdState of the tree
    node_t: list  # per depth d (0..D): (N_d, 3) world translation
    node_yaw: list
    node_s: list
    node_off: list


def _corners(box):
    lo, hi = box
    return np.array([[lo[0] if (k >> 2) & 1 == 0 else hi[0], lo[1] if (k >> 1) & 1 == 0 else hi[1],
                      lo[2] if k & 1 == 0 else hi[2]] for k in range(8)])


@njit(cache=True)
def _check_kernel(character, clip, position, scale, heading, anim_time, t_character, t_clip, t_position, t_scale,
                  t_heading, t_anim_time, period, tol):  # pragma: no cover - numba (check_reference is the reference)
    """True when n agents match a tree's n instances (InstancingPlan.check):
    same character and clip (the tree's ints), positions
    (n, 3) and scales within ``tol``, headings within ``tol`` modulo 2 pi, and
    the relative phase pattern anim_time - t_anim_time constant within ``tol``
    modulo ``period``. Non-finite values fail."""
    n = position.shape[0]
    two_pi = 2.0 * np.pi
    rel0 = 0.0
    for i in range(n):
        if character[i] != t_character or clip[i] != t_clip:
            return False
        for c in range(3):
            d = abs(np.float64(position[i, c]) - np.float64(t_position[i, c]))
            if not d <= tol:
                return False
        if not abs(np.float64(scale[i]) - np.float64(t_scale[i])) <= tol:
            return False
        dh = np.float64(heading[i]) - np.float64(t_heading[i]) + np.pi
        dh = dh - two_pi * np.floor(dh / two_pi) - np.pi
        if not abs(dh) <= tol:
            return False
        rel = np.float64(anim_time[i]) - np.float64(t_anim_time[i])
        if i == 0:
            rel0 = rel
        d = rel - rel0 + 0.5 * period
        d = d - period * np.floor(d / period) - 0.5 * period
        if not abs(d) <= tol:
            return False
    return True


class InstancingPlan:
    """The super-hierarchies of a scene's instancing groups and the per-frame
    top-down choice between them and the instances (§3.6).

    Parameters
    ----------
    groups : list of (first_agent, sim.instancing.Hierarchy, [SuperHierarchy per depth 1..D])
    """

    def __init__(self, groups):
        self.groups: list[_Group] = []
        for first, h, supers in groups:
            nt, ny, ns, no = [], [], [], []
            for d in range(h.depth + 1):
                t, yaw, s, off = h.node_transforms(d)
                nt.append(t)
                ny.append(yaw)
                ns.append(s)
                no.append(off)
            self.groups.append(_Group(int(first), h, list(supers), h.flatten(), nt, ny, ns, no))

    @property
    def reps(self) -> list:
        return [s.rep for g in self.groups for s in g.supers]

    def check(self, g: _Group, state) -> bool:
        """True when the group's agents still are the tree's instances (see the
        module docstring); one pass of the numba kernel :func:`_check_kernel`
        (the same answer as :meth:`check_reference`)."""
        a, n = g.first, g.hier.n_instances
        if a + n > state.n:
            return False
        f = g.flat
        sl = slice(a, a + n)
        return bool(_check_kernel(np.ascontiguousarray(state.character[sl]), np.ascontiguousarray(state.clip[sl]),
                                  np.ascontiguousarray(state.position[sl]), np.ascontiguousarray(state.scale[sl]),
                                  np.ascontiguousarray(state.heading[sl]), np.ascontiguousarray(state.anim_time[sl]),
                                  int(g.hier.character), int(g.hier.clip),
                                  np.ascontiguousarray(f.position), np.ascontiguousarray(f.scale),
                                  np.ascontiguousarray(f.heading), np.ascontiguousarray(f.anim_time),
                                  float(g.hier.period), CHECK_TOL))

    def check_reference(self, g: _Group, state) -> bool:
        """numpy reference of :meth:`check`."""
        a, n = g.first, g.hier.n_instances
        if a + n > state.n:
            return False
        f = g.flat
        sl = slice(a, a + n)
        if not (np.all(np.asarray(state.character[sl]) == g.hier.character)
                and np.all(np.asarray(state.clip[sl]) == g.hier.clip)):
            return False
        if not np.allclose(state.position[sl], f.position, rtol=0.0, atol=CHECK_TOL):
            return False
        if not np.allclose(state.scale[sl], f.scale, rtol=0.0, atol=CHECK_TOL):
            return False
        dh = np.mod(np.asarray(state.heading[sl], np.float64) - f.heading + np.pi, 2 * np.pi) - np.pi
        if not (np.abs(dh) <= CHECK_TOL).all():
            return False
        P = g.hier.period
        rel = np.asarray(state.anim_time[sl], np.float64) - f.anim_time
        with np.errstate(invalid="ignore"):  # non-finite times fail below
            d = np.mod(rel - rel[0] + 0.5 * P, P) - 0.5 * P
        return bool(np.isfinite(d).all() and (np.abs(d) <= CHECK_TOL).all())

    def select(self, state, origin, planes, vscale: float, splat: float):
        """This frame's super-hierarchy draws and the agents left to the per-instance path.

        Parameters
        ----------
        state : sim.state.CrowdState; origin : (3,) float64 camera position;
        planes : (6, 4) float64 camera-relative frustum planes; vscale : pixels
        per metre at depth 1; splat : splat size in pixels

        Returns
        -------
        draws : list of (SuperHierarchy, segment (k,) int64, data (k, 16) float32, first agent ids (k,) int32,
            instances represented (k,) int64)
        flat : (n,) bool, agents to draw per instance (every agent outside
            a valid group, and the instances whose nodes were all refined)
        """
        n = state.n
        flat = np.ones(n, bool)
        draws = []
        origin = np.asarray(origin, np.float64)
        fwd = planes[4, :3]
        for g in self.groups:
            h = g.hier
            if not g.supers or not self.check(g, state):
                continue
            a, ni = g.first, h.n_instances
            flat[a:a + ni] = False
            base = float(state.anim_time[a]) - float(g.flat.anim_time[0])
            active = np.zeros(1, np.int64)
            for d in range(h.depth, 0, -1):
                if active.size == 0:
                    break
                sup = g.supers[d - 1]
                t = g.node_t[d][active] - origin
                yaw, s = g.node_yaw[d][active], g.node_s[d][active]
                cs = _corners(sup.box)  # (8, 3)
                c, sn = np.cos(yaw), np.sin(yaw)
                wx = (c[:, None] * cs[None, :, 0] + sn[:, None] * cs[None, :, 2]) * s[:, None] + t[:, None, 0]
                wy = cs[None, :, 1] * s[:, None] + t[:, None, 1]
                wz = (-sn[:, None] * cs[None, :, 0] + c[:, None] * cs[None, :, 2]) * s[:, None] + t[:, None, 2]
                W = np.stack([wx, wy, wz], -1)  # (k, 8, 3)
                dist = W @ planes[:, :3].T + planes[:, 3]  # (k, 8, 6)
                culled = (dist < 0.0).all(1).any(1)
                dmin = (W @ fwd).min(1)
                coarse_ok = (dmin > 0.0) & (sup.r_leaf * np.abs(s) * vscale <= splat * np.where(dmin > 0, dmin, 1.0))
                use = ~culled & coarse_ok
                if use.any():
                    nodes = active[use]
                    local = np.mod(base + g.node_off[d][nodes], sup.period)
                    x = local / sup.period * sup.segments
                    seg = np.clip(np.floor(x).astype(np.int64), 0, sup.segments - 1)
                    u = np.clip(x - seg, 0.0, 1.0)
                    data = np.zeros((nodes.size, 16), np.float32)
                    data[:, :12] = model_rows(t[use], yaw[use], s[use])
                    data[:, 12] = u
                    m = h.instances_per_node(d)
                    draws.append((sup, seg, data, (a + nodes * m).astype(np.int32), np.full(nodes.size, m, np.int64)))
                down = active[~culled & ~coarse_ok]
                k = h.counts[d - 1]
                active = (down[:, None] * k + np.arange(k)[None, :]).reshape(-1)
            flat[a + active] = True
        return draws, flat
