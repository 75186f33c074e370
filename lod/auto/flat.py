"""Mode auto's per-instance selection over flat arrays of all instances (issue 26, item 2).

The per-group path of :class:`lod.auto.mode.AutoSelector` asks every candidate, master batch by master
batch, for an :class:`lod.auto.candidates.Options` table ((k, m) costs and errors), reduces each to the
cheapest admissible option per instance (:class:`lod.auto.plans._Block`) and lays the blocks of all
groups side by side to price the frame plans (:func:`lod.auto.plans.price_plans`). At a million agents
that is a second and a half of numpy on million-row temporaries: the float64 model rows of every group,
the (k, levels) projected errors, the point candidate's copies and sorts, the gathers of the side-by-side
layout.

Here every step is one numba pass over the instances of all groups at once, written straight into the
side-by-side layout (one row per candidate, one column per instance, groups in master order; a group
without a candidate's block has +inf there): the triangle chains' cheapest admissible level
(:func:`_tri_kernel`, the projected error of :func:`lod.auto.candidates.projected_errors` per level), the
point candidate's traversal and price (:mod:`lod.auto.flat_points`), the cluster candidate's cost lower
bound (:func:`_lb_kernel`; the exact cut, per group by the candidate itself, only where the bound undercuts
the best option so far, as the per-group path does), then the plans (:func:`price`: every pure plan and
the mixed one in one parallel pass, :func:`_plans_chunks`). The Python work per frame is a constant per
group (a few tables and the views handed back); the per-instance work is numba, parallel.

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
from lod.auto.plans import _Block, _finish_plans
from lod.chains import chain as tm_chain

#: instances per chunk of the plan pricing (fixed, so the sums do not depend on the thread count)
PLAN_CHUNK = 32768


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


# ---------------------------------------------------------------------------- triangles
@njit(cache=True, parallel=True)
def _tri_kernel(data, gof, g_chain, g_cols, g_err, g_cost, g_sphere, scale_px, bound, bmin,
                barg):  # pragma: no cover - compiled
    """Per instance the cheapest triangle-chain level whose projected error (the rule of
    :func:`lod.auto.candidates.projected_errors`) is within the bound, level 0 always admissible
    (:func:`lod.auto.plans.block_min` with ``fallback``); a group without a chain: its one option."""
    for i in prange(gof.shape[0]):
        g = gof[i]
        if not g_chain[g]:
            bmin[i] = g_cost[g, 0]
            barg[i] = 0
            continue
        s = 0.0
        for b in range(3):
            n = np.sqrt(np.float64(data[i, b]) ** 2 + np.float64(data[i, 4 + b]) ** 2 + np.float64(data[i, 8 + b]) ** 2)
            if n > s:
                s = n
        d2 = 0.0
        for a in range(3):
            x = (np.float64(data[i, 4 * a]) * g_sphere[g, 0] + np.float64(data[i, 4 * a + 1]) * g_sphere[g, 1]
                 + np.float64(data[i, 4 * a + 2]) * g_sphere[g, 2] + np.float64(data[i, 4 * a + 3]))
            d2 += x * x
        d = np.sqrt(d2) - g_sphere[g, 3] * s
        f = 0.0
        if d > 0.0:
            f = s * scale_px / d
        best = np.inf
        arg = 0
        for j in range(g_cols[g]):
            e = g_err[g, j]
            if d > 0.0:
                err = e * f
            else:
                err = np.inf if e > 0.0 else 0.0
            c = g_cost[g, j]
            if (err <= bound or j == 0) and c < best:
                best = c
                arg = j
        bmin[i] = best
        barg[i] = arg


def _triangles(c, frame, fl, r, bound, coef):
    """Row ``r`` of the flat layout for the triangle candidate; returns the per-group Options."""
    G = len(fl["groups"])
    chains = c._chains
    Lmax = max([ch.n_levels for ch in chains.values()] + [1])
    g_chain = np.zeros(G, np.bool_)
    g_cols = np.ones(G, np.int64)
    g_err = np.zeros((G, Lmax))
    g_cost = np.zeros((G, Lmax))
    g_sphere = np.zeros((G, 4))
    opts = []
    for gi, g in enumerate(fl["groups"]):
        rep = chains.get(g.batch.rep)
        if rep is None:  # no chain: full detail only
            tri = float(g.batch.triangles) / max(g.k, 1)
            g_cost[gi, 0] = coef["triangles"] * tri + coef["instances"]
            opts.append(LazyOptions(np.broadcast_to(g_cost[gi, :1].copy(), (g.k, 1)),
                                    _zeros(g.k), None, ("L0",)))
            continue
        L = rep.n_levels
        cost = coef["triangles"] * rep.level_count.astype(np.float64) + coef["instances"]
        g_chain[gi] = True
        g_cols[gi] = L if bound > 0.0 else 1
        g_err[gi, :L] = rep.level_error
        g_cost[gi, :L] = cost
        g_sphere[gi] = rep.clip_sphere[g.batch.part]
        opts.append(LazyOptions(np.broadcast_to(cost, (g.k, L)), _tri_errors(rep, g, frame.scale_px), rep,
                                tuple(f"L{i}" for i in range(L))))
    _tri_kernel(fl["data"], fl["gof"], g_chain, g_cols, g_err, g_cost, g_sphere, float(frame.scale_px),
                float(bound), fl["bmin"][r], fl["barg"][r])
    return opts


def _zeros(k):
    return lambda: np.zeros((k, 1))


def _tri_errors(rep, g, scale_px):
    return lambda: ac.projected_errors(rep.level_error, g.rows, rep.clip_sphere[g.batch.part], scale_px)


# ---------------------------------------------------------------------------- points
def _points(c, frame, fl, r, bound, coef):
    """Row ``r`` for the point candidate (:mod:`lod.auto.flat_points`); the per-group Options (None:
    no block) with the plans :meth:`lod.auto.candidates.PointsCandidate.emit` reads."""
    from lod.points.traverse import viewport_scale

    groups, gof, data, ids = fl["groups"], fl["gof"], fl["data"], fl["ids"]
    G, N = len(groups), gof.shape[0]
    p = c.splat_size(bound)
    forest = getattr(c, "_flat_forest", None)
    if forest is None:
        forest = c._flat_forest = fp.build_forest(c.by_char)
    g_on = np.zeros(G, np.bool_)
    g_skinned = np.zeros(G, np.bool_)
    g_ns = np.zeros(G, np.int64)
    g_soff = np.zeros(G, np.int64)
    g_t0, g_dur = np.zeros(G), np.zeros(G)
    g_loop = np.zeros(G, np.bool_)
    g_bin0 = np.zeros(G, np.int64)
    g_dev = np.zeros(G)
    g_sphere = np.zeros((G, 4))
    starts, ends, bin_h, bin_skinned, bin_group = [], [], [], [], []
    nseg = 0
    for gi, g in enumerate(groups):
        rep = c.by_char.get(g.char)
        if rep is None or p == 0 or g.k == 0:
            continue
        g_on[gi] = True
        g_bin0[gi] = len(bin_h)
        part = int(g.batch.part)
        if c.kinds[g.char] == "keyframed":
            bin_h.append(forest.base[g.char] + part)
            bin_skinned.append(False)
            bin_group.append((gi, part))
        else:
            kf = rep.keyframed
            a0, ns = int(kf.anim_first_seg[part]), int(kf.anim_n_segs[part])
            if ns == 0:
                return None  # the per-group path raises what locate raises
            g_skinned[gi] = True
            g_ns[gi], g_soff[gi] = ns, nseg
            g_t0[gi], g_dur[gi], g_loop[gi] = kf.anim_t0[part], kf.anim_duration[part], kf.anim_loop[part]
            starts.append(np.asarray(kf.seg_start[a0:a0 + ns], np.float64))
            ends.append(np.asarray(kf.seg_end[a0:a0 + ns], np.float64))
            nseg += ns
            for s in range(ns):
                bin_h.append(forest.base[g.char] + a0 + s)
                bin_skinned.append(True)
                bin_group.append((gi, a0 + s))
        dev = c.deviation[g.char] if g.char < len(c.deviation) else 0.0
        if dev > 0.0 and c.spheres[g.char] is not None:
            g_dev[gi] = dev
            g_sphere[gi] = c.spheres[g.char][part]
    B = len(bin_h)
    binof = np.empty(N, np.int64)
    uof = np.empty(N, np.float64)
    cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(1))
    fp._locate_kernel(ids, gof, g_on, g_skinned, g_ns, g_soff, g_t0, g_dur, g_loop, g_bin0, cat(starts), cat(ends),
                      np.ascontiguousarray(frame.state.anim_time, np.float64), binof, uof)
    chunks = max(1, min(64, N // 16384))
    first = np.linspace(0, N, chunks + 1).astype(np.int64)
    cc = fp._bin_counts(binof, first, max(B, 1))
    counts = cc.sum(axis=0)
    bstart = np.zeros(max(B, 1) + 1, np.int64)
    np.cumsum(counts, out=bstart[1:])
    K = int(bstart[-1])
    cstarts = np.ascontiguousarray(bstart[None, :-1] + np.cumsum(cc, axis=0) - cc)
    pos = np.empty(N, np.int64)
    src = np.empty(K, np.int64)
    pdata = np.empty((K, 16), np.float32)
    pids = np.empty(K, ids.dtype)
    fp._bin_scatter(binof, uof, ids, data, first, cstarts, pos, src, pdata, pids,
                    np.array(bin_skinned + [False], np.bool_))
    kbin = np.repeat(np.arange(max(B, 1), dtype=np.int64), counts)
    vs = viewport_scale(max(1, int(frame.size[1])), frame.camera.fov_y)
    pj, tj, psum, tsum, pj_at, tj_at = fp.traverse(forest, pdata, kbin, np.array(bin_h + [0], np.int64),
                                                   bstart[:B + 1], frame.planes, vs, float(p))
    pts = np.empty(N, np.int64)
    tris = np.empty(N, np.int64)
    cost = np.empty(N)
    err = np.empty(N)
    bmin = fl["bmin"][r]
    bmin[:] = np.inf
    fp._price_kernel(data, gof, g_on, g_dev, g_sphere, pos, psum, tsum, float(coef["points"]),
                     float(coef["triangles"]), float(coef["point_instances"]), float(p), float(frame.scale_px),
                     float(bound), pts, tris, cost, err, bmin)
    opts = [None] * G
    gstart = fl["gstart"]
    for gi, g in enumerate(groups):
        if not g_on[gi]:
            continue
        b0 = int(g_bin0[gi])
        nb = 1 if not g_skinned[gi] else int(g_ns[gi])
        k0, k1 = int(bstart[b0]), int(bstart[b0 + nb])
        jobs = {}
        used = 0
        for q in range(b0, b0 + nb):
            a, e = int(bstart[q]), int(bstart[q + 1])
            if e > a:
                used += 1
                jobs[bin_group[q][1]] = (a - k0, e - k0, pj[pj_at[q]:pj_at[q + 1]], tj[tj_at[q]:tj_at[q + 1]])
        a_, e_ = int(gstart[gi]), int(gstart[gi + 1])
        order = None if used == 1 else src[k0:k1] - a_  # the group's row of each sorted position
        plan = (c.by_char[g.char], pdata[k0:k1], pids[k0:k1], order, jobs, pts[a_:e_], tris[a_:e_], p)
        opts[gi] = LazyOptions(cost[a_:e_, None], err[a_:e_, None], plan, (f"splat{p}",))
    return opts


# ---------------------------------------------------------------------------- clusters
@njit(cache=True, parallel=True)
def _lb_kernel(data, gof, g_on, g_a, g_base, g_root, g_r0, g_r1, spheres, planes, bmin, before, lb, need, brow,
               arow, orow, srow):  # pragma: no cover - compiled
    """The cluster candidate's cost lower bound per instance (:meth:`lod.auto.candidates.ClustersCandidate.
    cost_lower_bound`: one instance and one cluster, plus the root cut where every root sphere lies inside
    every plane, as :func:`lod.auto.candidates.spheres_inside` tests it) and whether it undercuts the
    cheapest option of the rows ``0 .. before - 1`` (``need``). Instances not needed get the per-group
    path's skipped entries (error +inf, priced at the bound); the needed ones are left to the exact cut."""
    for i in prange(gof.shape[0]):
        g = gof[i]
        if not g_on[g]:
            need[i] = False
            brow[i] = np.inf
            arow[i] = 0
            srow[i] = False
            continue
        v = g_base[g]
        if g_r1[g] > g_r0[g]:
            s = 0.0
            for b in range(3):
                n = np.sqrt(np.float64(data[i, b]) ** 2 + np.float64(data[i, 4 + b]) ** 2
                            + np.float64(data[i, 8 + b]) ** 2)
                if n > s:
                    s = n
            ok = True
            for q in range(g_r0[g], g_r1[g]):
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
                v = v + g_root[g]
        lb[i] = v
        best = np.inf
        for j in range(before):
            if bmin[j, i] < best:
                best = bmin[j, i]
        need[i] = v < best
        arow[i] = g_a[g]
        if not need[i]:
            brow[i] = np.inf
            orow[i] = v
            srow[i] = True
        else:
            srow[i] = False


@njit(cache=True)
def _count_by_group(gof, mask, G):  # pragma: no cover - compiled
    out = np.zeros(G, np.int64)
    for i in range(gof.shape[0]):
        if mask[i]:
            out[gof[i]] += 1
    return out


def _clusters(c, frame, fl, r, bound, coef, layout):
    """Row ``r`` for the cluster candidate: the lower bound in one pass (:func:`_lb_kernel`), then per
    group the candidate's exact cut where the bound could win (its own ``options``, the per-group path's
    call), reduced by :meth:`lod.auto.plans._Block.of` into the group's slice of the rows. Returns the
    per-group Options and the groups that have skipped instances."""
    groups, gstart = fl["groups"], fl["gstart"]
    G, N = len(groups), fl["gof"].shape[0]
    g_on = np.zeros(G, np.bool_)
    g_base = np.zeros(G)
    g_root = np.zeros(G)
    g_r0 = np.zeros(G, np.int64)
    g_r1 = np.zeros(G, np.int64)
    spheres = []
    base = coef["instances"] + coef["clusters"]
    for gi, g in enumerate(groups):
        rep = c.by_char.get(g.char)
        if rep is None or layout[gi] < 0:
            continue
        g_on[gi] = True
        g_base[gi] = base
        h = rep.hierarchy
        roots = np.asarray(h.roots, np.int64)
        if roots.size:
            root_tris = h.__dict__.get("_root_triangles")
            if root_tris is None:
                root_tris = h.__dict__["_root_triangles"] = float(h.triangle_counts()[roots].sum())
            g_root[gi] = coef["clusters"] * (roots.size - 1) + coef["triangles"] * root_tris
            n0 = sum(len(s) for s in spheres)
            spheres.append(np.asarray(rep.sphere64[roots], np.float64).reshape(-1, 4))
            g_r0[gi], g_r1[gi] = n0, n0 + roots.size
    sph = np.ascontiguousarray(np.concatenate(spheres)) if spheres else np.zeros((1, 4))
    lb = np.empty(N)
    need = np.empty(N, np.bool_)
    bmin, barg, opt, sk = fl["bmin"], fl["barg"], fl["opt"], fl["sk"]
    _lb_kernel(fl["data"], fl["gof"], g_on, layout, g_base, g_root, g_r0, g_r1, sph,
               np.ascontiguousarray(frame.planes, np.float64), bmin, r, lb, need, bmin[r], barg[r], opt[r], sk[r])
    nneed = _count_by_group(fl["gof"], need, G)
    opts = [None] * G
    skipped = np.zeros(G, np.bool_)
    for gi, g in enumerate(groups):
        if not g_on[gi]:
            continue
        a, e = int(gstart[gi]), int(gstart[gi + 1])
        if nneed[gi] == 0:  # every instance at its bound, never drawn (error +inf)
            skipped[gi] = True
            opts[gi] = LazyOptions(opt[r, a:e, None], _infs(g.k), _empty_cut(c.by_char[g.char], g.k), ("cut",))
            continue
        nd = need[a:e]
        skip = None if nneed[gi] == g.k else ~nd
        o = c.options(frame, g) if skip is None else c.options(frame, g, nd)
        blk = _Block.of(c, o, int(layout[gi]), skip, bound, False)
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
@njit(cache=True, parallel=True)
def _fill_column(gof, g_a, barg):  # pragma: no cover - compiled
    for i in prange(gof.shape[0]):
        a = g_a[gof[i]]
        barg[i] = a if a >= 0 else 0


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
    a :class:`FlatGroups`. None when a candidate has no flat form (the per-group path then runs)."""
    order = sel._order()
    if not agents or any(type(c) not in FLAT_CANDIDATES for c in order):
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
    for r, c in enumerate(order):
        if not (g_a[r] >= 0).any():
            fl["bmin"][r] = np.inf
            fl["barg"][r] = 0
            continue
        if c is tri:
            opts[r] = _triangles(c, frame, fl, r, bound, coef)
        elif isinstance(c, ac.PointsCandidate):
            o = _points(c, frame, fl, r, bound, coef)
            if o is None:
                return None
            opts[r] = o
            _fill_column(gof, g_a[r], fl["barg"][r])
        else:
            opts[r], skipped[r] = _clusters(c, frame, fl, r, bound, coef, g_a[r])
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


# ---------------------------------------------------------------------------- the plans
@njit(cache=True, parallel=True)
def _plans_chunks(bmin, barg, opt, sk, pure, use, gof, cbase, chunk, ch, cost, exact,
                  used):  # pragma: no cover - compiled
    """:func:`lod.auto.plans._plans_kernel` over all instances, in chunks of ``chunk`` instances in
    parallel: per chunk c the summed seconds ``cost[c]``, ``exact[c]`` and the option columns drawn
    ``used[c]`` (group's first column ``cbase[g]`` + the instance's column); ``ch`` the chosen column
    within the group. A row's ``opt`` is read only where ``sk`` (skipped: priced at the bound)."""
    nb, N = bmin.shape
    n_pure = pure.shape[0]
    for c in prange(cost.shape[0]):
        i0 = c * chunk
        i1 = min(N, i0 + chunk)
        for q in range(n_pure + 1):
            cost[c, q] = 0.0
            exact[c, q] = True
        for i in range(i0, i1):
            cb = cbase[gof[i]]
            for q in range(n_pure):
                x = pure[q]
                o = opt[x, i] if sk[x, i] else bmin[x, i]
                if x > 0 and np.isfinite(o):
                    ch[q, i] = barg[x, i]
                    cost[c, q] += o
                    if sk[x, i]:
                        exact[c, q] = False
                else:
                    ch[q, i] = barg[0, i]
                    cost[c, q] += bmin[0, i]
                used[c, q, cb + ch[q, i]] = True
            best = np.inf
            w = 0
            for j in range(nb):
                if use[j] and bmin[j, i] < best:  # the first minimum: ties to the lower row
                    best = bmin[j, i]
                    w = j
            ch[n_pure, i] = barg[w, i]
            cost[c, n_pure] += bmin[w, i]
            used[c, n_pure, cb + barg[w, i]] = True
            for j in range(nb):
                if use[j] and sk[j, i] and opt[j, i] < bmin[w, i]:
                    exact[c, n_pure] = False


@njit(cache=True, parallel=True)
def _savings(bmin, mine, rest, chunk, out):  # pragma: no cover - compiled
    """Per chunk of instances: the sum of (cheapest of rows ``rest`` - row ``mine``) where row ``mine``
    is strictly cheaper (:func:`lod.auto.plans._use_mixed_rows`)."""
    N = bmin.shape[1]
    for c in prange(out.shape[0]):
        s = 0.0
        for i in range(c * chunk, min(N, (c + 1) * chunk)):
            other = np.inf
            for j in rest:
                if bmin[j, i] < other:
                    other = bmin[j, i]
            m = bmin[mine, i]
            if m < other:
                s += other - m
        out[c] = s


def _chunks(N: int) -> int:
    return max(1, -(-N // PLAN_CHUNK))


def price(candidates, fg: FlatGroups, coefficients, fc: dict, fixed=(0.0, frozenset()), order=None) -> dict:
    """The frame plans (:func:`lod.auto.plans.price_plans`, same contract) from the flat rows of
    :func:`groups`: the candidates the mixed plan may use, then every pure plan and the mixed one in one
    parallel pass (:func:`_plans_chunks`)."""
    c = coefficients
    fl = fg.rows
    order = list(fl["order"] if order is None else order)
    names = [cand.name for cand in candidates]
    row = {cand.name: r for r, cand in enumerate(order)}
    if row[names[0]] != 0:
        raise ValueError("flat.price: the triangle candidate's blocks must come first")
    bmin, barg, opt, sk, gof = fl["bmin"], fl["barg"], fl["opt"], fl["sk"], fl["gof"]
    N = gof.shape[0]
    C = _chunks(N)
    use = {cand.name for cand in candidates}
    for cand in candidates[1:]:
        if fc.get(cand.name, 0.0) <= 0.0 or cand.name in fixed[1]:
            continue
        rest = np.array([row[n] for n in use if n != cand.name], np.int64)
        part = np.empty(C)
        _savings(bmin, row[cand.name], rest, PLAN_CHUNK, part)
        if float(part.sum()) <= fc[cand.name]:
            use.discard(cand.name)
    n_plans = len(names) + 1
    ncols = fl["ncols"]
    cbase = np.zeros(ncols.shape[0] + 1, np.int64)
    np.cumsum(ncols, out=cbase[1:])
    ch = np.empty((n_plans, N), np.int64)
    cost = np.empty((C, n_plans))
    ex = np.empty((C, n_plans), np.bool_)
    used = np.zeros((C, n_plans, int(cbase[-1])), np.bool_)
    _plans_chunks(bmin, barg, opt, sk, np.array([row[n] for n in names], np.int64),
                  np.array([cand.name in use for cand in order]), gof, cbase, PLAN_CHUNK, ch, cost, ex, used)
    opts_used = used.any(axis=0)
    totals = float(c["frame"]) + float(fixed[0]) + cost.sum(axis=0) + c["batches"] * opts_used.sum(axis=1)
    # the candidate row of every option column
    col_cand = np.zeros(int(cbase[-1]), np.int64)
    g_a, widths = fl["g_a"], fl["widths"]
    for r in range(len(order)):
        for gi in np.flatnonzero(g_a[r] >= 0).tolist():
            a = int(cbase[gi] + g_a[r, gi])
            col_cand[a:a + int(widths[r, gi])] = r
    drawn = [set(fixed[1]) | {order[r].name for r in np.unique(col_cand[opts_used[q]]).tolist()}
             for q in range(n_plans)]
    cuts = fl["gstart"][1:-1]
    choices = [np.split(ch[q], cuts) for q in range(n_plans)]
    return _finish_plans(names, choices, totals, ex.all(axis=0), drawn, fc)


__all__ = ["FLAT_CANDIDATES", "FlatGroup", "FlatGroups", "LazyOptions", "groups", "price"]
