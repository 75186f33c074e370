"""The traversal of a follow hierarchy (:mod:`lod.points.follow`, Wand & Strasser 2002 §3.5's per-instance
traversal on rest-pose samples placed by the animation) for many instances at once, with each instance's root
decided in line where the root alone settles it (culled, or drawn as its coarse points): the same arithmetic as
:func:`lod.points.traverse._traverse_kernel`, in the kernel's order, so the results equal
:func:`lod.points.mode.traverse_instances` bit for bit (tests/lod/auto/test_auto_flat.py). Mode points' own
selection (:mod:`lod.points.mode`) and mode auto's flat selection (:mod:`lod.auto.flat`) both traverse with it;
far crowds, where most instances stop at the root, are where it pays (a million agents)."""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from lod.points.mode import traverse_chunks
from lod.points.traverse import _node_corners, _traverse_kernel


@njit(cache=True)
def _follow_rows(child_start, child_count, box0, box1, spacing, point_start, point_count, tri_start, tri_count,
                 bounds, coarse_count, coarse_spacing, ref, jt, data, planes, vscale, splat, r0, r1, base, cap, pjobs,
                 tjobs, psum, tsum, deep):  # pragma: no cover - compiled
    """:func:`lod.points.mode._traverse_rows` (same arguments, same results) with the root decided in line
    when it settles the instance (a far crowd: the root culled, or drawn as points and nothing else): its
    corners are :func:`lod.points.traverse._node_corners` (inlined: the same arithmetic), then the kernel's own
    tests in its order, so the outcome is the kernel's exactly; otherwise the kernel runs (a call per
    instance passing the hierarchy's arrays costs their reference counts, more than the root's test)."""
    N = child_start.shape[0]
    out_p = np.empty((N, 2), np.int64)
    out_pn = np.empty(N, np.int32)
    out_t = np.empty((N, 2), np.int64)
    out_tn = np.empty(N, np.int32)
    stack = np.empty(N + 8, np.int64)
    cs = np.empty((16, 3))
    lo = np.empty(3)
    hi = np.empty(3)
    model = np.empty((3, 4))
    npj = 0
    ntj = 0
    intervals = bounds.shape[0] - 1
    fast = N > 0 and tri_count[0] == 0 and child_count[0] > 0
    for r in range(r0, r1):
        for a in range(3):
            for b in range(4):
                model[a, b] = data[r, 4 * a + b]
        scale = 0.0
        for b in range(3):
            s = np.sqrt(model[0, b] ** 2 + model[1, b] ** 2 + model[2, b] ** 2)
            if s > scale:
                scale = s
        u = data[r, 12]
        if not np.isfinite(u):
            u = 0.0
        f0 = 0
        f1 = 0
        a = 0.0
        if ref.shape[0] > 0:  # a baked row (lod.points.follow), as render/shaders/skinning.glsl frame_pair
            last = jt.shape[0] - 1
            f = min(max(u, 0.0), float(last))
            f0 = int(np.floor(f))
            f1 = min(f0 + 1, last)
            a = f - f0
            u = 0.0
        u = min(max(u, 0.0), 1.0)
        j = 0  # the interval holding u (lod.points.stratify.interval_of)
        while j < intervals - 1 and bounds[j + 1] <= u:
            j += 1
        decided = False
        if fast:  # the kernel's first iteration (node 0), written out
            w = 1.0 - u
            for k in range(3):
                lo[k] = w * box0[0, 0, k] + u * box1[0, 0, k]
                hi[k] = w * box0[0, 1, k] + u * box1[0, 1, k]
            nc = _node_corners(0, lo, hi, ref, jt, f0, f1, a, model, cs)
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
            cnt = 0
            if culled:
                decided = True
            else:
                dmin = np.inf
                for c in range(nc):
                    d = planes[4, 0] * cs[c, 0] + planes[4, 1] * cs[c, 1] + planes[4, 2] * cs[c, 2]
                    if d < dmin:
                        dmin = d
                if dmin > 0.0 and spacing[0] * scale / dmin * vscale <= splat:
                    decided = True
                    if point_count[0, j] > 0:
                        cnt = point_count[0, j]
                        fq = scale / dmin * vscale
                        for q in range(coarse_count.shape[1]):
                            if coarse_spacing[j, q] * fq <= splat:
                                cnt = min(cnt, coarse_count[j, q])
                                break
            if decided:
                if cnt > 0:
                    if npj + 1 > cap:
                        return -1, -1
                    pjobs[base + npj, 0] = r
                    pjobs[base + npj, 1] = point_start[0, j]
                    pjobs[base + npj, 2] = cnt
                    npj += 1
                    deep[r] = 0
                else:
                    deep[r] = -1
                psum[r] = cnt
                tsum[r] = 0
                continue
        np_, nt = _traverse_kernel(child_start, child_count, box0, box1, spacing, point_start, point_count,
                                   tri_start, tri_count, coarse_count, coarse_spacing, ref, jt, f0, f1, a, u, j,
                                   planes, model, scale, vscale, splat, out_p, out_pn, out_t, out_tn, stack, cs, lo,
                                   hi)
        if npj + np_ > cap or ntj + nt > cap:
            return -1, -1
        dn = -1
        for q in range(np_):
            dn = max(dn, out_pn[q])
        for q in range(nt):
            dn = max(dn, out_tn[q])
        deep[r] = dn
        sp = 0
        for q in range(np_):
            pjobs[base + npj, 0] = r
            pjobs[base + npj, 1] = out_p[q, 0]
            pjobs[base + npj, 2] = out_p[q, 1]
            sp += out_p[q, 1]
            npj += 1
        st = 0
        for q in range(nt):
            tjobs[base + ntj, 0] = r
            tjobs[base + ntj, 1] = out_t[q, 0]
            tjobs[base + ntj, 2] = out_t[q, 1]
            st += out_t[q, 1]
            ntj += 1
        psum[r] = sp
        tsum[r] = st
    return npj, ntj


@njit(cache=True, parallel=True)
def _follow_chunks(child_start, child_count, box0, box1, spacing, point_start, point_count, tri_start, tri_count,
                   bounds, coarse_count, coarse_spacing, ref, jt, data, planes, vscale, splat, first, cap, pjobs, tjobs,
                   npc, ntc, psum, tsum, deep):  # pragma: no cover - compiled
    for c in prange(first.shape[0] - 1):
        npc[c], ntc[c] = _follow_rows(child_start, child_count, box0, box1, spacing, point_start, point_count,
                                      tri_start, tri_count, bounds, coarse_count, coarse_spacing, ref, jt, data,
                                      planes, vscale, splat, first[c], first[c + 1], c * cap, cap, pjobs, tjobs, psum,
                                      tsum, deep)


def follow_traverse(h, data, planes, vscale: float, splat: float, totals: bool = True, deepest: bool = True):
    """:func:`lod.points.mode.traverse_instances` of a follow hierarchy's view (``lod.points.follow.FollowRep.
    view``) with ``totals`` and ``deepest``: the same chunks, capacities and job tables, each instance's root
    decided in line where it settles it (:func:`_follow_rows`). The signature is traverse_instances', so
    :func:`lod.points.follow_select.follow_batch` takes it as its traversal."""
    from lod.points.mode import _harrays

    if not (totals and deepest):
        raise ValueError("follow_traverse: totals and deepest only")
    data = np.asarray(data)
    data = np.ascontiguousarray(data, data.dtype if data.dtype in (np.float32, np.float64) else np.float64)
    data = data.reshape(-1, 16)
    planes = np.ascontiguousarray(planes, np.float64)
    k = data.shape[0]
    per = int(getattr(h, "_jobs_per_instance", 4))
    arr = _harrays(h)
    psum, tsum, deep = np.empty(k, np.int64), np.empty(k, np.int64), np.empty(k, np.int64)
    chunks = traverse_chunks(k)
    first = np.linspace(0, k, chunks + 1).astype(np.int64)
    rows = int(np.diff(first).max()) if k else 0
    cap = max(16, per * rows)
    while True:
        pj = np.empty((cap * chunks, 3), np.int64)
        tj = np.empty((cap * chunks, 3), np.int64)
        npc, ntc = np.empty(chunks, np.int64), np.empty(chunks, np.int64)
        if chunks == 1:
            npc[0], ntc[0] = _follow_rows(*arr, data, planes, float(vscale), float(splat), 0, k, 0, cap, pj, tj, psum,
                                          tsum, deep)
        else:
            _follow_chunks(*arr, data, planes, float(vscale), float(splat), first, cap, pj, tj, npc, ntc, psum, tsum,
                           deep)
        if (npc >= 0).all():
            break
        cap *= 2
    h._jobs_per_instance = max(per, -(-int(max(npc.max(), ntc.max())) // max(rows, 1)))
    if chunks == 1:
        npj, ntj = int(npc[0]), int(ntc[0])
        pj = pj[:npj] if 2 * npj >= cap else pj[:npj].copy()
        tj = tj[:ntj] if 2 * ntj >= cap else tj[:ntj].copy()
    else:
        pj = np.concatenate([pj[c * cap:c * cap + npc[c]] for c in range(chunks)])
        tj = np.concatenate([tj[c * cap:c * cap + ntc[c]] for c in range(chunks)])
    return pj, tj, psum, tsum, deep


__all__ = ["follow_traverse"]
