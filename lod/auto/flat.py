"""Mode auto's per-instance selection over flat arrays of all instances (issue 26, item 2).

The per-group path of :class:`lod.auto.mode.AutoSelector` asks every candidate, master batch by master
batch, for an :class:`lod.auto.candidates.Options` table ((k, m) costs and errors), reduces each to the
cheapest admissible option per instance (:class:`lod.auto.plans._Block`) and lays the blocks of all
groups side by side to price the frame plans (:func:`lod.auto.plans.price_plans`). At a million agents
that is a second and a half of numpy on million-row temporaries: the float64 model rows of every group,
the (k, levels) projected errors, the point candidate's copies and sorts, the gathers of the side-by-side
layout.

Here the work is a few numba passes over the instances of all groups at once, written straight into the
side-by-side layout (one row per candidate, one column per instance, groups in master order; a group
without a candidate's block has +inf there): the point candidate's segments, sort and traversal
(:mod:`lod.auto.flat_points`, the job writer :mod:`lod.points.jobs` with the root decided in line for far
instances; a character whose
samples follow the animation, :mod:`lod.points.follow`, has one hierarchy traversed at each copy's pose:
its groups get the candidate's own options, one :func:`lod.points.follow_select.follow_batch` per group
traversed by :func:`lod.points.jobs.follow_traverse` (the same results, the root decided in line),
whose per-instance totals the pass below prices), then one pass
(:func:`_rows_kernel`) that reads each instance's model rows once and fills every candidate's row: the
triangle chain's cheapest admissible level (the projected error of
:func:`lod.auto.candidates.projected_errors` per level), the point candidate's price, the cluster
candidate's cost lower bound (the exact cut, per group by the candidate itself, only where the bound
undercuts the best option so far, as the per-group path does); then the plans
(:func:`lod.auto.flat_plans.price`: every pure plan and the mixed one in one parallel pass). The Python work per frame is a
constant per group (a few tables and the views handed back); the per-instance work is numba, parallel.

What comes out is what the per-group path makes: the same ``groups`` list ((group, [_Block], columns)
per master batch, each block's arrays views of the flat rows, the candidates' ``Options`` with the plans
their ``emit`` reads) and the same frame plans, so the plan choice and the emission
(:meth:`lod.auto.candidates.Candidate.emit`) are shared. Costs, errors and choices are computed by the same
expressions, hence equal; the plans' summed seconds are added in fixed chunks of instances (independent of
the thread count), so they may differ from the serial sum in the last bits. A candidate without a flat form
(any other class) makes the selector use the per-group path (:meth:`lod.auto.mode.AutoSelector._options`),
which stays the reference the tests compare with (tests/lod/auto/test_auto_flat.py).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from lod.auto import candidates as ac
from lod.auto import flat_points as fp
from lod.auto.plans import _Block
from lod.points.jobs import follow_traverse

class FlatGroup:
    """A master batch (:class:`lod.auto.candidates.Group`'s fields) whose float64 model rows are
    computed only when a candidate asks for them (the per-group cluster cut)."""

    __slots__ = ("char", "batch", "_rows")

    def __init__(self, char: int, batch):
        self.char, self.batch, self._rows = int(char), batch, None

    @property
    def k(self) -> int:
        return int(self.batch.n_instances)

    @property
    def rows(self) -> np.ndarray:
        if self._rows is None:
            d = np.asarray(self.batch.instance_data, np.float32)
            self._rows = d[:, :12].astype(np.float64).reshape(-1, 3, 4)
        return self._rows


class LazyOptions:
    """:class:`lod.auto.candidates.Options` whose ``error`` (and ``plan``) are computed when read: the
    flat path prices from the reduced rows and only the emission (or a test) reads them."""

    def __init__(self, cost, error, plan, labels):
        self.cost, self._error, self._plan, self.labels = cost, error, plan, tuple(labels)

    @property
    def error(self):
        if callable(self._error):
            self._error = self._error()
        return self._error

    @property
    def plan(self):
        if callable(self._plan):
            self._plan = self._plan()
        return self._plan


class FlatGroups(list):
    """The ``groups`` list of the selector ([(group, [_Block], columns)]) with the flat rows its blocks
    view (``rows``: a dict of the arrays :func:`price` reads). Replacing an item (the exact pricing of
    instances a cost lower bound skipped) makes the rows stale: the plans are then priced from the blocks."""

    def __init__(self, items, rows):
        super().__init__(items)
        self.rows = rows
        self.stale = False

    def __setitem__(self, i, v):
        self.stale = True
        super().__setitem__(i, v)


def _packed(arrays):
    """The one array of which ``arrays`` are consecutive row slices (the master selection packs every
    batch into one array, :func:`lod.full.pack.instance_batches`), or their concatenation."""
    base = arrays[0].base
    if isinstance(base, np.ndarray) and base.flags.c_contiguous and base.ndim == arrays[0].ndim and base.size:
        p0 = base.__array_interface__["data"][0]
        stride = base.strides[0]
        first = (arrays[0].__array_interface__["data"][0] - p0) // stride
        at = first
        for a in arrays:
            if a.base is not base or a.__array_interface__["data"][0] != p0 + at * stride \
                    or not a.flags.c_contiguous:
                break
            at += a.shape[0]
        else:
            return base[first:at]
    return np.ascontiguousarray(np.concatenate(arrays))


# ---------------------------------------------------------------------------- one pass over the instances
@njit(cache=True, parallel=True)
def _rows_kernel(data, gof, scale_px, bound, t_chain, t_cols, t_err, t_cost, t_sphere, rp, p_on, p_a, p_dev, p_same,
                 p_sphere, pos, psum, tsum, c_pts, c_tri, c_pinst, splat, pts, tris, pcost, perr, rc, c_on, c_a,
                 c_base, c_root, c_r0, c_r1, spheres, planes, lb, need, bmin, barg, opt, sk):  # pragma: no cover
    """Every candidate's row of one instance in one pass (the model rows read once; their largest axis
    scale and the distance to the clip sphere computed once, as each reference computes them):

    - row 0, the triangle chain: the cheapest level whose projected error (the rule of
      :func:`lod.auto.candidates.projected_errors`) is within the bound, level 0 always admissible
      (:func:`lod.auto.plans.block_min` with ``fallback``); a group without a chain, its one option;
    - row ``rp`` (>= 0), the point candidate: points and triangles of the instance's traversal (sorted row
      ``pos[i]``), cost ``c_pts * points + c_tri * triangles + c_pinst``, error ``splat`` plus the keyframe
      deviation projected as :func:`lod.auto.candidates.projected_errors` does, its option or +inf;
    - row ``rc`` (>= 0), the cluster candidate: its cost lower bound (one instance and one cluster, plus
      the root cut where every root sphere lies inside every plane: :meth:`lod.auto.candidates.
      ClustersCandidate.cost_lower_bound`) and whether it undercuts the cheapest option of the rows before
      (``need``); instances not needed get the per-group path's skipped entries (error +inf, priced at
      the bound), the needed ones are left to the exact cut (:func:`_clusters_finish`)."""
    for i in prange(gof.shape[0]):
        g = gof[i]
        s = 0.0
        for b in range(3):
            n = np.sqrt(np.float64(data[i, b]) ** 2 + np.float64(data[i, 4 + b]) ** 2 + np.float64(data[i, 8 + b]) ** 2)
            if n > s:
                s = n
        # triangles
        dt = 0.0
        if not t_chain[g]:
            bmin[0, i] = t_cost[g, 0]
            barg[0, i] = 0
        else:
            d2 = 0.0
            for a in range(3):
                x = (np.float64(data[i, 4 * a]) * t_sphere[g, 0] + np.float64(data[i, 4 * a + 1]) * t_sphere[g, 1]
                     + np.float64(data[i, 4 * a + 2]) * t_sphere[g, 2] + np.float64(data[i, 4 * a + 3]))
                d2 += x * x
            dt = np.sqrt(d2) - t_sphere[g, 3] * s
            f = 0.0
            if dt > 0.0:
                f = s * scale_px / dt
            best = np.inf
            arg = 0
            for j in range(t_cols[g]):
                e = t_err[g, j]
                if dt > 0.0:
                    err = e * f
                else:
                    err = np.inf if e > 0.0 else 0.0
                c = t_cost[g, j]
                if (err <= bound or j == 0) and c < best:
                    best = c
                    arg = j
            bmin[0, i] = best
            barg[0, i] = arg
        # points
        if rp >= 0:
            if not p_on[g]:
                bmin[rp, i] = np.inf
                barg[rp, i] = 0
            else:
                k = pos[i]
                pp = psum[k]
                tt = tsum[k]
                pts[i] = pp
                tris[i] = tt
                c = c_pts * np.float64(pp) + c_tri * np.float64(tt) + c_pinst
                e = splat
                dev = p_dev[g]
                if dev > 0.0:
                    if p_same[g] and t_chain[g]:
                        d = dt
                    else:
                        d2 = 0.0
                        for a in range(3):
                            x = (np.float64(data[i, 4 * a]) * p_sphere[g, 0]
                                 + np.float64(data[i, 4 * a + 1]) * p_sphere[g, 1]
                                 + np.float64(data[i, 4 * a + 2]) * p_sphere[g, 2] + np.float64(data[i, 4 * a + 3]))
                            d2 += x * x
                        d = np.sqrt(d2) - p_sphere[g, 3] * s
                    if d > 0.0:
                        e = e + dev * (s * scale_px / d)
                    else:
                        e = e + np.inf
                pcost[i] = c
                perr[i] = e
                bmin[rp, i] = c if (e <= bound and c < np.inf) else np.inf
                barg[rp, i] = p_a[g]
        # clusters
        if rc >= 0:
            if not c_on[g]:
                need[i] = False
                bmin[rc, i] = np.inf
                barg[rc, i] = 0
                sk[rc, i] = False
                continue
            v = c_base[g]
            if c_r1[g] > c_r0[g]:
                ok = True
                for q in range(c_r0[g], c_r1[g]):
                    rad = spheres[q, 3] * s
                    c0 = (np.float64(data[i, 0]) * spheres[q, 0] + np.float64(data[i, 1]) * spheres[q, 1]
                          + np.float64(data[i, 2]) * spheres[q, 2] + np.float64(data[i, 3]))
                    c1 = (np.float64(data[i, 4]) * spheres[q, 0] + np.float64(data[i, 5]) * spheres[q, 1]
                          + np.float64(data[i, 6]) * spheres[q, 2] + np.float64(data[i, 7]))
                    c2 = (np.float64(data[i, 8]) * spheres[q, 0] + np.float64(data[i, 9]) * spheres[q, 1]
                          + np.float64(data[i, 10]) * spheres[q, 2] + np.float64(data[i, 11]))
                    for p in range(planes.shape[0]):
                        if not (planes[p, 0] * c0 + planes[p, 1] * c1 + planes[p, 2] * c2 + planes[p, 3] >= rad):
                            ok = False
                if ok:
                    v = v + c_root[g]
            lb[i] = v
            best = np.inf
            for j in range(rc):
                if bmin[j, i] < best:
                    best = bmin[j, i]
            need[i] = v < best
            barg[rc, i] = c_a[g]
            if not need[i]:
                bmin[rc, i] = np.inf
                opt[rc, i] = v
                sk[rc, i] = True
            else:
                sk[rc, i] = False


def _tri_tables(c, frame, groups, bound, coef):
    """The triangle candidate's tables for :func:`_rows_kernel` and its per-group Options (the chain
    rep of each group, or its one full-detail option)."""
    G = len(groups)
    chains = c._chains
    Lmax = max([ch.n_levels for ch in chains.values()] + [1])
    t_chain = np.zeros(G, np.bool_)
    t_cols = np.ones(G, np.int64)
    t_err = np.zeros((G, Lmax))
    t_cost = np.zeros((G, Lmax))
    t_sphere = np.zeros((G, 4))
    opts = []
    for gi, g in enumerate(groups):
        rep = chains.get(g.batch.rep)
        if rep is None:  # no chain: full detail only
            tri = float(g.batch.triangles) / max(g.k, 1)
            t_cost[gi, 0] = coef["triangles"] * tri + coef["instances"]
            opts.append(LazyOptions(np.broadcast_to(t_cost[gi, :1].copy(), (g.k, 1)), _zeros(g.k), None, ("L0",)))
            continue
        L = rep.n_levels
        cost = coef["triangles"] * rep.level_count.astype(np.float64) + coef["instances"]
        t_chain[gi] = True
        t_cols[gi] = L if bound > 0.0 else 1
        t_err[gi, :L] = rep.level_error
        t_cost[gi, :L] = cost
        t_sphere[gi] = rep.clip_sphere[g.batch.part]
        opts.append(LazyOptions(np.broadcast_to(cost, (g.k, L)), _tri_errors(rep, g, frame.scale_px), rep,
                                tuple(f"L{i}" for i in range(L))))
    return (t_chain, t_cols, t_err, t_cost, t_sphere), opts


def _zeros(k):
    return lambda: np.zeros((k, 1))


def _tri_errors(rep, g, scale_px):
    return lambda: ac.projected_errors(rep.level_error, g.rows, rep.clip_sphere[g.batch.part], scale_px)


# ---------------------------------------------------------------------------- points
class _PointsFrame:
    """The point candidate's frame before the pass over the instances: segments located, instances sorted
    and traversed (:mod:`lod.auto.flat_points`); ``tables`` for :func:`_rows_kernel`; :meth:`options`
    after it. A group whose rep follows the animation (``follow``) is not sorted into the forest's bins:
    its Options are the candidate's (:meth:`lod.auto.candidates.PointsCandidate._follow_options`, one
    follow batch traversed by :func:`lod.points.jobs.follow_traverse`: the plan
    ``("follow", rep, batch, splat)`` its emission reads), and its instances' rows
    of the traversal totals (``pos``) point at the batch's per-instance totals, appended after the sorted
    rows', so the pass prices them by the same expression (no keyframe deviation: the samples follow the
    skinned animation exactly)."""

    def __init__(self, c, frame, fl, bound, coef, g_a, t_sphere):
        from lod.points.traverse import viewport_scale

        groups, gof, data, ids = fl["groups"], fl["gof"], fl["data"], fl["ids"]
        G, N = len(groups), gof.shape[0]
        self.c, self.fl = c, fl
        p = self.p = c.splat_size(bound)
        forest = getattr(c, "_flat_forest", None)
        if forest is None:  # the per-keyframe-pair octrees (reps that follow the animation have none)
            forest = c._flat_forest = fp.build_forest({ch: r for ch, r in c.by_char.items()
                                                        if not getattr(r, "follow", False)})
        g_on = self.g_on = np.zeros(G, np.bool_)
        g_bins = np.zeros(G, np.bool_)  # the group's instances are sorted into the forest's bins
        self.follow = {}  # group -> its Options from the follow hierarchy (lod.points.follow_select)
        g_skinned = self.g_skinned = np.zeros(G, np.bool_)
        g_ns = self.g_ns = np.zeros(G, np.int64)
        g_soff = np.zeros(G, np.int64)
        g_t0, g_dur = np.zeros(G), np.zeros(G)
        g_loop = np.zeros(G, np.bool_)
        g_bin0 = self.g_bin0 = np.zeros(G, np.int64)
        g_dev = np.zeros(G)
        g_sphere = np.zeros((G, 4))
        g_same = np.zeros(G, np.bool_)
        starts, ends, bin_h, bin_skinned, self.bin_seg = [], [], [], [], []
        self.ok = True
        nseg = 0
        for gi, g in enumerate(groups):
            rep = c.by_char.get(g.char)
            if rep is None or g_a[gi] < 0:
                continue
            g_on[gi] = True
            if getattr(rep, "follow", False):  # the candidate's own per-group options: one follow_batch
                self.follow[gi] = c._follow_options(frame, g, rep, p, traverse=follow_traverse)
                continue
            g_bins[gi] = True
            g_bin0[gi] = len(bin_h)
            part = int(g.batch.part)
            if c.kinds[g.char] == "keyframed":
                bin_h.append(forest.base[g.char] + part)
                bin_skinned.append(False)
                self.bin_seg.append(part)
            else:
                kf = rep.keyframed
                a0, ns = int(kf.anim_first_seg[part]), int(kf.anim_n_segs[part])
                if ns == 0:
                    self.ok = False  # the per-group path raises what locate raises
                    return
                g_skinned[gi] = True
                g_ns[gi], g_soff[gi] = ns, nseg
                g_t0[gi], g_dur[gi], g_loop[gi] = kf.anim_t0[part], kf.anim_duration[part], kf.anim_loop[part]
                starts.append(np.asarray(kf.seg_start[a0:a0 + ns], np.float64))
                ends.append(np.asarray(kf.seg_end[a0:a0 + ns], np.float64))
                nseg += ns
                for s in range(ns):
                    bin_h.append(forest.base[g.char] + a0 + s)
                    bin_skinned.append(True)
                    self.bin_seg.append(a0 + s)
            dev = c.deviation[g.char] if g.char < len(c.deviation) else 0.0
            if dev > 0.0 and c.spheres[g.char] is not None:
                g_dev[gi] = dev
                g_sphere[gi] = c.spheres[g.char][part]
                g_same[gi] = bool(np.array_equal(g_sphere[gi], t_sphere[gi]))
        B = len(bin_h)
        binof = np.empty(N, np.int64)
        uof = np.empty(N, np.float64)
        cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(1))
        fp._locate_kernel(ids, gof, g_bins, g_skinned, g_ns, g_soff, g_t0, g_dur, g_loop, g_bin0, cat(starts),
                          cat(ends), np.ascontiguousarray(frame.state.anim_time, np.float64), binof, uof)
        chunks = max(1, min(64, N // 16384))
        first = np.linspace(0, N, chunks + 1).astype(np.int64)
        cc = fp._bin_counts(binof, first, max(B, 1))
        counts = cc.sum(axis=0)
        bstart = self.bstart = np.zeros(max(B, 1) + 1, np.int64)
        np.cumsum(counts, out=bstart[1:])
        K = int(bstart[-1])
        cstarts = np.ascontiguousarray(bstart[None, :-1] + np.cumsum(cc, axis=0) - cc)
        pos = np.empty(N, np.int64)
        self.src = np.empty(K, np.int64)
        self.pdata = np.empty((K, 16), np.float32)
        self.pids = np.empty(K, ids.dtype)
        fp._bin_scatter(binof, uof, ids, data, first, cstarts, pos, self.src, self.pdata, self.pids,
                        np.array(bin_skinned + [False], np.bool_))
        kbin = np.repeat(np.arange(max(B, 1), dtype=np.int64), counts)
        vs = viewport_scale(max(1, int(frame.size[1])), frame.camera.fov_y)
        self.pj, self.tj, psum, tsum, self.pj_at, self.tj_at = fp.traverse(
            forest, self.pdata, kbin, np.array(bin_h + [0], np.int64), bstart[:B + 1], frame.planes, vs, float(p))
        if self.follow:  # the follow groups' totals after the sorted rows' (pos points there)
            gstart, fpts, ftris = fl["gstart"], [psum], [tsum]
            at = psum.shape[0]
            for gi, o in self.follow.items():
                fb = o.plan[2]
                a, e = int(gstart[gi]), int(gstart[gi + 1])
                pos[a:e] = np.arange(at, at + (e - a))
                fpts.append(np.asarray(fb.inst_points, np.int64))
                ftris.append(np.asarray(fb.inst_triangles, np.int64))
                at += e - a
            psum, tsum = np.concatenate(fpts), np.concatenate(ftris)
        self.pts, self.tris = np.empty(N, np.int64), np.empty(N, np.int64)
        self.cost, self.err = np.empty(N), np.empty(N)
        self.tables = (g_on, np.maximum(g_a, 0), g_dev, g_same, g_sphere, pos, psum, tsum, float(coef["points"]),
                       float(coef["triangles"]), float(coef["point_instances"]), float(p), self.pts, self.tris,
                       self.cost, self.err)

    def options(self) -> list:
        """Per group the Options with the plan :meth:`lod.auto.candidates.PointsCandidate.emit` reads (None:
        no block): the group's sorted rows, ids, order, per-segment job tables (slices), totals."""
        c, fl, bstart = self.c, self.fl, self.bstart
        gstart = fl["gstart"]
        opts = [None] * len(fl["groups"])
        for gi, g in enumerate(fl["groups"]):
            if not self.g_on[gi]:
                continue
            if gi in self.follow:
                opts[gi] = self.follow[gi]
                continue
            b0 = int(self.g_bin0[gi])
            nb = 1 if not self.g_skinned[gi] else int(self.g_ns[gi])
            k0, k1 = int(bstart[b0]), int(bstart[b0 + nb])
            jobs = {}
            for q in range(b0, b0 + nb):
                a, e = int(bstart[q]), int(bstart[q + 1])
                if e > a:
                    jobs[self.bin_seg[q]] = (a - k0, e - k0, self.pj[self.pj_at[q]:self.pj_at[q + 1]],
                                             self.tj[self.tj_at[q]:self.tj_at[q + 1]])
            a_, e_ = int(gstart[gi]), int(gstart[gi + 1])
            order = None if len(jobs) == 1 else self.src[k0:k1] - a_  # the group's row of each sorted position
            plan = (c.by_char[g.char], self.pdata[k0:k1], self.pids[k0:k1], order, jobs, self.pts[a_:e_],
                    self.tris[a_:e_], self.p)
            opts[gi] = LazyOptions(self.cost[a_:e_, None], self.err[a_:e_, None], plan, (f"splat{self.p}",))
        return opts


# ---------------------------------------------------------------------------- clusters
def _cluster_tables(c, groups, coef, g_a):
    """The cluster candidate's lower-bound tables for :func:`_rows_kernel`: per group whether it has a
    block, the bound's base (one instance, one cluster) and root cut, its root spheres' range."""
    G = len(groups)
    c_on = np.zeros(G, np.bool_)
    c_base = np.zeros(G)
    c_root = np.zeros(G)
    c_r0 = np.zeros(G, np.int64)
    c_r1 = np.zeros(G, np.int64)
    spheres = []
    base = coef["instances"] + coef["clusters"]
    n0 = 0
    for gi, g in enumerate(groups):
        rep = c.by_char.get(g.char)
        if rep is None or g_a[gi] < 0:
            continue
        c_on[gi] = True
        c_base[gi] = base
        h = rep.hierarchy
        roots = np.asarray(h.roots, np.int64)
        if roots.size:
            root_tris = h.__dict__.get("_root_triangles")
            if root_tris is None:
                root_tris = h.__dict__["_root_triangles"] = float(h.triangle_counts()[roots].sum())
            c_root[gi] = coef["clusters"] * (roots.size - 1) + coef["triangles"] * root_tris
            spheres.append(np.asarray(rep.sphere64[roots], np.float64).reshape(-1, 4))
            c_r0[gi], c_r1[gi] = n0, n0 + roots.size
            n0 += roots.size
    sph = np.ascontiguousarray(np.concatenate(spheres)) if spheres else np.zeros((1, 4))
    return c_on, np.maximum(g_a, 0), c_base, c_root, c_r0, c_r1, sph


@njit(cache=True)
def _count_by_group(gof, mask, G):  # pragma: no cover - compiled
    out = np.zeros(G, np.int64)
    for i in range(gof.shape[0]):
        if mask[i]:
            out[gof[i]] += 1
    return out


def _clusters_finish(c, frame, fl, r, bound, c_on, need, g_a):
    """After the pass over the instances: per group the candidate's exact cut where the lower bound could
    win (its own ``options``, the per-group path's call), reduced by :meth:`lod.auto.plans._Block.of`
    into the group's slice of row ``r``. Returns the per-group Options and the groups with skipped
    instances."""
    groups, gstart = fl["groups"], fl["gstart"]
    G = len(groups)
    bmin, barg, opt, sk = fl["bmin"], fl["barg"], fl["opt"], fl["sk"]
    nneed = _count_by_group(fl["gof"], need, G)
    opts = [None] * G
    skipped = np.zeros(G, np.bool_)
    for gi, g in enumerate(groups):
        if not c_on[gi]:
            continue
        a, e = int(gstart[gi]), int(gstart[gi + 1])
        if nneed[gi] == 0:  # every instance at its bound, never drawn (error +inf)
            skipped[gi] = True
            opts[gi] = LazyOptions(opt[r, a:e, None], _infs(g.k), _empty_cut(c.by_char[g.char], g.k), ("cut",))
            continue
        nd = need[a:e]
        skip = None if nneed[gi] == g.k else ~nd
        o = c.options(frame, g) if skip is None else c.options(frame, g, nd)
        blk = _Block.of(c, o, int(g_a[gi]), skip, bound, False)
        bmin[r, a:e], barg[r, a:e] = blk.bmin, blk.barg
        if skip is not None:
            opt[r, a:e], sk[r, a:e] = blk.opt, skip
            skipped[gi] = True
        opts[gi] = o
    return opts, skipped


def _infs(k):
    return lambda: np.full((k, 1), np.inf)


def _empty_cut(rep, k):
    return lambda: (rep, np.zeros(k + 1, np.int64), np.zeros(0, np.int32), np.zeros(k))


# ---------------------------------------------------------------------------- the groups
def _width(c, g, bound, tri) -> int:
    """Option columns of candidate ``c``'s block for group ``g`` (0: none), as its ``options`` decides."""
    if c is tri:
        rep = c._chains.get(g.batch.rep)
        return rep.n_levels if rep is not None else 1
    if not bound > 0.0 or g.k == 0 or c.by_char.get(g.char) is None:
        return 0
    if isinstance(c, ac.PointsCandidate):
        return 1 if c.splat_size(bound) else 0
    return 1


#: candidates with a flat form (exact classes: a subclass may change what its options are)
FLAT_CANDIDATES = (ac.TrianglesCandidate, ac.ClustersCandidate, ac.PointsCandidate)


def groups(sel, frame, agents, bound: float):
    """The selector's ``groups`` ([(group, [_Block], columns)] per master batch) of the agent batches
    ``agents`` ([(character, DrawBatch)] in master order), computed over flat arrays (module docstring);
    a :class:`FlatGroups`. None when a candidate has no flat form (the per-group path then runs). The flat point
    forest holds the per-keyframe-pair octrees (``animation = "baked"``); a group of a rep that follows the
    animation is priced from its own follow batch (:class:`_PointsFrame`)."""
    order = sel._order()
    if not agents or any(type(c) not in FLAT_CANDIDATES for c in order) or \
            sum(isinstance(c, ac.PointsCandidate) for c in order) > 1 or \
            sum(isinstance(c, ac.ClustersCandidate) for c in order) > 1:
        return None
    tri = order[0]
    gs = [FlatGroup(ri, b) for ri, b in agents]
    ids = _packed([np.asarray(b.instance_ids) for _, b in agents])
    data = _packed([np.asarray(b.instance_data) for _, b in agents])
    if data.dtype != np.float32 or data.ndim != 2 or data.shape[1] != 16:
        return None
    G = len(gs)
    ks = np.array([g.k for g in gs], np.int64)
    gstart = np.zeros(G + 1, np.int64)
    np.cumsum(ks, out=gstart[1:])
    N = int(gstart[-1])
    gof = np.repeat(np.arange(G, dtype=np.int64), ks)
    nb = len(order)
    # the block layout of every group: candidates in order, each with its first column (-1: no block)
    g_a = np.full((nb, G), -1, np.int64)
    ncols = np.zeros(G, np.int64)
    widths = np.zeros((nb, G), np.int64)
    for r, c in enumerate(order):
        for gi, g in enumerate(gs):
            m = _width(c, g, bound, tri) if (c is tri or bound > 0.0) else 0
            if m:
                g_a[r, gi], widths[r, gi] = ncols[gi], m
                ncols[gi] += m
    fl = {"groups": gs, "ids": ids, "data": data, "gof": gof, "gstart": gstart,
          "bmin": np.empty((nb, N)), "barg": np.empty((nb, N), np.int64), "opt": np.empty((nb, N)),
          "sk": np.zeros((nb, N), np.bool_)}
    coef = frame.model.coefficients
    opts = [[None] * G for _ in range(nb)]
    skipped = np.zeros((nb, G), np.bool_)
    ttab, opts[0] = _tri_tables(tri, frame, gs, bound, coef)
    rp = rc = -1
    ptab = (np.zeros(1, np.bool_), np.zeros(1, np.int64), np.zeros(1), np.zeros(1, np.bool_), np.zeros((1, 4)),
            np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64), 0.0, 0.0, 0.0, 0.0,
            np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1), np.zeros(1))
    ctab = (np.zeros(1, np.bool_), np.zeros(1, np.int64), np.zeros(1), np.zeros(1), np.zeros(1, np.int64),
            np.zeros(1, np.int64), np.zeros((1, 4)))
    pf = None
    for r, c in enumerate(order[1:], 1):
        if not (g_a[r] >= 0).any():  # no block anywhere (e.g. a zero bound)
            fl["bmin"][r] = np.inf
            fl["barg"][r] = 0
        elif isinstance(c, ac.PointsCandidate):
            pf = _PointsFrame(c, frame, fl, bound, coef, g_a[r], ttab[4])
            if not pf.ok:
                return None
            rp, ptab = r, pf.tables
        else:
            rc, ctab = r, _cluster_tables(c, gs, coef, g_a[r])
    lb = np.empty(N if rc >= 0 else 1)
    need = np.zeros(N if rc >= 0 else 1, np.bool_)
    _rows_kernel(data, gof, float(frame.scale_px), float(bound), *ttab, rp, *ptab[:12], *ptab[12:], rc, *ctab[:6],
                 ctab[6], np.ascontiguousarray(frame.planes, np.float64), lb, need, fl["bmin"], fl["barg"],
                 fl["opt"], fl["sk"])
    if pf is not None:
        opts[rp] = pf.options()
    if rc >= 0:
        opts[rc], skipped[rc] = _clusters_finish(order[rc], frame, fl, rc, bound, ctab[0], need, g_a[rc])
    items = []
    for gi, g in enumerate(gs):
        a, e = int(gstart[gi]), int(gstart[gi + 1])
        bl = []
        for r, c in enumerate(order):
            if g_a[r, gi] < 0:
                continue
            b = _Block()
            b.cand, b.options, b.a, b.m = c, opts[r][gi], int(g_a[r, gi]), int(widths[r, gi])
            b.bmin, b.barg = fl["bmin"][r, a:e], fl["barg"][r, a:e]
            if skipped[r, gi]:
                b.skipped = fl["sk"][r, a:e]
                b.opt = np.where(b.skipped, fl["opt"][r, a:e], b.bmin)
            else:
                b.skipped, b.opt = None, b.bmin
            bl.append(b)
        items.append((g, bl, int(ncols[gi])))
    fl.update(g_a=g_a, widths=widths, ncols=ncols, order=order)
    return FlatGroups(items, fl)


__all__ = ["FLAT_CANDIDATES", "FlatGroup", "FlatGroups", "LazyOptions", "groups"]
