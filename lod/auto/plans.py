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
def _plans_kernel(bmin, barg, opt, sk, pure, use, ch, cost, exact, used):  # pragma: no cover - compiled
    """One group's plans in one pass (:meth:`AutoSelector._plans`): rows 0..P-1 of the outputs are the
    pure plans of the blocks ``pure`` (0: the triangle chain; a pure plan draws its block wherever its
    optimistic price is finite, the chain elsewhere), row P the mixed plan over the blocks ``use``.
    Outputs: ch (P+1, k) chosen columns, cost (P+1,) summed seconds, exact (P+1,) no instance priced
    at a lower bound that could matter, used (P+1, columns) the option columns drawn."""
    nb, k = bmin.shape
    n_pure = pure.shape[0]
    for q in range(n_pure + 1):
        cost[q] = 0.0
        exact[q] = True
    for i in range(k):
        for q in range(n_pure):
            x = pure[q]
            if x > 0 and np.isfinite(opt[x, i]):
                ch[q, i] = barg[x, i]
                cost[q] += opt[x, i]
                if sk[x, i]:
                    exact[q] = False
            else:
                ch[q, i] = barg[0, i]
                cost[q] += bmin[0, i]
            used[q, ch[q, i]] = True
        best = np.inf
        w = 0
        for j in range(nb):
            if use[j] and bmin[j, i] < best:  # the first minimum: ties to the lower column
                best = bmin[j, i]
                w = j
        ch[n_pure, i] = barg[w, i]
        cost[n_pure] += bmin[w, i]
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
