"""The traversal's job writer: many instances traversed at once (Wand & Straßer 2002 §3.2, the per-instance
traversal of :func:`lod.points.traverse._traverse_kernel`), each instance's point and triangle ranges written
as job rows ``(instance row, start, count)`` the renderer draws.

One numba kernel (:func:`_write_rows`, its chunks run in parallel by :func:`_write_chunks`) serves every
caller:

- mode points' baked octrees (:func:`traverse_instances`, :mod:`lod.points.mode`, and mode auto's point
  candidate per group): one hierarchy, every instance traversed by the kernel;
- the hierarchies that follow the animation (:func:`follow_traverse`, :mod:`lod.points.follow_select`,
  :mod:`lod.auto.flat`): one hierarchy with node boxes in joint frames (column 12 the instance's fractional
  baked row), and ``root`` on: the instance's root decided in line where it settles the instance (culled, or
  drawn as its coarse points and nothing else: a far crowd), by the kernel's own arithmetic in the kernel's
  order (:func:`lod.points.traverse._node_corners` for the corners, then its plane and spacing tests), so
  the outcome is the kernel's exactly; a call per instance passing the hierarchy's arrays costs their
  reference counts, more than the root's test;
- mode auto's flat pass (:mod:`lod.auto.flat_points`): a *forest* of hierarchies (every character's
  segments concatenated), each sorted instance with the hierarchy of its bin (group, segment), job rows
  numbered within the bin and counted per bin, ``root`` on.

The hierarchy arrays are those of a forest: ``node0`` (H + 1,) the first node of each hierarchy, node rows of
all hierarchies, ``bounds`` (H, J + 1) and ``intervals`` (H,) the time intervals, ``coarse_count`` /
``coarse_spacing`` (H, J, Q) the coarse prefixes (``lod.points.coarse``; padded with count 0 and spacing
+inf, a padded prefix never fits a splat), ``ref`` / ``jt`` the joint frames (``lod.points.traverse.
joint_frames``: of a one-hierarchy forest only; empty for a forest of several). :func:`hierarchy_arrays`
gives them for one hierarchy (H = 1, views with a leading axis: the values as they are).

Job tables come out in instance order whatever the chunks (each chunk writes its own rows, then the chunks
are laid one after another), so serial and parallel runs give the same tables; :func:`traverse_instances_
reference` is the plain per-instance reference the tests compare with.
"""
from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from lod.points.coarse import coarse_arrays
from lod.points.traverse import _node_corners, _traverse_kernel, joint_frames, traverse

#: instances per call below which the traversal runs serially (a parallel region costs a thread wake-up,
#: milliseconds on a loaded machine)
TRAVERSE_PARALLEL_MIN = 20_000
#: chunks per numba thread of the parallel traversal
TRAVERSE_CHUNKS_PER_THREAD = 4
#: job rows per instance a chunk reserves at first for a hierarchy it has not traversed before (then what it
#: needed last time; a retry doubles it)
JOBS_PER_INSTANCE = 4


def traverse_chunks(k: int) -> int:
    """Chunks of the traversal of ``k`` instances: 1 (the serial kernel) below :data:`TRAVERSE_PARALLEL_MIN`,
    else ``TRAVERSE_CHUNKS_PER_THREAD`` per numba thread (uneven instance costs balance), at most one per
    ``TRAVERSE_PARALLEL_MIN // 4`` instances."""
    threads = numba.get_num_threads()
    if k < TRAVERSE_PARALLEL_MIN or threads < 2:
        return 1
    return int(max(2, min(threads * TRAVERSE_CHUNKS_PER_THREAD, k // max(1, TRAVERSE_PARALLEL_MIN // 4))))


def hierarchy_arrays(h) -> tuple:
    """The forest arrays (module docstring) of the one hierarchy ``h`` (a ``PointHierarchy`` or a follow
    hierarchy's view), kept on ``h``: (node0, child_start, child_count, box0, box1, spacing, point_start,
    point_count, tri_start, tri_count, bounds (1, J + 1), intervals (1,), coarse_count (1, J, Q),
    coarse_spacing (1, J, Q), ref, jt)."""
    arr = getattr(h, "_traverse_arrays", None)
    if arr is None:
        bounds = np.ascontiguousarray(h.bounds, np.float64)
        cc, cs = coarse_arrays(h)
        arr = (np.array([0, h.child_start.shape[0]], np.int64), h.child_start.astype(np.int64),
               h.child_count.astype(np.int64), np.ascontiguousarray(h.box0), np.ascontiguousarray(h.box1),
               np.ascontiguousarray(h.spacing), np.ascontiguousarray(h.point_start),
               np.ascontiguousarray(h.point_count), np.ascontiguousarray(h.tri_start),
               np.ascontiguousarray(h.tri_count), bounds[None], np.array([bounds.shape[0] - 1], np.int64),
               np.ascontiguousarray(cc)[None], np.ascontiguousarray(cs)[None], *joint_frames(h))
        h._traverse_arrays = arr
    return arr


#: ``kbin``, ``bin_h``, ``bin_row0`` of a one-hierarchy traversal: every row in bin 0 (no per-row table),
#: hierarchy 0, job rows the instance rows
ONE_BIN = (np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64))


# ---------------------------------------------------------------------------- the kernel
@njit(cache=True)
def _write_rows(node0, child_start, child_count, box0, box1, spacing, point_start, point_count, tri_start,
                tri_count, bounds, intervals, coarse_count, coarse_spacing, ref, jt, data, kbin, bin_h, bin_row0,
                planes, vscale, splat, root, r0, r1, base, cap, pjobs, tjobs, psum, tsum, deep, pbin,
                tbin):  # pragma: no cover - compiled
    """Traverse instances ``r0 .. r1 - 1`` into ``pjobs`` / ``tjobs`` rows ``base .. base + cap - 1``; returns
    (point jobs, triangle jobs) written, or (-1, -1) when they do not fit.

    Instance r is traversed in hierarchy ``bin_h[b]`` of its bin ``b = kbin[r]`` (``kbin`` empty: bin 0) and
    its jobs name row ``r - bin_row0[b]``; ``pbin`` / ``tbin`` (B,) count the jobs per bin; ``psum[r]`` /
    ``tsum[r]`` its points and triangles; ``deep[r]`` (``deep`` empty: not written) the largest node it draws
    (points or triangles), -1 for none. With joint frames (``ref`` not empty, ``lod.points.follow``) column 12
    is the instance's fractional baked row, else its time u in the segment. ``root``: decide the root in line
    where it settles the instance (module docstring)."""
    n_max = 0
    for h in range(node0.shape[0] - 1):
        n_max = max(n_max, node0[h + 1] - node0[h])
    out_p = np.empty((n_max, 2), np.int64)
    out_pn = np.empty(n_max, np.int32)
    out_t = np.empty((n_max, 2), np.int64)
    out_tn = np.empty(n_max, np.int32)
    stack = np.empty(n_max + 8, np.int64)
    cs = np.empty((16, 3))
    lo = np.empty(3)
    hi = np.empty(3)
    model = np.empty((3, 4))
    pbin[:] = 0
    tbin[:] = 0
    binned = kbin.shape[0] > 0
    write_deep = deep.shape[0] > 0
    npj = 0
    ntj = 0
    for r in range(r0, r1):
        b = kbin[r] if binned else 0
        h = bin_h[b]
        a, e = node0[h], node0[h + 1]
        row = r - bin_row0[b]
        for x in range(3):
            for y in range(4):
                model[x, y] = data[r, 4 * x + y]
        scale = 0.0
        for y in range(3):
            s = np.sqrt(model[0, y] ** 2 + model[1, y] ** 2 + model[2, y] ** 2)
            if s > scale:
                scale = s
        u = np.float64(data[r, 12])
        if not np.isfinite(u):
            u = 0.0
        f0 = 0
        f1 = 0
        fa = 0.0
        if ref.shape[0] > 0:  # a baked row (lod.points.follow), as render/shaders/poses/skinning.glsl frame_pair
            last = jt.shape[0] - 1
            f = min(max(u, 0.0), float(last))
            f0 = int(np.floor(f))
            f1 = min(f0 + 1, last)
            fa = f - f0
            u = 0.0
        u = min(max(u, 0.0), 1.0)
        j = 0  # the interval holding u (lod.points.stratify.interval_of)
        while j < intervals[h] - 1 and bounds[h, j + 1] <= u:
            j += 1
        if root and e > a and tri_count[a] == 0 and child_count[a] > 0:  # the kernel's first node, written out
            w = 1.0 - u
            for k in range(3):
                lo[k] = w * box0[a, 0, k] + u * box1[a, 0, k]
                hi[k] = w * box0[a, 1, k] + u * box1[a, 1, k]
            nc = _node_corners(0, lo, hi, ref, jt, f0, f1, fa, model, cs)
            culled = False
            for p in range(planes.shape[0]):
                outside = True
                for c in range(nc):
                    if planes[p, 0] * cs[c, 0] + planes[p, 1] * cs[c, 1] + planes[p, 2] * cs[c, 2] + planes[p, 3] \
                            >= 0.0:
                        outside = False
                        break
                if outside:
                    culled = True
                    break
            decided = culled
            cnt = 0
            if not culled:
                dmin = np.inf
                for c in range(nc):
                    d = planes[4, 0] * cs[c, 0] + planes[4, 1] * cs[c, 1] + planes[4, 2] * cs[c, 2]
                    if d < dmin:
                        dmin = d
                if dmin > 0.0 and spacing[a] * scale / dmin * vscale <= splat:
                    decided = True
                    if point_count[a, j] > 0:
                        cnt = point_count[a, j]
                        fq = scale / dmin * vscale
                        for q in range(coarse_count.shape[2]):
                            if coarse_spacing[h, j, q] * fq <= splat:
                                cnt = min(cnt, coarse_count[h, j, q])
                                break
            if decided:  # drawn from the root's points (or from none), nothing else
                if cnt > 0:
                    if npj + 1 > cap:
                        return -1, -1
                    pjobs[base + npj, 0] = row
                    pjobs[base + npj, 1] = point_start[a, j]
                    pjobs[base + npj, 2] = cnt
                    npj += 1
                    pbin[b] += 1
                if write_deep:
                    deep[r] = 0 if cnt > 0 else -1
                psum[r] = cnt
                tsum[r] = 0
                continue
        np_, nt = _traverse_kernel(child_start[a:e], child_count[a:e], box0[a:e], box1[a:e], spacing[a:e],
                                   point_start[a:e], point_count[a:e], tri_start[a:e], tri_count[a:e],
                                   coarse_count[h], coarse_spacing[h], ref, jt, f0, f1, fa, u, j, planes, model,
                                   scale, vscale, splat, out_p, out_pn, out_t, out_tn, stack, cs, lo, hi)
        if npj + np_ > cap or ntj + nt > cap:
            return -1, -1
        if write_deep:
            dn = -1
            for q in range(np_):
                dn = max(dn, out_pn[q])
            for q in range(nt):
                dn = max(dn, out_tn[q])
            deep[r] = dn
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
def _write_chunks(node0, child_start, child_count, box0, box1, spacing, point_start, point_count, tri_start,
                  tri_count, bounds, intervals, coarse_count, coarse_spacing, ref, jt, data, kbin, bin_h, bin_row0,
                  planes, vscale, splat, root, first, cap, pjobs, tjobs, npc, ntc, psum, tsum, deep, pbin,
                  tbin):  # pragma: no cover - compiled
    """Chunk c (rows ``first[c] .. first[c + 1] - 1``) into job rows ``c * cap ..``, the chunks in parallel
    (each writes only its own job rows, instances and row of ``pbin`` / ``tbin``)."""
    for c in prange(first.shape[0] - 1):
        npc[c], ntc[c] = _write_rows(node0, child_start, child_count, box0, box1, spacing, point_start,
                                     point_count, tri_start, tri_count, bounds, intervals, coarse_count,
                                     coarse_spacing, ref, jt, data, kbin, bin_h, bin_row0, planes, vscale, splat,
                                     root, first[c], first[c + 1], c * cap, cap, pjobs, tjobs, psum, tsum, deep,
                                     pbin[c], tbin[c])


@njit(cache=True, parallel=True)
def _gather_jobs(src, cap, counts, offs, out):  # pragma: no cover - compiled
    """The chunks' job rows (chunk c: ``src[c * cap : c * cap + counts[c]]``) one after another in ``out``."""
    for c in prange(counts.shape[0]):
        for q in range(counts[c]):
            for x in range(3):
                out[offs[c] + q, x] = src[c * cap + q, x]


# ---------------------------------------------------------------------------- the entry points
def write_jobs(arrays: tuple, data, planes, vscale: float, splat: float, owner, root: bool = False,
               deepest: bool = False, bins: tuple = ONE_BIN) -> tuple:
    """Traverse every instance row of ``data`` (module docstring) and write its jobs.

    Parameters
    ----------
    arrays : the forest arrays (module docstring; :func:`hierarchy_arrays` for one hierarchy)
    data : (K, 16) float32/64 instance data (camera-relative model rows, column 12 u or the baked row)
    planes : (6, 4) float64 camera-relative frustum planes; vscale : pixels per metre at depth 1;
        splat : splat size in pixels
    owner : the object the job capacity per instance is kept on (``_jobs_per_instance``; first
        :data:`JOBS_PER_INSTANCE`)
    root : decide each root in line where it settles the instance
    deepest : also write each instance's largest drawn node
    bins : (kbin (K,) int64, bin_h (B,) int64, bin_row0 (B + 1,) int64) of a forest (the instances sorted by
        bin), or :data:`ONE_BIN`

    Returns
    -------
    point jobs (P, 3) and triangle jobs (Q, 3) int64 (row, start, count) in instance order; points and
    triangles (K,) int64 per instance; deepest nodes (K,) int64 or None; point and triangle jobs per bin
    (B,) int64.
    """
    data = np.asarray(data)
    # float32 instance data is read as it is (the kernel widens each value to float64 as a copy would)
    data = np.ascontiguousarray(data, data.dtype if data.dtype in (np.float32, np.float64) else np.float64)
    data = data.reshape(-1, 16)
    planes = np.ascontiguousarray(planes, np.float64)
    k = data.shape[0]
    kbin, bin_h, bin_row0 = bins
    B = bin_h.shape[0]
    per = int(getattr(owner, "_jobs_per_instance", JOBS_PER_INSTANCE))
    psum = np.empty(k, np.int64)
    tsum = np.empty(k, np.int64)
    deep = np.empty(k if deepest else 0, np.int64)
    chunks = traverse_chunks(k)
    first = np.linspace(0, k, chunks + 1).astype(np.int64)
    rows = int(np.diff(first).max()) if k else 0
    cap = max(16, per * rows)
    args = (*arrays, data, kbin, bin_h, bin_row0, planes, float(vscale), float(splat), bool(root))
    while True:
        pj = np.empty((cap * chunks, 3), np.int64)
        tj = np.empty((cap * chunks, 3), np.int64)
        npc, ntc = np.empty(chunks, np.int64), np.empty(chunks, np.int64)
        pbin, tbin = np.empty((chunks, B), np.int64), np.empty((chunks, B), np.int64)
        if chunks == 1:
            npc[0], ntc[0] = _write_rows(*args, 0, k, 0, cap, pj, tj, psum, tsum, deep, pbin[0], tbin[0])
        else:
            _write_chunks(*args, first, cap, pj, tj, npc, ntc, psum, tsum, deep, pbin, tbin)
        if (npc >= 0).all():
            break
        cap *= 2
    owner._jobs_per_instance = max(per, -(-int(max(npc.max(), ntc.max())) // max(rows, 1)))

    def compact(src, counts):
        if chunks == 1:  # a view while the buffer is at most twice what was used (no copy), else a compact copy
            n = int(counts[0])
            return src[:n] if 2 * n >= cap else src[:n].copy()
        offs = np.zeros(chunks, np.int64)
        np.cumsum(counts[:-1], out=offs[1:])
        out = np.empty((int(counts.sum()), 3), np.int64)
        _gather_jobs(src, cap, counts, offs, out)
        return out

    return (compact(pj, npc), compact(tj, ntc), psum, tsum, deep if deepest else None, pbin.sum(axis=0),
            tbin.sum(axis=0))


def traverse_instances(h, data: np.ndarray, planes, vscale: float, splat: float, totals: bool = False,
                       deepest: bool = False, root: bool = False):
    """Traverse ``h`` (§3.2) once per instance (numba, :func:`write_jobs`).

    Parameters
    ----------
    h : PointHierarchy, or a follow hierarchy's view (``lod.points.follow.FollowRep.view``)
    data : (k, 16) float32/64 instance data (camera-relative model rows, u in column 12)
    planes : (6, 4) float64 camera-relative frustum planes; vscale : pixels per
        metre at depth 1; splat : splat size in pixels
    totals : also return each instance's point and triangle totals
    deepest : also return each instance's largest drawn node (-1: none), whose
        point and vertex prefixes ``lod.points.follow`` places per pose
    root : decide each instance's root in line where it settles it (the same results)

    Returns
    -------
    point_jobs (J, 3) int64 and tri_jobs (Q, 3) int64: (instance row, start,
    count); with ``totals`` also points (k,) int64 and triangles (k,) int64
    per instance (the sums of its jobs' counts); with ``deepest`` then (k,)
    int64 nodes.
    """
    pj, tj, psum, tsum, deep, _, _ = write_jobs(hierarchy_arrays(h), data, planes, vscale, splat, h, root=root,
                                                deepest=deepest)
    return (pj, tj) + ((psum, tsum) if totals else ()) + ((deep,) if deepest else ())


def follow_traverse(h, data, planes, vscale: float, splat: float, totals: bool = True, deepest: bool = True):
    """:func:`traverse_instances` of a follow hierarchy's view with each instance's root decided in line (far
    crowds, where most instances stop at the root: a million agents); by default with ``totals`` and
    ``deepest``, so :func:`lod.points.follow_select.follow_batch` takes it as its traversal."""
    return traverse_instances(h, data, planes, vscale, splat, totals=totals, deepest=deepest, root=True)


def traverse_instances_reference(h, data, planes, vscale: float, splat: float):
    """Reference of :func:`traverse_instances`: ``lod.points.traverse.traverse`` per instance."""
    data = np.asarray(data, np.float64).reshape(-1, 16)
    pj, tj = [], []
    for r in range(data.shape[0]):
        res = traverse(h, float(data[r, 12]), planes, vscale, splat, data[r, :12].reshape(3, 4),
                       frame=float(data[r, 12]))
        pj += [(r, s, c) for s, c in res.point_ranges.tolist()]
        tj += [(r, s, c) for s, c in res.tri_ranges.tolist()]
    return np.array(pj, np.int64).reshape(-1, 3), np.array(tj, np.int64).reshape(-1, 3)


__all__ = ["JOBS_PER_INSTANCE", "ONE_BIN", "TRAVERSE_CHUNKS_PER_THREAD", "TRAVERSE_PARALLEL_MIN", "follow_traverse",
           "hierarchy_arrays", "traverse_chunks", "traverse_instances", "traverse_instances_reference", "write_jobs"]
