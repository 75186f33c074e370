"""The frame plans of mode auto priced from the flat rows of :func:`lod.auto.flat.groups` (issue 26, item 2):
:func:`lod.auto.plans.price_plans`'s contract, every pure plan and the mixed one in one parallel pass over the
instances (:func:`_plans_chunks`), the candidates the mixed plan may use from chunked sums of their savings
(:func:`_savings`). The summed seconds are added in fixed chunks of :data:`PLAN_CHUNK` instances (independent of
the thread count), so they may differ from the serial sum of the per-group path in the last bits; the choices
are the same (tests/lod/auto/test_auto_flat.py).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from lod.auto.plans import _finish_plans

#: instances per chunk of the plan pricing (fixed, so the sums do not depend on the thread count)
PLAN_CHUNK = 32768


@njit(cache=True, parallel=True)
def _plans_chunks(bmin, barg, opt, sk, pure, use, gof, cbase, chunk, ch, cost, exact,
                  used, split):  # pragma: no cover - compiled
    """:func:`lod.auto.plans._plans_kernel` over all instances, in chunks of ``chunk`` instances in
    parallel: per chunk c the summed seconds ``cost[c]``, ``exact[c]``, the option columns drawn
    ``used[c]`` (group's first column ``cbase[g]`` + the instance's column) and the seconds per block row
    ``split[c]``; ``ch`` the chosen column within the group. A row's ``opt`` is read only where ``sk``
    (skipped: priced at the bound)."""
    nb, N = bmin.shape
    n_pure = pure.shape[0]
    cols = used.shape[2]
    for c in prange(cost.shape[0]):
        i0 = c * chunk
        i1 = min(N, i0 + chunk)
        acc = np.zeros(n_pure + 1)  # the chunk's sums and flags in locals, written back once
        spl = np.zeros((n_pure + 1, nb))
        ex = np.ones(n_pure + 1, np.bool_)
        us = np.zeros((n_pure + 1, cols), np.bool_)
        for i in range(i0, i1):
            cb = cbase[gof[i]]
            b0 = bmin[0, i]
            a0 = barg[0, i]
            for q in range(n_pure):
                x = pure[q]
                col = a0
                if x > 0:
                    s = sk[x, i]
                    o = opt[x, i] if s else bmin[x, i]
                    if np.isfinite(o):
                        col = barg[x, i]
                        acc[q] += o
                        spl[q, x] += o
                        if s:
                            ex[q] = False
                    else:
                        acc[q] += b0
                        spl[q, 0] += b0
                else:
                    acc[q] += b0
                    spl[q, 0] += b0
                ch[q, i] = col
                us[q, cb + col] = True
            best = np.inf
            w = 0
            for j in range(nb):
                if use[j] and bmin[j, i] < best:  # the first minimum: ties to the lower row
                    best = bmin[j, i]
                    w = j
            col = barg[w, i]
            bw = bmin[w, i]
            ch[n_pure, i] = col
            acc[n_pure] += bw
            spl[n_pure, w] += bw
            us[n_pure, cb + col] = True
            for j in range(nb):
                if use[j] and sk[j, i] and opt[j, i] < bw:
                    ex[n_pure] = False
        for q in range(n_pure + 1):
            cost[c, q] = acc[q]
            exact[c, q] = ex[q]
            for j in range(nb):
                split[c, q, j] = spl[q, j]
            for k in range(cols):
                used[c, q, k] = us[q, k]


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


def price(candidates, fg, coefficients, fc: dict, fixed=(0.0, frozenset()), order=None) -> dict:
    """The frame plans (:func:`lod.auto.plans.price_plans`, same contract) from the flat rows of
    :func:`lod.auto.flat.groups` (a :class:`lod.auto.flat.FlatGroups`): the candidates the mixed plan may use, then every pure plan and the mixed one in one
    parallel pass (:func:`_plans_chunks`)."""
    c = coefficients
    fl = fg.rows
    order = list(fl["order"] if order is None else order)
    names = [cand.name for cand in candidates]
    row = {cand.name: r for r, cand in enumerate(order)}
    if row[names[0]] != 0:
        raise ValueError("flat_plans.price: the triangle candidate's blocks must come first")
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
    split = np.zeros((C, n_plans, len(order)))
    _plans_chunks(bmin, barg, opt, sk, np.array([row[n] for n in names], np.int64),
                  np.array([cand.name in use for cand in order]), gof, cbase, PLAN_CHUNK, ch, cost, ex, used, split)
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
    return _finish_plans(names, choices, totals, ex.all(axis=0), drawn, fc,
                         split.sum(axis=0)[:, [row[n] for n in names]], fixed)


__all__ = ["PLAN_CHUNK", "price"]
