"""The point candidate of mode auto over flat arrays of all instances (issue 26, item 2).

:meth:`lod.auto.candidates.PointsCandidate.options` works group by group: it copies the group's
instance data, locates every instance's keyframe segment (Wand & Straßer §3: a point hierarchy per
keyframe pair), sorts the group's rows by segment and traverses each segment's hierarchy for its
instances (§3.2, :func:`lod.points.mode.traverse_instances`). Here the same work is done for the
instances of every group at once:

1. :func:`_locate_kernel`: every instance's segment and time ``u`` within it (the clip's table, as
   :meth:`lod.full.reps.KeyframedRep.locate`), and its *bin*: (group, segment), numbered group-major;
2. a stable counting sort by bin (:func:`_bin_counts`, :func:`_bin_scatter`: chunks of instances in
   parallel, each from its exclusive prefix), which writes the sorted copy of the instance data with
   ``u`` in column 12 (float32, as the per-group copy holds it): every group's rows grouped by segment in
   group order, the segments in order, exactly the per-group ``order``;
3. :func:`_traverse_kernel`: one parallel pass over all sorted instances, each traversing the hierarchy
   of its bin's segment (the hierarchies of every character's segments concatenated into one
   :class:`Forest`), writing point and triangle jobs (instance row within its segment, first, count)
   per chunk of instances, then copied into one table in instance order (the per-segment job tables are
   its slices);
4. the price of every instance's option (points, triangles, cost, error) is computed with the other
   candidates' rows in one pass (:func:`lod.auto.flat._rows_kernel`).

A character whose samples follow the animation (:mod:`lod.points.follow`: one hierarchy, node boxes in
joint frames, each copy at its own baked row) is not in the forest: its groups are traversed one call each
by :func:`lod.points.follow_traverse.follow_traverse`, :func:`lod.points.mode.traverse_instances` with the
root decided in line (the far crowd's common case) by the kernel's own arithmetic.

Every value is computed by the same expressions as the per-group path (the traversal is
:func:`lod.points.traverse._traverse_kernel` itself), so the options, job tables and sorted data are
identical (tests/lod/auto/test_auto_flat.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from lod.points.coarse import coarse_arrays
from lod.points.mode import traverse_chunks
from lod.points.traverse import _traverse_kernel

#: job rows per instance a chunk of the traversal reserves at first (doubled until the jobs fit)
JOBS_PER_INSTANCE = 2


@dataclass
class Forest:
    """The segment hierarchies of every character of the point candidate, concatenated.

    node0 : (H + 1,) int64 first node of each hierarchy (its nodes' child indices are its own);
    the node arrays as :func:`lod.points.mode._harrays` gives them, rows of all hierarchies;
    point_start, point_count : (nodes, J) int64, J the most intervals of any hierarchy;
    bounds : (H, J + 1) float64 interval boundaries, ``intervals`` (H,) int64 their count;
    coarse_count, coarse_spacing : (H, J, Q) the coarse prefixes (lod.points.coarse), padded with
    count 0 and spacing +inf (a padded prefix never fits a splat);
    base : character -> index of its first hierarchy (its segments in order); n_nodes : most nodes
    of one hierarchy (scratch size); fast : (H,) bool, the root stores no triangles and has children
    (:func:`_root_fast` may decide an instance from the root alone).
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
    n_nodes: int
    fast: np.ndarray

    def arrays(self) -> tuple:
        return (self.node0, self.child_start, self.child_count, self.box0, self.box1, self.spacing,
                self.point_start, self.point_count, self.tri_start, self.tri_count, self.bounds, self.intervals,
                self.coarse_count, self.coarse_spacing, self.fast)


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
               cat("tri_count", np.int64, (0,)), bounds, intervals, cc, cs, base,
               int(max([h.n_nodes for h in hs] + [1])), np.zeros(H, np.bool_))
    for i in range(H):
        if node0[i + 1] > node0[i]:
            r = int(node0[i])
            f.fast[i] = f.tri_count[r] == 0 and f.child_count[r] > 0
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
#: relative margin of :func:`_root_fast` (far above the rounding of the kernel's corner arithmetic,
#: about 1e-15 of the magnitudes involved)
ROOT_MARGIN = 1e-10


@njit(cache=True)
def _root_fast(box0, box1, spacing, point_count, coarse_count, coarse_spacing, fast, node0, intervals, bounds,
               pdata, kbin, bin_h, planes, vscale, splat, r0, r1, out):  # pragma: no cover - compiled
    """For sorted instances ``r0 .. r1 - 1``: ``out[r - r0]`` = the points the traversal draws when it is
    decided from the instance's root alone (the common case of a far crowd: the root drawn as points,
    :func:`lod.points.traverse._traverse_kernel` visits nothing else; 0: the root has none in the
    interval), or -1 when it cannot be decided that way (the kernel then runs).

    Exact, not approximate: the kernel takes the minimum view depth over the 8 transformed corners of the
    root's box at u; here it is computed in closed form (the depth of the centre minus the box's
    half-extents along the view direction) with a margin ``m`` (:data:`ROOT_MARGIN` of the magnitudes
    involved) far above the kernel's rounding, so the kernel's value lies in [d - m, d + m]. The kernel's
    tests (spacing within the splat; the first coarse prefix that fits) are monotone in the depth under
    rounding (a positive numerator divided by a larger depth never rounds larger), so when both ends of
    the interval give the same answer, so does the kernel's depth; otherwise -1. Likewise the root is not
    culled when its centre lies inside every plane by more than the margin (some corner is then inside
    each plane). The instance's scale and interval are the kernel's caller's (same expressions). One loop
    over the instances, scalars only: a call per instance passing these arrays would cost their
    reference counts, more than the test itself."""
    n0, n1, n2 = planes[4, 0], planes[4, 1], planes[4, 2]
    Q = coarse_spacing.shape[2]
    for r in range(r0, r1):
        h = bin_h[kbin[r]]
        out[r - r0] = -1
        if not fast[h]:
            continue
        a = node0[h]
        m00, m01, m02, m03 = (np.float64(pdata[r, 0]), np.float64(pdata[r, 1]), np.float64(pdata[r, 2]),
                              np.float64(pdata[r, 3]))
        m10, m11, m12, m13 = (np.float64(pdata[r, 4]), np.float64(pdata[r, 5]), np.float64(pdata[r, 6]),
                              np.float64(pdata[r, 7]))
        m20, m21, m22, m23 = (np.float64(pdata[r, 8]), np.float64(pdata[r, 9]), np.float64(pdata[r, 10]),
                              np.float64(pdata[r, 11]))
        scale = 0.0
        for y in range(3):
            c_ = np.sqrt(np.float64(pdata[r, y]) ** 2 + np.float64(pdata[r, 4 + y]) ** 2
                         + np.float64(pdata[r, 8 + y]) ** 2)
            if c_ > scale:
                scale = c_
        u = np.float64(pdata[r, 12])
        if not np.isfinite(u):
            u = 0.0
        u = min(max(u, 0.0), 1.0)
        j = 0
        while j < intervals[h] - 1 and bounds[h, j + 1] <= u:
            j += 1
        w = 1.0 - u
        lo0 = w * box0[a, 0, 0] + u * box1[a, 0, 0]
        lo1 = w * box0[a, 0, 1] + u * box1[a, 0, 1]
        lo2 = w * box0[a, 0, 2] + u * box1[a, 0, 2]
        hi0 = w * box0[a, 1, 0] + u * box1[a, 1, 0]
        hi1 = w * box0[a, 1, 1] + u * box1[a, 1, 1]
        hi2 = w * box0[a, 1, 2] + u * box1[a, 1, 2]
        x0, x1, x2 = 0.5 * (lo0 + hi0), 0.5 * (lo1 + hi1), 0.5 * (lo2 + hi2)
        h0, h1, h2 = 0.5 * abs(hi0 - lo0), 0.5 * abs(hi1 - lo1), 0.5 * abs(hi2 - lo2)
        c0 = m00 * x0 + m01 * x1 + m02 * x2 + m03
        c1 = m10 * x0 + m11 * x1 + m12 * x2 + m13
        c2 = m20 * x0 + m21 * x1 + m22 * x2 + m23
        e0, e1, e2 = abs(x0) + h0, abs(x1) + h1, abs(x2) + h2
        mag = (abs(m03) + abs(m00) * e0 + abs(m01) * e1 + abs(m02) * e2 + abs(m13) + abs(m10) * e0
               + abs(m11) * e1 + abs(m12) * e2 + abs(m23) + abs(m20) * e0 + abs(m21) * e1 + abs(m22) * e2)
        m = ROOT_MARGIN * (mag + 1.0)
        inside = True
        for p in range(planes.shape[0]):
            if not (planes[p, 0] * c0 + planes[p, 1] * c1 + planes[p, 2] * c2 + planes[p, 3]
                    > m + ROOT_MARGIN * abs(planes[p, 3])):
                inside = False
                break
        if not inside:
            continue
        d = (n0 * c0 + n1 * c1 + n2 * c2 - abs(n0 * m00 + n1 * m10 + n2 * m20) * h0
             - abs(n0 * m01 + n1 * m11 + n2 * m21) * h1 - abs(n0 * m02 + n1 * m12 + n2 * m22) * h2)
        dlo = d - m
        dhi = d + m
        if not dlo > 0.0:
            continue
        if not (spacing[a] * scale / dlo * vscale <= splat):  # the far end may descend: the kernel decides
            continue
        pc = point_count[a, j]
        if pc <= 0:
            out[r - r0] = 0
            continue
        flo = scale / dlo * vscale
        fhi = scale / dhi * vscale
        qlo = -1
        for q in range(Q):  # the first coarse prefix within the splat, at both ends
            if coarse_spacing[h, j, q] * flo <= splat:
                qlo = q
                break
        qhi = -1
        for q in range(Q):
            if coarse_spacing[h, j, q] * fhi <= splat:
                qhi = q
                break
        if qlo != qhi:
            continue
        out[r - r0] = min(pc, coarse_count[h, j, qlo]) if qlo >= 0 else pc


@njit(cache=True)
def _traverse_range(node0, child_start, child_count, box0, box1, spacing, point_start, point_count, tri_start,
                    tri_count, bounds, intervals, coarse_count, coarse_spacing, fast, n_nodes, pdata, kbin, bin_h, bin_row0,
                    planes, vscale, splat, r0, r1, base, cap, pjobs, tjobs, psum, tsum, pbin,
                    tbin):  # pragma: no cover - compiled
    """Sorted instances ``r0 .. r1 - 1`` into job rows ``base .. base + cap - 1`` (as
    :func:`lod.points.mode._traverse_rows`, each instance with its bin's hierarchy), counting the jobs per
    bin in ``pbin`` / ``tbin``; returns the point and triangle jobs written, (-1, -1) when they do not fit."""
    pbin[:] = 0
    tbin[:] = 0
    out_p = np.empty((n_nodes, 2), np.int64)
    out_pn = np.empty(n_nodes, np.int32)
    out_t = np.empty((n_nodes, 2), np.int64)
    out_tn = np.empty(n_nodes, np.int32)
    stack = np.empty(n_nodes + 8, np.int64)
    cs = np.empty((16, 3))
    ref0 = np.zeros(0, np.int32)  # lod.points.traverse.NO_JOINTS: the forest holds per-keyframe-pair octrees only
    jt0 = np.zeros((1, 1, 3, 4), np.float32)
    lo = np.empty(3)
    hi = np.empty(3)
    model = np.empty((3, 4))
    npj = 0
    ntj = 0
    root = np.empty(r1 - r0, np.int64)
    _root_fast(box0, box1, spacing, point_count, coarse_count, coarse_spacing, fast, node0, intervals, bounds, pdata,
               kbin, bin_h, planes, vscale, splat, r0, r1, root)
    for r in range(r0, r1):
        b = kbin[r]
        h = bin_h[b]
        a, e = node0[h], node0[h + 1]
        cnt = root[r - r0]
        if cnt >= 0:  # decided at the root: drawn from its points (or from none), nothing else
            if cnt > 0:
                if npj + 1 > cap:
                    return -1, -1
                u = min(max(np.float64(pdata[r, 12]) if np.isfinite(pdata[r, 12]) else 0.0, 0.0), 1.0)
                j = 0
                while j < intervals[h] - 1 and bounds[h, j + 1] <= u:
                    j += 1
                pjobs[base + npj, 0] = r - bin_row0[b]
                pjobs[base + npj, 1] = point_start[a, j]
                pjobs[base + npj, 2] = cnt
                npj += 1
                pbin[b] += 1
            psum[r] = cnt
            tsum[r] = 0
            continue
        for x in range(3):
            for y in range(4):
                model[x, y] = pdata[r, 4 * x + y]
        scale = 0.0
        for y in range(3):
            s = np.sqrt(model[0, y] ** 2 + model[1, y] ** 2 + model[2, y] ** 2)
            if s > scale:
                scale = s
        u = np.float64(pdata[r, 12])
        if not np.isfinite(u):
            u = 0.0
        u = min(max(u, 0.0), 1.0)
        j = 0
        while j < intervals[h] - 1 and bounds[h, j + 1] <= u:
            j += 1
        np_, nt = _traverse_kernel(child_start[a:e], child_count[a:e], box0[a:e], box1[a:e], spacing[a:e],
                                   point_start[a:e], point_count[a:e], tri_start[a:e], tri_count[a:e],
                                   coarse_count[h], coarse_spacing[h], ref0, jt0, 0, 0, 0.0, u, j, planes, model,
                                   scale, vscale,
                                   splat, out_p, out_pn, out_t, out_tn, stack, cs, lo, hi)
        if npj + np_ > cap or ntj + nt > cap:
            return -1, -1
        row = r - bin_row0[b]
        sp = 0
        for q in range(np_):
            pjobs[base + npj, 0] = row
            pjobs[base + npj, 1] = out_p[q, 0]
            pjobs[base + npj, 2] = out_p[q, 1]
            sp += out_p[q, 1]
            npj += 1
        st = 0
        for q in range(nt):
            tjobs[base + ntj, 0] = row
            tjobs[base + ntj, 1] = out_t[q, 0]
            tjobs[base + ntj, 2] = out_t[q, 1]
            st += out_t[q, 1]
            ntj += 1
        psum[r] = sp
        tsum[r] = st
        pbin[b] += np_
        tbin[b] += nt
    return npj, ntj


@njit(cache=True, parallel=True)
def _traverse_chunks(node0, child_start, child_count, box0, box1, spacing, point_start, point_count, tri_start,
                     tri_count, bounds, intervals, coarse_count, coarse_spacing, fast, n_nodes, pdata, kbin, bin_h,
                     bin_row0, planes, vscale, splat, first, cap, pjobs, tjobs, npc, ntc, psum, tsum, pbin,
                     tbin):  # pragma: no cover - compiled
    for c in prange(first.shape[0] - 1):
        npc[c], ntc[c] = _traverse_range(node0, child_start, child_count, box0, box1, spacing, point_start,
                                         point_count, tri_start, tri_count, bounds, intervals, coarse_count,
                                         coarse_spacing, fast, n_nodes, pdata, kbin, bin_h, bin_row0, planes, vscale,
                                         splat, first[c], first[c + 1], c * cap, cap, pjobs, tjobs, psum, tsum,
                                         pbin[c], tbin[c])


@njit(cache=True, parallel=True)
def _gather_jobs(src, first, cap, counts, offs, out):  # pragma: no cover - compiled
    """The chunks' job rows (chunk c: ``src[c * cap : c * cap + counts[c]]``) one after another in ``out``."""
    for c in prange(first.shape[0] - 1):
        for q in range(counts[c]):
            for x in range(3):
                out[offs[c] + q, x] = src[c * cap + q, x]


def traverse(forest: Forest, pdata, kbin, bin_h, bin_row0, planes, vscale: float, splat: float):
    """Jobs of every sorted instance (module docstring, 3): point jobs (J, 3) and triangle jobs (Q, 3) int64
    (row within the instance's bin, first, count) in instance order, per instance its points and
    triangles (K,) int64, and per bin the first of its point and triangle jobs ((B + 1,) int64 each)."""
    K = pdata.shape[0]
    B = bin_row0.shape[0] - 1
    psum = np.empty(K, np.int64)
    tsum = np.empty(K, np.int64)
    if K == 0:
        z = np.zeros(B + 1, np.int64)
        return np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64), psum, tsum, z, z
    chunks = traverse_chunks(K)
    first = np.linspace(0, K, chunks + 1).astype(np.int64)
    rows = int(np.diff(first).max())
    per = int(getattr(forest, "jobs_per_instance", JOBS_PER_INSTANCE))
    cap = max(16, per * rows)
    args = (*forest.arrays(), forest.n_nodes, pdata, kbin, bin_h, bin_row0, np.ascontiguousarray(planes, np.float64),
            float(vscale), float(splat))
    while True:
        pj = np.empty((cap * chunks, 3), np.int64)
        tj = np.empty((cap * chunks, 3), np.int64)
        npc, ntc = np.empty(chunks, np.int64), np.empty(chunks, np.int64)
        pbin, tbin = np.empty((chunks, max(B, 1)), np.int64), np.empty((chunks, max(B, 1)), np.int64)
        if chunks == 1:
            npc[0], ntc[0] = _traverse_range(*args, 0, K, 0, cap, pj, tj, psum, tsum, pbin[0], tbin[0])
        else:
            _traverse_chunks(*args, first, cap, pj, tj, npc, ntc, psum, tsum, pbin, tbin)
        if (npc >= 0).all():
            break
        cap *= 2
    forest.jobs_per_instance = max(per, -(-int(max(npc.max(), ntc.max())) // max(rows, 1)))

    def compact(src, counts):
        if chunks == 1:
            return src[:counts[0]]
        offs = np.zeros(chunks, np.int64)
        np.cumsum(counts[:-1], out=offs[1:])
        out = np.empty((int(counts.sum()), 3), np.int64)
        _gather_jobs(src, first, cap, counts, offs, out)
        return out

    # a bin's jobs follow those of every earlier bin's instances (bins are consecutive instances)
    p_at = np.zeros(B + 1, np.int64)
    t_at = np.zeros(B + 1, np.int64)
    np.cumsum(pbin.sum(axis=0)[:B], out=p_at[1:])
    np.cumsum(tbin.sum(axis=0)[:B], out=t_at[1:])
    return compact(pj, npc), compact(tj, ntc), psum, tsum, p_at, t_at


__all__ = ["Forest", "build_forest", "traverse"]
