"""Octree of prefiltered point samples and triangles for one keyframe pair
(Wand & Straßer 2002, §3.1 and §3.3).

Build, top-down, for the vertices moving linearly from ``p0`` (u = 0) to
``p1`` (u = 1) of one segment of a keyframe animation:

1. Root: the bounding cube of the triangles at the start keyframe (§3.3: the
   construction is applied to the first keyframe).
2. A node holding at most ``leaf_triangles`` triangles is a leaf and stores
   them without sampling (§3.1).
3. Otherwise its remaining triangles are sampled (§3.4.1 candidates by maximum
   area, §3.4.2 stratification per time interval, §3.5 filtering) with the
   spacing ``r = fraction * max side of the node's start and end boxes``
   (§3.3). Triangles that receive more than ``triangle_samples`` kept points
   (in any interval) are stored at the node as triangles and leave the sampling
   below (§3.1).
4. The other triangles go to the child cube holding their centre (at the start
   keyframe) if they exceed it by at most ``loose * child side``, else they
   are stored at this node (§3.1, after Wand et al. 2001).
5. Every node keeps its start and end axis-aligned bounding box (of all the
   triangles of its subtree), interpolated linearly at render time (§3.3).

Nodes are finished one by one in breadth-first order (the node numbering),
and drawn ahead of that in the same order (boxes, spacing, every random
draw), so the random numbers are those of a plain node-by-node build; the
stratification (one work item per time interval,
``lod.points.stratify.stratify_async``) and the filtering of the drawn nodes
run meanwhile in worker threads, which release the GIL. The hierarchy is the
same for any thread count.

Departures:

* Spacing: ``r = min(fraction * max side, r_parent / 2)``. The paper takes the
  box-based value, which only guarantees that r does not grow downwards; the
  extra clamp makes r at least halve per level, as the traversal of §3.2
  assumes ("reduced to the half if we step from one node to its child").
* Points lying on triangles that get stored at the node are kept (the paper
  stores those triangles "also"), so a node drawn as points represents its
  whole subtree on its own.
* "Receives a sample" counts the *kept* samples (after stratification), the
  ones that would be drawn; the maximum over the time intervals is used.
* Candidates per time interval: the set is drawn once by the maximum areas over
  the keyframe pair; each interval stratifies a random subset thinned to the
  candidate count and area distribution of its own maximum areas
  (:func:`lod.points.sampling.interval_thinning`), which is what §3.4.1 would
  draw for that interval alone. A shrinking surface's late intervals otherwise
  stratify a set many times denser than their area needs, and the greedy rule
  keeps more points from a denser set. One interval: the whole set, as before.

Data layout (structure of arrays, ready for numba and GPU upload): nodes in
breadth-first order with contiguous children; per node a point range for each
time interval (points kept in several intervals are stored once per interval)
and one range into ``tri_order``.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from sim.atomic_io import atomic_open
from lod.points import config as C
from lod.points.filter import filter_points, filter_set
from lod.points.sampling import (
    candidate_count,
    interval_areas,
    interval_thinning,
    max_area,
    sample_triangles,
    triangle_vertices,
)
from lod.points.stratify import choose_interval_times, interval_times, stratify_async, worker_count

#: storage type of the points' filtered colours and normals (see PointHierarchy)
ATTR_DTYPE = np.float16
#: candidates of the nodes drawn ahead of the one being finished (their
#: stratification runs in the worker threads meanwhile); bounds the memory
PIPELINE_CANDIDATES = 1_000_000
#: the same with ``poses`` (each candidate held at K poses): a few dozen nodes keep two threads busy
PIPELINE_POSED_CANDIDATES = 100_000


@dataclass
class PointHierarchy:
    """Point-sample/triangle octree of one keyframe pair (flat SoA arrays).

    Nodes (N, breadth-first; node 0 is the root; children contiguous):

    child_start : (N,) int32, index of the first child (0 when none)
    child_count : (N,) int32, number of children (0 for a leaf)
    parent : (N,) int32, -1 for the root
    depth : (N,) int32, 0 for the root
    box0, box1 : (N, 2, 3) float64, [lo, hi] bounding box of the subtree's
        triangles at u = 0 and u = 1 (model space)
    spacing : (N,) float64, maximum sample distance r of the node's points
        (0 for leaves, which have none)
    point_start, point_count : (N, m) int64, range of the node's points for
        each time interval (``interval_of(u, m)``)
    tri_start, tri_count : (N,) int64, range of the node's triangles in
        ``tri_order``

    Points (P):

    pos0, pos1 : (P, 3) float32 positions at u = 0 and u = 1
    nrm0, nrm1 : (P, 3) float16 filtered unit normals at u = 0 and 1
    col0, col1 : (P, 4) float16 filtered colours at u = 0 and 1 (float16:
        ~5e-4 precision, below the GPU's RGBA8 colours; files written before
        hold float32, which loads as well)
    tri : (P,) int32 triangle the sample lies on; bary : (P, 2) float32
        barycentric weights of its corners 1 and 2
    node : (P,) int32 owning node

    Triangles:

    tri_order : (T_stored,) int32 triangle ids (rows of ``indices``) grouped
        by node; every input triangle appears exactly once.
    indices : (T, 3) int64 the segment's index buffer
    intervals : int, number of time intervals m
    params : dict of the build parameters
    interval_bounds : (m + 1,) float64 boundaries of the intervals in [0, 1]
        (``lod.points.stratify.choose_interval_times``); None = equal
    """

    child_start: np.ndarray
    child_count: np.ndarray
    parent: np.ndarray
    depth: np.ndarray
    box0: np.ndarray
    box1: np.ndarray
    spacing: np.ndarray
    point_start: np.ndarray
    point_count: np.ndarray
    tri_start: np.ndarray
    tri_count: np.ndarray
    pos0: np.ndarray
    pos1: np.ndarray
    nrm0: np.ndarray
    nrm1: np.ndarray
    col0: np.ndarray
    col1: np.ndarray
    tri: np.ndarray
    bary: np.ndarray
    node: np.ndarray
    tri_order: np.ndarray
    indices: np.ndarray
    intervals: int
    params: dict = field(default_factory=dict)
    interval_bounds: np.ndarray | None = None

    @property
    def n_nodes(self) -> int:
        return int(self.child_start.shape[0])

    @property
    def n_points(self) -> int:
        return int(self.pos0.shape[0])

    @property
    def nbytes(self) -> int:
        """Bytes of all arrays (the data structure size)."""
        return int(sum(v.nbytes for v in self.__dict__.values() if isinstance(v, np.ndarray)))

    def points_at(self, node: int, u: float) -> slice:
        """Slice of the points node ``node`` draws at time u."""
        from lod.points.stratify import interval_of

        j = interval_of(u, self.intervals, self.interval_bounds)
        s = int(self.point_start[node, j])
        return slice(s, s + int(self.point_count[node, j]))

    @property
    def bounds(self) -> np.ndarray:
        """(m + 1,) float64 interval boundaries (equal when none were chosen)."""
        if self.interval_bounds is None:
            return interval_times(self.intervals)
        return np.asarray(self.interval_bounds, np.float64)

    def box_at(self, u: float) -> np.ndarray:
        """(N, 2, 3) float64 interpolated node boxes at time u (§3.3)."""
        return (1.0 - u) * self.box0 + u * self.box1


# --------------------------------------------------------------------------- kernels

@njit(cache=True, nogil=True)
def _positions_kernel(v0, v1, tri, bary, times, out):  # pragma: no cover - compiled
    n = tri.shape[0]
    for t in range(times.shape[0]):
        u = times[t]
        w = 1.0 - u
        for i in range(n):
            k = tri[i]
            b1 = bary[i, 0]
            b2 = bary[i, 1]
            b0 = 1.0 - b1 - b2
            for c in range(3):
                a = w * v0[k, 0, c] + u * v1[k, 0, c]
                b = w * v0[k, 1, c] + u * v1[k, 1, c]
                d = w * v0[k, 2, c] + u * v1[k, 2, c]
                out[t, i, c] = b0 * a + b1 * b + b2 * d
    return out


@njit(cache=True, nogil=True)
def _posed_positions_kernel(VK, tri, bary, out):  # pragma: no cover - compiled
    for q in range(VK.shape[0]):
        for i in range(tri.shape[0]):
            k = tri[i]
            b1 = bary[i, 0]
            b2 = bary[i, 1]
            b0 = 1.0 - b1 - b2
            for c in range(3):
                out[q, i, c] = b0 * VK[q, k, 0, c] + b1 * VK[q, k, 1, c] + b2 * VK[q, k, 2, c]
    return out


def sample_positions_posed(VK, tri, bary) -> np.ndarray:
    """(K, N, 3) float64 positions of barycentric samples on triangles ``tri`` (ids into VK's T) at each of
    the K poses of ``VK`` (K, T, 3, 3) (numba; equals :func:`sample_positions_at` per pose)."""
    out = np.empty((VK.shape[0], np.asarray(tri).shape[0], 3))
    if out.size:
        _posed_positions_kernel(VK, np.ascontiguousarray(tri, np.int64), np.ascontiguousarray(bary, np.float64), out)
    return out


def sample_positions_at(v0, v1, tri, bary, times) -> np.ndarray:
    """(len(times), N, 3) float64 positions of barycentric samples (numba)."""
    times = np.ascontiguousarray(times, np.float64).reshape(-1)
    out = np.empty((times.shape[0], tri.shape[0], 3))
    if tri.shape[0]:
        _positions_kernel(v0, v1, np.ascontiguousarray(tri, np.int64), np.ascontiguousarray(bary, np.float64),
                          times, out)
    return out


# --------------------------------------------------------------------------- build

class _Node:
    """Work record of one node during :func:`build_hierarchy`."""

    def __init__(self, tris, cube_lo, cube_side, depth, r_parent, parent):
        self.tris = tris  # (t,) int64 the node's triangles (rows of the index buffer)
        self.cube_lo, self.cube_side = cube_lo, cube_side  # octree cube (§3.1)
        self.depth, self.r_parent, self.parent = depth, r_parent, parent
        self.box0 = self.box1 = None
        self.r = 0.0
        self.leaf = True
        self.ctri = self.cbary = None  # candidates (§3.4.1)
        self.fcount, self.fset = 0, None  # filter set F (§3.5)
        self.pending = None  # lod.points.stratify.stratify_async handle
        self.pos = self.keep = self.anyk = self.filtered = None

    def positions(self, V0, V1, times, VK=None):
        """``at(j)``: (2, N, 3) candidate positions at the ends of interval j,
        computed for all the boundaries by the first work item that asks
        (thread-safe) and dropped by :meth:`filter`. With ``VK`` (K, T, 3, 3),
        the triangle corners at K poses (``build_hierarchy(poses=...)``, one
        interval): (K, N, 3) the candidates at every pose."""
        lock = threading.Lock()

        def at(j):
            with lock:
                if self.pos is None:
                    if VK is None:
                        self.pos = sample_positions_at(V0[self.tris], V1[self.tris], self.ctri, self.cbary, times)
                    else:
                        self.pos = sample_positions_posed(VK, self.tris[self.ctri], self.cbary)
                return self.pos if VK is not None else self.pos[j:j + 2]
        return at

    def filter(self, keep, V0, V1, CC0, CC1, NN0, NN1, areas, sigma):
        """Store the stratification ``keep`` and filter the kept points (§3.5)."""
        self.keep = keep
        self.pos = None
        t = self.tris
        self.anyk = np.flatnonzero(self.keep.any(0))
        self.filtered = filter_points(V0[t], V1[t], CC0[t], CC1[t], NN0[t], NN1[t], areas[t],
                                      self.ctri[self.anyk], self.cbary[self.anyk], self.r, None,
                                      self.fcount, sigma, f_set=self.fset)


def _check_inputs(p0, p1, indices, c0, c1, n0, n1):
    p0 = np.asarray(p0, np.float64)
    p1 = np.asarray(p1, np.float64)
    if p0.ndim != 2 or p0.shape[1] != 3 or p1.shape != p0.shape:
        raise ValueError(f"build_hierarchy: p0 and p1 must both be (V, 3), got {p0.shape} and {p1.shape}")
    if not (np.isfinite(p0).all() and np.isfinite(p1).all()):
        raise ValueError("build_hierarchy: p0/p1 must be finite, got NaN or Inf")
    idx = np.asarray(indices, np.int64).reshape(-1, 3)
    V = p0.shape[0]
    if idx.size and (idx.min() < 0 or idx.max() >= V):
        raise ValueError(f"build_hierarchy: indices must lie in 0..{V - 1}, got {idx.min()}..{idx.max()}")

    def attr(a, width, default):
        if a is None:
            return np.broadcast_to(np.asarray(default, np.float64), (V, width)).copy()
        a = np.asarray(a, np.float64)
        if a.shape != (V, width) or not np.isfinite(a).all():
            raise ValueError(f"build_hierarchy: per-vertex attributes must be finite ({V}, {width}), got {a.shape}")
        return a

    c0 = attr(c0, 4, (0.8, 0.8, 0.8, 1.0))
    c1 = attr(c1, 4, c0) if c1 is not None else c0
    n0 = attr(n0, 3, (0.0, 1.0, 0.0))
    n1 = attr(n1, 3, n0) if n1 is not None else n0
    return p0, p1, idx, c0, c1, n0, n1


def build_hierarchy(p0, p1, indices, c0=None, c1=None, n0=None, n1=None, *,
                    spacing_fraction: float = C.POINTS_SPACING_FRACTION,
                    triangle_samples: int = C.POINTS_TRIANGLE_SAMPLES,
                    leaf_triangles: int = C.POINTS_LEAF_TRIANGLES,
                    loose: float = C.POINTS_LOOSE_FRACTION,
                    safety: float = C.POINTS_SAFETY_FACTOR,
                    intervals: int = C.POINTS_TIME_INTERVALS,
                    filter_factor: float = C.POINTS_FILTER_FACTOR,
                    filter_sigma: float = C.POINTS_FILTER_SIGMA,
                    max_depth: int = C.POINTS_MAX_DEPTH,
                    seed: int = 0, adaptive_intervals: bool = True,
                    progress: bool | None = None, threads: int | None = None,
                    poses=None, areas=None) -> PointHierarchy:
    """Build the point/triangle octree of one keyframe pair (§3.1, §3.3-3.5).

    Parameters
    ----------
    p0, p1 : (V, 3) float positions at the start (u = 0) and end (u = 1)
    indices : (T, 3) int index buffer into the V vertices
    c0, c1 : (V, 4) float colours at start/end (default light grey; c1
        defaults to c0)
    n0, n1 : (V, 3) float normals at start/end (default +Y; n1 defaults to n0)
    spacing_fraction : r as a fraction of the node's larger box side, (0, 1]
        (paper 1/8..1/16)
    triangle_samples : k >= 0; a triangle with more than k kept samples is
        stored as a triangle (paper 1..3)
    leaf_triangles : >= 1, leaf size (paper 50)
    loose : >= 0, child-cube tolerance as a fraction of its side (paper 0.1)
    safety : > 0, coupon-collector factor (paper 3..5)
    intervals : >= 1, stratification time intervals (paper 3..5)
    filter_factor : > 0, size of F per bin (see ``lod.points.filter``)
    filter_sigma : > 0, Gaussian sigma as a fraction of r
    max_depth : octree depth limit
    seed : int, all randomness derives from it (same seed, same hierarchy)
    adaptive_intervals : choose the interval boundaries by the area change
        (``lod.points.stratify.choose_interval_times``; equal when that gains
        under 1%, as for animated characters) or always equal intervals
    progress : show a tqdm bar (None: only if the build takes over a second)
    poses : None, or (K, V, 3) float positions of the vertices at K poses
        (``lod.points.follow``: samples that follow an animation): one
        interval (``intervals`` must be 1) whose stratification keeps a
        candidate unless another covers it at every pose, and whose node
        spacing is a fraction of the largest box side over p0 and the poses;
        p0 is the pose the octree cells, boxes and filtered attributes are
        taken at (p1 is ignored: the start and the end are p0)
    areas : None or (T,) float sampling weights of the candidates and of the
        filter set in place of the maximum areas over p0 -> p1 (§3.4.1: the
        largest area a triangle takes over the animation)
    threads : worker threads of the stratification and filtering (None:
        ``lod.points.stratify.worker_count``); the result does not depend on it

    Returns
    -------
    PointHierarchy

    Raises
    ------
    ValueError naming the argument and what is accepted.
    """
    p0, p1, idx, c0, c1, n0, n1 = _check_inputs(p0, p1, indices, c0, c1, n0, n1)
    if not 0.0 < spacing_fraction <= 1.0:
        raise ValueError(f"build_hierarchy: spacing_fraction must be in (0, 1], got {spacing_fraction}")
    if int(intervals) < 1 or int(leaf_triangles) < 1 or int(triangle_samples) < 0:
        raise ValueError("build_hierarchy: intervals and leaf_triangles must be >= 1 and triangle_samples >= 0, "
                         f"got {intervals}, {leaf_triangles}, {triangle_samples}")
    if not (safety > 0.0 and filter_factor > 0.0 and filter_sigma > 0.0 and loose >= 0.0):
        raise ValueError("build_hierarchy: safety, filter_factor and filter_sigma must be > 0 and loose >= 0")
    m = int(intervals)
    rng = np.random.default_rng([int(seed), 0x5753])
    T = idx.shape[0]
    V0 = triangle_vertices(p0, idx)
    if poses is None:
        V1 = triangle_vertices(p1, idx)
        CC0, CC1 = c0[idx], c1[idx]
        NN0, NN1 = n0[idx], n1[idx]
    else:  # one pose (p1 is p0): the start and end arrays are the same ones
        V1, CC0, NN0 = V0, c0[idx], n0[idx]
        CC1, NN1 = CC0, NN0
    if poses is not None:
        poses = np.asarray(poses, np.float64)
        if poses.ndim != 3 or poses.shape[0] < 1 or poses.shape[1:] != p0.shape or not np.isfinite(poses).all():
            raise ValueError(f"build_hierarchy: poses must be finite (K, {p0.shape[0]}, 3), got {poses.shape}")
        if m != 1:
            raise ValueError(f"build_hierarchy: poses need intervals = 1, got {m}")
    # (K, T, 3, 3) float32: the candidates' positions at the K poses only decide coverage at spacings >> 1e-7
    VK = None if poses is None else np.stack([triangle_vertices(p, idx).astype(np.float32) for p in poses])
    if areas is None:
        areas, _ = max_area(V0, V1)
    else:
        areas = np.asarray(areas, np.float64).reshape(-1)
        if areas.shape != (idx.shape[0],) or not np.isfinite(areas).all() or (areas < 0.0).any():
            raise ValueError(f"build_hierarchy: areas must be {idx.shape[0]} finite values >= 0")
    tlo0, thi0 = V0.min(1), V0.max(1)
    tlo1, thi1 = (tlo0, thi0) if V1 is V0 else (V1.min(1), V1.max(1))
    centre = V0.mean(1)
    times = choose_interval_times(V0, V1, m) if adaptive_intervals else interval_times(m)
    A_int = interval_areas(V0, V1, times) if m > 1 else None

    if T:
        root_lo = tlo0.min(0)
        side = float((thi0.max(0) - root_lo).max())
    else:
        root_lo, side = np.zeros(3), 0.0
    root_side = max(side, 1e-9)
    eps_len = C.POINTS_EPS ** 0.5 * root_side

    nodes = []  # dicts in BFS order
    pts = {k: [] for k in ("tri", "bary", "col0", "col1", "nrm0", "nrm1", "node")}
    tri_chunks = []
    queue = [_Node(np.arange(T, dtype=np.int64), root_lo.astype(np.float64), root_side, 0, np.inf, -1)]
    drawn = 0  # queue[:drawn] have their boxes and random draws, and are being stratified
    ahead = 0  # candidates of the drawn nodes not finished yet
    n_points = 0
    n_tris = 0
    workers = worker_count(threads)

    bar = None
    t_start = time.perf_counter()
    show = progress

    def filtered(nd):  # in the thread that stratified the node's last interval
        return lambda keep: nd.filter(keep, V0, V1, CC0, CC1, NN0, NN1, areas, filter_sigma)

    # The nodes are finished in breadth-first order (the node numbering) in
    # this thread, and drawn ahead of that in the same order, so the random
    # draws are those of a plain node-by-node build; the stratification and
    # filtering of the drawn nodes run meanwhile in the worker threads
    me = 0
    while me < len(queue):
        # 1. boxes, spacing and the random draws of §3.4.1/§3.5 of the next
        #    nodes, then their stratification (§3.4.2) and filtering (§3.5)
        while drawn < len(queue) and (drawn == me or ahead < (PIPELINE_CANDIDATES if VK is None else
                                                             PIPELINE_POSED_CANDIDATES)):
            nd = queue[drawn]
            drawn += 1
            tris = nd.tris
            if tris.size:
                nd.box0 = np.stack([tlo0[tris].min(0), thi0[tris].max(0)])
                nd.box1 = np.stack([tlo1[tris].min(0), thi1[tris].max(0)])
            else:
                nd.box0 = np.stack([nd.cube_lo, nd.cube_lo])
                nd.box1 = nd.box0.copy()
            maxside = float(max((nd.box0[1] - nd.box0[0]).max(), (nd.box1[1] - nd.box1[0]).max()))
            if VK is not None and tris.size:  # the largest box over the poses too (§3.3 generalised)
                for v in VK:
                    vt = v[tris].reshape(-1, 3)
                    maxside = max(maxside, float((vt.max(0) - vt.min(0)).max()))
            nd.r = min(spacing_fraction * maxside, 0.5 * nd.r_parent)
            nd.leaf = tris.size <= leaf_triangles or nd.depth >= max_depth or nd.r <= eps_len
            if nd.leaf:
                continue
            a = areas[tris]
            ctri, cbary = sample_triangles(a, candidate_count(float(a.sum()), nd.r, safety), rng)
            if ctri.size:
                nd.ctri, nd.cbary = ctri, cbary
                order = rng.permutation(ctri.size)
                eligible = None
                if m > 1:  # each interval stratifies the candidates its own areas call for (§3.4.1)
                    thin = interval_thinning(a, A_int[:, tris], nd.r, safety)
                    eligible = rng.random(ctri.size) < thin[:, ctri]
                h = nd.r * C.POINTS_BIN_RATIO
                nd.fcount = int(min(filter_factor * int(np.ceil(a.sum() / (h * h))), C.POINTS_MAX_CANDIDATES))
                nd.fset = filter_set(a, nd.fcount, rng)
                ahead += ctri.size
                nd.pending = stratify_async((m, nd.positions(V0, V1, times, VK)), nd.r, order, workers,
                                            on_done=filtered(nd), eligible=eligible)
        # 2. stored triangles, children and points of node me
        if bar is None and (show or (show is None and time.perf_counter() - t_start > 1.0)):
            from tqdm.auto import tqdm

            bar = tqdm(total=T, desc="point hierarchy", unit="tri", initial=n_tris, leave=False)
        nd = queue[me]
        if nd.pending is not None:
            nd.pending.result()
            nd.pending = None
            ahead -= nd.ctri.size
        tris = nd.tris
        rec = dict(parent=nd.parent, depth=nd.depth, child_start=0, child_count=0,
                   point_start=np.zeros(m, np.int64), point_count=np.zeros(m, np.int64),
                   box0=nd.box0, box1=nd.box1, spacing=0.0 if nd.leaf else nd.r)
        stored = np.zeros(tris.size, bool)
        if nd.leaf:
            stored[:] = True
        else:
            if nd.keep is not None:
                got = np.zeros(tris.size, np.int64)
                for j in range(m):
                    got = np.maximum(got, np.bincount(nd.ctri[nd.keep[j]], minlength=tris.size))
                stored = got > triangle_samples
            # distribute the rest among the children (§3.1)
            rest = np.flatnonzero(~stored)
            half = 0.5 * nd.cube_side
            mid = nd.cube_lo + half
            oct_ = ((centre[tris[rest]] >= mid) * np.array([4, 2, 1])).sum(1)
            tol = loose * half
            clo = nd.cube_lo + half * np.array([(oct_ >> 2) & 1, (oct_ >> 1) & 1, oct_ & 1]).T
            fits = ((tlo0[tris[rest]] >= clo - tol) & (thi0[tris[rest]] <= clo + half + tol)).all(1)
            stored[rest[~fits]] = True
            rest, oct_, clo = rest[fits], oct_[fits], clo[fits]
            children = []
            for o in range(8):
                sel = oct_ == o
                if sel.any():
                    children.append(_Node(tris[rest[sel]], clo[sel][0], half, nd.depth + 1, nd.r, me))
            if children:
                rec["child_start"] = len(queue)
                rec["child_count"] = len(children)
                queue.extend(children)
                # the points represent the subtree; a node whose triangles all
                # stay here is drawn as triangles only and keeps no points
                if nd.keep is not None:
                    slot = np.full(nd.ctri.size, -1, np.int64)
                    slot[nd.anyk] = np.arange(nd.anyk.size)
                    fc0, fc1, fn0, fn1 = nd.filtered
                    for j in range(m):
                        sel = np.flatnonzero(nd.keep[j])
                        s = slot[sel]
                        cnt = sel.size
                        rec["point_start"][j] = n_points
                        rec["point_count"][j] = cnt
                        n_points += cnt
                        for key, val in (("tri", tris[nd.ctri[sel]]), ("bary", nd.cbary[sel]),
                                         ("col0", fc0[s]), ("col1", fc1[s]), ("nrm0", fn0[s]), ("nrm1", fn1[s]),
                                         ("node", np.full(cnt, me, np.int32))):
                            pts[key].append(val)
            else:
                rec["spacing"] = 0.0
        mine = tris[stored]
        rec["tri_start"] = n_tris
        rec["tri_count"] = mine.size
        tri_chunks.append(mine)
        n_tris += mine.size
        nodes.append(rec)
        queue[me] = None  # its arrays are no longer needed
        me += 1
        if bar is not None:
            bar.update(mine.size)
    if bar is not None:
        bar.close()

    N = len(nodes)

    def col(key, dtype):
        return np.array([nd[key] for nd in nodes], dtype)

    def cat(key, shape, dtype):
        return np.concatenate(pts[key]).astype(dtype) if pts[key] else np.zeros(shape, dtype)

    tri_p = cat("tri", (0,), np.int64)
    bary_p = cat("bary", (0, 2), np.float64)
    h = PointHierarchy(
        child_start=col("child_start", np.int32), child_count=col("child_count", np.int32),
        parent=col("parent", np.int32), depth=col("depth", np.int32),
        box0=np.array([nd["box0"] for nd in nodes], np.float64).reshape(N, 2, 3),
        box1=np.array([nd["box1"] for nd in nodes], np.float64).reshape(N, 2, 3),
        spacing=col("spacing", np.float64),
        point_start=np.array([nd["point_start"] for nd in nodes], np.int64).reshape(N, m),
        point_count=np.array([nd["point_count"] for nd in nodes], np.int64).reshape(N, m),
        tri_start=col("tri_start", np.int64), tri_count=col("tri_count", np.int64),
        pos0=sample_positions_at(V0, V1, tri_p, bary_p, [0.0])[0].astype(np.float32),
        pos1=sample_positions_at(V0, V1, tri_p, bary_p, [1.0])[0].astype(np.float32),
        nrm0=cat("nrm0", (0, 3), ATTR_DTYPE), nrm1=cat("nrm1", (0, 3), ATTR_DTYPE),
        col0=cat("col0", (0, 4), ATTR_DTYPE), col1=cat("col1", (0, 4), ATTR_DTYPE),
        tri=tri_p.astype(np.int32), bary=bary_p.astype(np.float32), node=cat("node", (0,), np.int32),
        tri_order=(np.concatenate(tri_chunks) if tri_chunks else np.zeros(0, np.int64)).astype(np.int32),
        indices=idx, intervals=m, interval_bounds=np.asarray(times, np.float64),
        params=dict(spacing_fraction=spacing_fraction, triangle_samples=int(triangle_samples),
                    leaf_triangles=int(leaf_triangles), loose=float(loose), safety=float(safety),
                    intervals=m, filter_factor=float(filter_factor), filter_sigma=float(filter_sigma),
                    max_depth=int(max_depth), seed=int(seed)),
    )
    return h


def build_segment(animation, k: int, **kw) -> PointHierarchy:
    """Hierarchy of segment k of a ``sim.keyframes.KeyframeAnimation`` (§3.3).

    Positions, colours and normals of the segment's vertices at the start and
    end keyframes (``src``/``dst`` correspondences) feed :func:`build_hierarchy`;
    keyword arguments are passed on.
    """
    seg = animation.segments[k]
    a, b = animation.segment_keyframes(k)
    src = np.asarray(seg.src, np.int64)
    dst = np.asarray(seg.dst, np.int64)
    return build_hierarchy(np.asarray(a.positions, np.float64)[src], np.asarray(b.positions, np.float64)[dst],
                           np.asarray(seg.indices, np.int64),
                           np.asarray(a.colors, np.float64)[src], np.asarray(b.colors, np.float64)[dst],
                           np.asarray(a.normals, np.float64)[src], np.asarray(b.normals, np.float64)[dst], **kw)


# --------------------------------------------------------------------------- files

_FORMAT = 1


def save_hierarchy(h: PointHierarchy, path) -> None:
    """Write ``h`` to an ``.npz`` file atomically (:func:`sim.atomic_io.atomic_open`).

    The file holds every array of :class:`PointHierarchy` plus ``intervals``,
    the build parameters (JSON) and a format number; see
    :func:`load_hierarchy`.
    """
    import json

    arrays = {k: v for k, v in h.__dict__.items() if isinstance(v, np.ndarray)}
    meta = json.dumps({"format": _FORMAT, "intervals": int(h.intervals), "params": h.params})
    with atomic_open(path, "wb") as f:
        np.savez(f, __meta__=np.frombuffer(meta.encode(), np.uint8), **arrays)


def load_hierarchy(path) -> PointHierarchy:
    """Read a hierarchy written by :func:`save_hierarchy`.

    Raises
    ------
    ValueError naming the file when it is unreadable, of another format or
    missing arrays (a cache should then rebuild it).
    """
    import json

    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["__meta__"]).decode())
            if meta.get("format") != _FORMAT:
                raise ValueError(f"{path}: point hierarchy format {meta.get('format')}, expected {_FORMAT}")
            names = [f for f in PointHierarchy.__dataclass_fields__
                     if f not in ("intervals", "params", "interval_bounds")]
            arrays = {k: z[k] for k in names}
            if "interval_bounds" in z.files:  # files of before the unequal intervals hold none: equal
                arrays["interval_bounds"] = z["interval_bounds"]
    except Exception as e:  # a damaged file can fail anywhere in zipfile/numpy (EOFError, NotImplementedError, ...)
        if isinstance(e, ValueError) and str(e).startswith(str(path)):
            raise
        raise ValueError(f"{path}: not a readable point hierarchy file ({type(e).__name__}: {e})") from None
    m = int(meta["intervals"])
    b = arrays.get("interval_bounds")
    if b is not None and (b.shape != (m + 1,) or not np.isfinite(b).all() or b[0] != 0.0 or b[-1] != 1.0
                          or (np.diff(b) <= 0).any()):
        raise ValueError(f"{path}: interval_bounds must be {m + 1} increasing times from 0 to 1")
    return PointHierarchy(**arrays, intervals=m, params=dict(meta["params"]))
