"""The point candidate of mode auto over flat arrays of all instances (issue 26, item 2).

:meth:`lod.auto.candidates.PointsCandidate.options` works group by group: it copies the group's
instance data, locates every instance's keyframe segment (Wand & Straßer §3: a point hierarchy per
keyframe pair), sorts the group's rows by segment and traverses each segment's hierarchy for its
instances (§3.2, :func:`lod.points.jobs.traverse_instances`). Here the same work is done for the
instances of every group at once:

1. :func:`_locate_kernel`: every instance's segment and time ``u`` within it (the clip's table, as
   :meth:`lod.full.reps.KeyframedRep.locate`), and its *bin*: (group, segment), numbered group-major;
2. a stable counting sort by bin (:func:`_bin_counts`, :func:`_bin_scatter`: chunks of instances in
   parallel, each from its exclusive prefix), which writes the sorted copy of the instance data with
   ``u`` in column 12 (float32, as the per-group copy holds it): every group's rows grouped by segment in
   group order, the segments in order, exactly the per-group ``order``;
3. :func:`traverse`: one pass of the job writer (:func:`lod.points.jobs.write_jobs`, parallel in chunks of
   instances) over all sorted instances, each traversing the hierarchy of its bin's segment (the
   hierarchies of every character's segments concatenated into one :class:`Forest`), the root decided in
   line where it settles the instance (the far crowd's common case), writing point and triangle jobs
   (instance row within its segment, first, count) in instance order (the per-segment job tables are its
   slices);
4. the price of every instance's option (points, triangles, cost, error) is computed with the other
   candidates' rows in one pass (:func:`lod.auto.flat._rows_kernel`).

A character whose samples follow the animation (:mod:`lod.points.follow`: one hierarchy, node boxes in
joint frames, each copy at its own baked row) is not in the forest: its groups are traversed one call each
by :func:`lod.points.jobs.follow_traverse` (the same writer on that one hierarchy).

Every value is computed by the same expressions as the per-group path (the traversal is the same writer,
:func:`lod.points.jobs.traverse_instances` per segment there), so the options, job tables and sorted data
are identical (tests/lod/auto/test_auto_flat.py, tests/lod/points/test_points_jobs.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from lod.points.coarse import coarse_arrays
from lod.points.jobs import write_jobs
from lod.points.traverse import NO_JOINTS

#: job rows per instance the traversal of a forest reserves at first (then what it needed; doubled until the
#: jobs fit)
JOBS_PER_INSTANCE = 2


@dataclass
class Forest:
    """The segment hierarchies of every character of the point candidate, concatenated.

    node0 : (H + 1,) int64 first node of each hierarchy (its nodes' child indices are its own);
    the node arrays as :func:`lod.points.jobs.hierarchy_arrays` gives them, rows of all hierarchies;
    point_start, point_count : (nodes, J) int64, J the most intervals of any hierarchy;
    bounds : (H, J + 1) float64 interval boundaries, ``intervals`` (H,) int64 their count;
    coarse_count, coarse_spacing : (H, J, Q) the coarse prefixes (lod.points.coarse), padded with
    count 0 and spacing +inf (a padded prefix never fits a splat);
    base : character -> index of its first hierarchy (its segments in order). No joint frames (the
    per-keyframe-pair octrees only): :meth:`arrays` ends with :data:`lod.points.traverse.NO_JOINTS`.
    """

    node0: np.ndarray
    child_start: np.ndarray
    child_count: np.ndarray
    box0: np.ndarray
    box1: np.ndarray
    spacing: np.ndarray
    point_start: np.ndarray
    point_count: np.ndarray
    tri_start: np.ndarray
    tri_count: np.ndarray
    bounds: np.ndarray
    intervals: np.ndarray
    coarse_count: np.ndarray
    coarse_spacing: np.ndarray
    base: dict
    #: job rows per instance the next traversal reserves (:func:`lod.points.jobs.write_jobs`' ``owner``)
    _jobs_per_instance: int = JOBS_PER_INSTANCE

    def arrays(self) -> tuple:
        """The forest arrays of :func:`lod.points.jobs.write_jobs`."""
        return (self.node0, self.child_start, self.child_count, self.box0, self.box1, self.spacing,
                self.point_start, self.point_count, self.tri_start, self.tri_count, self.bounds, self.intervals,
                self.coarse_count, self.coarse_spacing, *NO_JOINTS)


def build_forest(by_char: dict) -> Forest:
    """The :class:`Forest` of ``{character: PointsRep}``."""
    hs, base = [], {}
    for ch in sorted(by_char):
        base[ch] = len(hs)
        hs.extend(by_char[ch].hierarchies)
    H = len(hs)
    node0 = np.zeros(H + 1, np.int64)
    np.cumsum([h.n_nodes for h in hs], out=node0[1:])
    J = max([int(np.asarray(h.point_count).reshape(h.n_nodes, -1).shape[1]) for h in hs] + [1])
    co = [coarse_arrays(h) for h in hs]
    Q = max([int(c[0].shape[1]) for c in co] + [0])
    cc = np.zeros((H, J, Q), np.int64)
    cs = np.full((H, J, Q), np.inf)
    bounds = np.ones((H, J + 1), np.float64)
    intervals = np.zeros(H, np.int64)
    ps = np.zeros((int(node0[-1]), J), np.int64)
    pc = np.zeros((int(node0[-1]), J), np.int64)
    for i, (h, (c, s)) in enumerate(zip(hs, co)):
        b = np.asarray(h.bounds, np.float64)
        bounds[i, :b.shape[0]] = b
        intervals[i] = b.shape[0] - 1
        cc[i, :c.shape[0], :c.shape[1]] = c
        cs[i, :s.shape[0], :s.shape[1]] = s
        a, e = int(node0[i]), int(node0[i + 1])
        p0, p1 = np.asarray(h.point_start).reshape(h.n_nodes, -1), np.asarray(h.point_count).reshape(h.n_nodes, -1)
        ps[a:e, :p0.shape[1]] = p0
        pc[a:e, :p1.shape[1]] = p1

    def cat(name, dtype, shape):
        parts = [np.asarray(getattr(h, name), dtype) for h in hs]
        return np.ascontiguousarray(np.concatenate(parts)) if parts else np.zeros(shape, dtype)

    f = Forest(node0, cat("child_start", np.int64, (0,)), cat("child_count", np.int64, (0,)),
               cat("box0", np.float64, (0, 2, 3)), cat("box1", np.float64, (0, 2, 3)),
               cat("spacing", np.float64, (0,)), ps, pc, cat("tri_start", np.int64, (0,)),
               cat("tri_count", np.int64, (0,)), bounds, intervals, cc, cs, base)
    return f


# ---------------------------------------------------------------------------- 1, 2: segments and the sort
@njit(cache=True, parallel=True)
def _locate_kernel(ids, gof, g_on, g_skinned, g_ns, g_soff, g_t0, g_dur, g_loop, g_bin0, starts, ends, anim_time,
                   binof, uof):  # pragma: no cover - compiled
    """Per instance of a group the candidate draws: its bin (the group's first bin + segment within the
    clip) and ``u`` (skinned: located from the agent's animation time by the rule of
    :func:`lod.full.reps._locate_one`, the clip's segments at ``starts[g_soff[g]:][:g_ns[g]]``; keyframed:
    the group's part is the segment, the master's column 12 its u); -1 elsewhere. The body is written
    out here: a helper taking the segment tables costs their reference counts per instance."""
    for i in prange(ids.shape[0]):
        g = gof[i]
        if not g_on[g]:
            binof[i] = -1
            continue
        if not g_skinned[g]:
            binof[i] = g_bin0[g]
            continue
        s0, ns, t0, dur = g_soff[g], g_ns[g], g_t0[g], g_dur[g]
        x = anim_time[ids[i]]
        if not np.isfinite(x):
            x = t0
        if g_loop[g] and dur > 0.0:
            x = t0 + (x - t0) % dur  # Python's float modulo: the sign of dur, as np.mod
        x = min(max(x, starts[s0]), ends[s0 + ns - 1])
        lo, hi = 0, ns  # searchsorted(starts, x, side="right") - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if starts[s0 + mid] <= x:
                lo = mid + 1
            else:
                hi = mid
        s = min(max(lo - 1, 0), ns - 1)
        span = ends[s0 + s] - starts[s0 + s]
        v = (x - starts[s0 + s]) / (span if span > 0.0 else 1.0)
        binof[i] = g_bin0[g] + s
        uof[i] = min(max(v, 0.0), 1.0)


@njit(cache=True, parallel=True)
def _bin_counts(binof, first, B):  # pragma: no cover - compiled
    """(C, B) instances of each bin in each chunk ``first[c] .. first[c + 1] - 1``."""
    C = first.shape[0] - 1
    out = np.zeros((C, B), np.int64)
    for c in prange(C):
        for i in range(first[c], first[c + 1]):
            b = binof[i]
            if b >= 0:
                out[c, b] += 1
    return out


@njit(cache=True, parallel=True)
def _bin_scatter(binof, uof, ids, data, first, cstarts, pos, src, pdata, pids, skinned_bin):  # pragma: no cover
    """The stable counting sort: chunk c writes bin b from ``cstarts[c, b]``; ``pos[i]`` is instance i's
    sorted row (-1: none), ``src[k]`` the instance of sorted row k; the sorted rows get the instance data
    with ``u`` as float32 in column 12 (a skinned group's; a keyframed group's data is copied as it is)."""
    for c in prange(first.shape[0] - 1):
        cursor = cstarts[c].copy()
        for i in range(first[c], first[c + 1]):
            b = binof[i]
            if b < 0:
                pos[i] = -1
                continue
            k = cursor[b]
            cursor[b] += 1
            pos[i] = k
            src[k] = i
            pids[k] = ids[i]
            for q in range(16):
                pdata[k, q] = data[i, q]
            if skinned_bin[b]:
                pdata[k, 12] = np.float32(uof[i])


# ---------------------------------------------------------------------------- 3: the traversal
def traverse(forest: Forest, pdata, kbin, bin_h, bin_row0, planes, vscale: float, splat: float):
    """Jobs of every sorted instance (module docstring, 3; :func:`lod.points.jobs.write_jobs` with ``root``):
    point jobs (J, 3) and triangle jobs (Q, 3) int64 (row within the instance's bin, first, count) in
    instance order, per instance its points and triangles (K,) int64, and per bin the first of its point and
    triangle jobs ((B + 1,) int64 each, B = ``bin_row0.shape[0] - 1``)."""
    K = pdata.shape[0]
    B = bin_row0.shape[0] - 1
    if K == 0:
        z = np.zeros(B + 1, np.int64)
        return np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64), np.empty(0, np.int64), \
            np.empty(0, np.int64), z, z
    pj, tj, psum, tsum, _, pbin, tbin = write_jobs(forest.arrays(), pdata, planes, vscale, splat, forest, root=True,
                                                   bins=(kbin, bin_h, bin_row0))
    # a bin's jobs follow those of every earlier bin's instances (bins are consecutive instances)
    p_at = np.zeros(B + 1, np.int64)
    t_at = np.zeros(B + 1, np.int64)
    np.cumsum(pbin[:B], out=p_at[1:])
    np.cumsum(tbin[:B], out=t_at[1:])
    return pj, tj, psum, tsum, p_at, t_at


__all__ = ["Forest", "build_forest", "traverse"]
