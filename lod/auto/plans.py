"""Frame plans of mode auto (see :mod:`lod.auto.mode`, "Plans"): per instance
group the cheapest option under the bound, reduced in blocks by numba kernels,
and the plan record the selector draws.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit


@dataclass
class _Plan:
    """One frame plan (module docstring, "Plans"): per group the chosen option
    column of each instance, the predicted seconds under the stored
    calibration, whether that price is exact (no instance priced at a lower
    bound), and ``alias``: the earlier pure plan it coincides with."""

    choices: list
    seconds: float
    exact: bool
    alias: str | None = None
    #: what the plan draws, as the share of its priced seconds per candidate (the selector's candidate order;
    #: instances and per-frame passes; None when it prices nothing): the content its measured bias is kept by
    #: (:mod:`lod.auto.control`, "Bias by content")
    content: np.ndarray | None = None

    def measured_as(self, name: str) -> str:
        """The name the plan's measurements are kept under."""
        return self.alias or name


@njit(cache=True)
def _block_min_kernel(cost, error, bound, cols, fallback, out_min, out_arg):  # pragma: no cover - compiled
    for i in range(cost.shape[0]):
        best = np.inf
        arg = 0
        for j in range(cols):
            c = cost[i, j]
            if (error[i, j] <= bound or (fallback and j == 0)) and c < best:  # first minimum, as np.argmin
                best = c
                arg = j
        out_min[i] = best
        out_arg[i] = arg


def block_min(cost, error, bound: float, fallback: bool = False, cols: int | None = None):
    """Per row the cheapest option within the bound (numba, one pass).

    Parameters
    ----------
    cost, error : (k, m) float64 seconds and pixels; bound : pixels;
    fallback : column 0 is admissible whatever its error (the triangle
        chain's full detail); cols : only the first ``cols`` columns count
        (default all)

    Returns
    -------
    bmin (k,) float64 (inf: no admissible option), barg (k,) int64 column
    of it (0 when none; ties to the lower column, as ``np.argmin``).
    """
    k, m = cost.shape
    out_min = np.empty(k, np.float64)
    out_arg = np.empty(k, np.int64)
    _block_min_kernel(cost, error, float(bound), m if cols is None else int(cols), bool(fallback), out_min, out_arg)
    return out_min, out_arg


@njit(cache=True)
def _plans_kernel(bmin, barg, opt, sk, pure, use, ch, cost, exact, used, split):  # pragma: no cover - compiled
    """One group's plans in one pass (:meth:`AutoSelector._plans`): rows 0..P-1 of the outputs are the
    pure plans of the blocks ``pure`` (0: the triangle chain; a pure plan draws its block wherever its
    optimistic price is finite, the chain elsewhere), row P the mixed plan over the blocks ``use``.
    Outputs: ch (P+1, k) chosen columns, cost (P+1,) summed seconds, exact (P+1,) no instance priced
    at a lower bound that could matter, used (P+1, columns) the option columns drawn, split (P+1, blocks)
    the summed seconds per block (what each plan draws, :attr:`_Plan.content`)."""
    nb, k = bmin.shape
    n_pure = pure.shape[0]
    for q in range(n_pure + 1):
        cost[q] = 0.0
        exact[q] = True
        for j in range(nb):
            split[q, j] = 0.0
    for i in range(k):
        for q in range(n_pure):
            x = pure[q]
            if x > 0 and np.isfinite(opt[x, i]):
                ch[q, i] = barg[x, i]
                cost[q] += opt[x, i]
                split[q, x] += opt[x, i]
                if sk[x, i]:
                    exact[q] = False
            else:
                ch[q, i] = barg[0, i]
                cost[q] += bmin[0, i]
                split[q, 0] += bmin[0, i]
            used[q, ch[q, i]] = True
        best = np.inf
        w = 0
        for j in range(nb):
            if use[j] and bmin[j, i] < best:  # the first minimum: ties to the lower column
                best = bmin[j, i]
                w = j
        ch[n_pure, i] = barg[w, i]
        cost[n_pure] += bmin[w, i]
        split[n_pure, w] += bmin[w, i]
        used[n_pure, barg[w, i]] = True
        for j in range(nb):
            if use[j] and sk[j, i] and opt[j, i] < bmin[w, i]:
                exact[n_pure] = False  # a skipped option might have been cheaper than what was chosen


class _Block:
    """One candidate's options for one group, reduced once per frame: ``a``
    its first column, ``m`` its column count, ``bmin``/``barg`` per instance
    the cheapest admissible option and its absolute column, ``opt`` that
    price with skipped instances at their lower bound (optimistic),
    ``skipped`` the instances priced at the bound (None: none)."""

    __slots__ = ("cand", "options", "a", "m", "bmin", "barg", "opt", "skipped")

    @classmethod
    def of(cls, cand, o, a: int, skipped, bound: float, is_tri: bool):
        b = cls()
        b.cand, b.options, b.a, b.m, b.skipped = cand, o, int(a), int(o.cost.shape[1]), skipped
        if bound > 0.0 or is_tri:
            bmin, barg = block_min(o.cost, o.error, bound, fallback=is_tri, cols=None if bound > 0.0 else 1)
        else:
            bmin, barg = np.full(o.cost.shape[0], np.inf), np.zeros(o.cost.shape[0], np.int64)
        b.bmin, b.barg = bmin, barg + b.a
        b.opt = bmin
        if skipped is not None:  # skipped instances priced at the lower bound (optimistic)
            b.opt = bmin.copy()
            b.opt[skipped] = o.cost[skipped].min(axis=1)
        return b


# ---------------------------------------------------------------------------- pricing the frame plans
def _use_mixed(candidates, groups, fc: dict, fixed_names) -> set:
    """Names of the candidates the mixed plan may use: a candidate with a per-frame cost is dropped
    when its instances' savings over the others in use do not pay for it (per-group loop: reference)."""
    use = {cand.name for cand in candidates}
    for cand in candidates[1:]:
        if fc.get(cand.name, 0.0) <= 0.0 or cand.name in fixed_names:  # no cost, or paid by the wholes
            continue
        saving = 0.0
        for g, opts, ncols in groups:
            mine = next((x.bmin for x in opts if x.cand is cand), None)
            if mine is None:
                continue
            rest = [x.bmin for x in opts if x.cand is not cand and x.cand.name in use]
            other = rest[0] if len(rest) == 1 else np.min(np.stack(rest), axis=0)
            wins = mine < other  # ties go to the lower column: only strict wins count
            saving += float((other[wins] - mine[wins]).sum())
        if saving <= fc[cand.name]:
            use.discard(cand.name)
    return use


def _content(split_q, names, used_q, fc, fixed) -> np.ndarray | None:
    """:attr:`_Plan.content` of one plan: its instances' seconds per candidate (``split_q``, ``names`` order)
    plus the per-frame passes it uses and the whole-group draws (``fixed``: seconds, candidate names), as
    shares."""
    s = np.asarray(split_q, np.float64).copy()
    for j, n in enumerate(names):
        if n in used_q:
            s[j] += fc.get(n, 0.0)
    wholes = [j for j, n in enumerate(names) if n in fixed[1]]
    if wholes and fixed[0] > 0.0:
        s[wholes] += float(fixed[0]) / len(wholes)
    s = np.where(np.isfinite(s) & (s > 0.0), s, 0.0)
    t = float(s.sum())
    return s / t if t > 0.0 else None


def _finish_plans(names, choices, totals, exact, used, fc, split=None, fixed=(0.0, frozenset())) -> dict:
    """name -> :class:`_Plan`, and the aliases: a plan whose choices equal an earlier plan's is that plan
    (its measurements are shared): a pure plan that draws what an earlier pure one draws (e.g. every agent
    in super nodes: all plans draw the same), and the mixed plan equal to a pure one. ``split``: (plans,
    candidates in ``names`` order) the instances' seconds per candidate (:attr:`_Plan.content`)."""
    plans = {}
    for q, name in enumerate(names + ["mixed"]):
        plans[name] = _Plan(choices[q], float(totals[q]) + sum(fc.get(n, 0.0) for n in used[q]), bool(exact[q]),
                            content=None if split is None else _content(split[q], names, used[q], fc, fixed))

    def same(x, y):
        return all(np.array_equal(a_, b_) for a_, b_ in zip(x.choices, y.choices))

    # roots first: a pure plan whose own candidate draws (so the far view drawn from super nodes alone is
    # "points", not "triangles"), then candidate order
    order = sorted(names, key=lambda n: (n not in used[names.index(n)], names.index(n)))
    for i, name in enumerate(order + ["mixed"]):
        this = plans[name]
        for other in order[:i]:
            o = plans[other]
            if o.alias is None and same(this, o):
                this.exact = this.exact and o.exact
                if o.exact or not this.exact:
                    this.seconds = o.seconds
                this.alias = other
                break
    return plans


def price_plans_loop(candidates, groups, coefficients, fc: dict, fixed=(0.0, frozenset())) -> dict:
    """Reference of :func:`price_plans`: the frame plans priced group by group (one
    :func:`_plans_kernel` call and a Python loop over the blocks per group)."""
    c = coefficients
    names = [cand.name for cand in candidates]
    use = _use_mixed(candidates, groups, fc, fixed[1])
    n_plans = len(names) + 1  # the pure plans in candidate order, then the mixed one
    totals = np.full(n_plans, float(c["frame"]) + float(fixed[0]))
    exact = np.ones(n_plans, bool)
    used = [set(fixed[1]) for _ in range(n_plans)]
    choices = [[] for _ in range(n_plans)]
    split = np.zeros((n_plans, len(names)))
    for g, opts, ncols in groups:
        col = {x.cand.name: j for j, x in enumerate(opts)}  # blocks in column order, triangles first
        bmin = np.stack([x.bmin for x in opts])
        barg = np.stack([x.barg for x in opts])
        opt = np.stack([x.opt for x in opts])
        sk = np.zeros(bmin.shape, np.bool_)
        for j, x in enumerate(opts):
            if x.skipped is not None:
                sk[j] = x.skipped
        pure = np.array([col.get(n, 0) for n in names], np.int64)  # 0: the triangle chain
        ch = np.empty((n_plans, g.k), np.int64)
        cost = np.empty(n_plans)
        ex = np.empty(n_plans, np.bool_)
        opts_used = np.zeros((n_plans, ncols), np.bool_)
        sp = np.zeros((n_plans, len(opts)))
        _plans_kernel(bmin, barg, opt, sk, pure, np.array([x.cand.name in use for x in opts]), ch, cost, ex,
                      opts_used, sp)
        for j, x in enumerate(opts):
            split[:, names.index(x.cand.name)] += sp[:, j]
        totals += cost
        exact &= ex
        for q in range(n_plans):
            choices[q].append(ch[q])
        for x in opts:  # batches: the distinct options of each block a plan draws
            k = opts_used[:, x.a:x.a + x.m].sum(axis=1)
            totals += c["batches"] * k
            for q in np.flatnonzero(k).tolist():
                used[q].add(x.cand.name)
    return _finish_plans(names, choices, totals, exact, used, fc, split, fixed)


def price_plans(candidates, groups, coefficients, fc: dict, fixed=(0.0, frozenset()), order=None) -> dict:
    """The frame plans of :class:`lod.auto.mode.AutoSelector` (its module docstring, "Plans") priced over
    every group of every character in one pass: the blocks of all groups are laid side by side, one row
    per candidate (a group without a candidate's block has +inf there), and one :func:`_plans_kernel`
    call prices every pure plan and the mixed one over all instances; the batches each plan draws are
    counted from one matrix of the option columns used. Same plans as :func:`price_plans_loop`.

    Parameters
    ----------
    candidates : the selector's candidates (triangles first); groups : [(group, [_Block], columns)];
    coefficients : cost model coefficients; fc : candidate name -> per-frame cost (s); fixed : (seconds,
    candidate names) of the whole-group draws every plan includes; order : the candidates in the
    order their blocks appear in a group (ties between blocks go to the earlier one; default: as given)
    """
    c = coefficients
    names = [cand.name for cand in candidates]
    order = list(candidates) if order is None else list(order)
    row = {cand.name: r for r, cand in enumerate(order)}
    nb = len(order)
    n_plans = len(names) + 1
    ks = np.array([g.k for g, _, _ in groups], np.int64)
    N = int(ks.sum())
    ncols = np.array([n for _, _, n in groups], np.int64)
    cbase = np.zeros(len(groups) + 1, np.int64)
    np.cumsum(ncols, out=cbase[1:])
    ibase = np.zeros(len(groups) + 1, np.int64)
    np.cumsum(ks, out=ibase[1:])
    bmin = np.full((nb, N), np.inf)
    barg = np.zeros((nb, N), np.int64)
    opt = np.full((nb, N), np.inf)
    sk = np.zeros((nb, N), np.bool_)
    col_cand = np.zeros(int(cbase[-1]), np.int64)  # the candidate row of every option column
    # gather the blocks side by side (concatenations, no per-group pricing)
    blocks = [(gi, x) for gi, (_, opts, _) in enumerate(groups) for x in opts]
    brow = np.array([row[x.cand.name] for _, x in blocks], np.int64)
    bgrp = np.array([gi for gi, _ in blocks], np.int64)
    ba = np.array([x.a for _, x in blocks], np.int64)
    bm = np.array([x.m for _, x in blocks], np.int64)
    bk = ks[bgrp] if blocks else np.zeros(0, np.int64)
    # every block's instances (global) and option columns (global), in block order
    inst = np.repeat(ibase[bgrp] - np.concatenate([[0], np.cumsum(bk)[:-1]]), bk) + np.arange(int(bk.sum()))
    cols = np.repeat(cbase[bgrp] + ba - np.concatenate([[0], np.cumsum(bm)[:-1]]), bm) + np.arange(int(bm.sum()))
    r_of = np.repeat(brow, bk)
    if blocks:
        bmin[r_of, inst] = np.concatenate([x.bmin for _, x in blocks])
        barg[r_of, inst] = np.concatenate([x.barg for _, x in blocks]) + np.repeat(cbase[bgrp], bk)
        opt[r_of, inst] = np.concatenate([x.opt for _, x in blocks])
        sk[r_of, inst] = np.concatenate([x.skipped if x.skipped is not None else np.zeros(x.bmin.shape[0], np.bool_)
                                         for _, x in blocks])
        col_cand[cols] = np.repeat(brow, bm)
    use = _use_mixed_rows(candidates, row, bmin, fc, fixed[1])
    pure = np.array([row[n] for n in names], np.int64)
    tri = row[names[0]]
    if tri != 0:
        raise ValueError("price_plans: the triangle candidate's blocks must come first")
    ch = np.empty((n_plans, N), np.int64)
    cost = np.empty(n_plans)
    ex = np.empty(n_plans, np.bool_)
    opts_used = np.zeros((n_plans, int(cbase[-1])), np.bool_)
    sp = np.zeros((n_plans, nb))
    _plans_kernel(bmin, barg, opt, sk, pure, np.array([cand.name in use for cand in order]), ch, cost, ex, opts_used,
                  sp)
    totals = float(c["frame"]) + float(fixed[0]) + cost + c["batches"] * opts_used.sum(axis=1)
    onehot = np.zeros((int(cbase[-1]), nb), np.bool_)
    onehot[np.arange(int(cbase[-1])), col_cand] = True
    drawn = (opts_used.astype(np.int64) @ onehot.astype(np.int64)) > 0  # (plans, candidate rows)
    used = [set(fixed[1]) | {order[r].name for r in np.flatnonzero(drawn[q]).tolist()} for q in range(n_plans)]
    local = ch - np.repeat(cbase[:-1], ks)[None, :]
    choices = [np.split(local[q], ibase[1:-1]) for q in range(n_plans)]
    return _finish_plans(names, choices, totals, ex, used, fc, sp[:, [row[n] for n in names]], fixed)


def _use_mixed_rows(candidates, row: dict, bmin: np.ndarray, fc: dict, fixed_names) -> set:
    """:func:`_use_mixed` over the side-by-side blocks (rows of ``bmin``, +inf where a group has none)."""
    use = {cand.name for cand in candidates}
    for cand in candidates[1:]:
        if fc.get(cand.name, 0.0) <= 0.0 or cand.name in fixed_names:
            continue
        mine = bmin[row[cand.name]]
        rest = [row[n] for n in use if n != cand.name]
        other = bmin[rest].min(axis=0)
        wins = mine < other
        saving = float((other[wins] - mine[wins]).sum())
        if saving <= fc[cand.name]:
            use.discard(cand.name)
    return use
