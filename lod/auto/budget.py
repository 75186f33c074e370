"""The per-instance choice at a pixel bound and the budget controller that moves
the bound towards a frame-time budget (mode auto, :mod:`lod.auto.mode`).

With ``budget_ms > 0`` (a frame-time budget) the bound adapts once per frame
from the last frame's cost (measured, when the caller reports it through
:meth:`lod.auto.mode.AutoSelector.observe`, else predicted) with hysteresis: it is
multiplied by ``step`` when the cost exceeds the budget by more than
``UP_TOLERANCE`` (5 %), divided by ``step`` when it is below by more than
``DOWN_TOLERANCE`` (15 %), and left alone inside that band. ``step`` is
square-rooted at every change of direction (a damped, bisection-like
search) down to ``MIN_STEP``; a lowered bound whose selection is predicted
to pass the budget is refused before it is drawn and the bound before held
(:meth:`BudgetController.refuse`, from :mod:`lod.auto.mode`), and the bound is not lowered again for
``REFUSE_HOLD`` frames, doubled at every refusal in a row (a back-off: the cliff is still there while the view
stays); a reversal
from over- to under-budget at the smallest step holds the bound (the cost
jumps across the band between two neighbouring bounds: the under-budget one
is kept) until the cost at the
held bound changes by more than ``HOLD_RELEASE`` (30 %: the view changed). The
bound is clamped to ``[BOUND_MIN, BOUND_MAX]`` pixels. A cost outside the
band moves the bound only after ``PERSIST`` consecutive frames on the same
side (a single noisy measurement does not), or at once when it is off the
budget by more than a factor ``URGENT``.
"""
from __future__ import annotations

import math

import numpy as np

#: cost above budget * (1 + UP_TOLERANCE): coarsen (raise the bound)
UP_TOLERANCE = 0.05
#: cost below budget * (1 - DOWN_TOLERANCE): refine (lower the bound)
DOWN_TOLERANCE = 0.15
#: bound change factor at the start and after a run in one direction
MAX_STEP = 1.5
#: the step is never below this factor
MIN_STEP = 1.02
#: an out-of-band cost must persist this many consecutive frames before the bound moves (one noisy
#: frame does not), unless it is off the budget by more than ``URGENT`` (a factor)
PERSIST = 2
URGENT = 1.5
#: a held bound is released when the cost at it changes by more than this fraction (the view changed: a frame
#: time on llvmpipe swings 10-15 % from frame to frame, which must not restart the search)
HOLD_RELEASE = 0.30
#: after a refused bound, frames the bound is not lowered again whatever the cost does (doubled at each refusal
#: in a row, up to REFUSE_HOLD_MAX): a refused frame selects twice, and its measured cost, ~40 % above its
#: neighbours' on the stadium, released the hold and the refusal came back every third frame (13 ms of
#: selection each time, issue 49)
REFUSE_HOLD = 8
REFUSE_HOLD_MAX = 32
#: clamp of the adaptive bound, pixels
BOUND_MIN = 0.25
BOUND_MAX = 1000.0


def choose(cost: np.ndarray, error_px: np.ndarray, bound: float) -> np.ndarray:
    """Per instance, the index of the cheapest candidate with error <= ``bound``.

    Parameters
    ----------
    cost : (L,) or (k, L) float64 predicted seconds per candidate
    error_px : (k, L) float64 projected error; column 0 is full detail
    bound : pixels >= 0

    Returns
    -------
    (k,) int64; 0 (full detail) where no candidate is within the bound.
    Ties go to the lower index (finer).
    """
    err = np.asarray(error_px, np.float64)
    c = np.broadcast_to(np.asarray(cost, np.float64), err.shape)
    ok = err <= float(bound)
    ok[:, 0] = True
    masked = np.where(ok, c, np.inf)
    return np.argmin(masked, axis=1).astype(np.int64)


class BudgetController:
    """The adaptive bound of budget mode (module docstring).

    Parameters
    ----------
    budget_s : seconds > 0
    bound : start value, pixels (clamped)
    """

    def __init__(self, budget_s: float, bound: float = 1.0):
        if not (math.isfinite(budget_s) and budget_s > 0.0):
            raise ValueError(f"[lod] budget_ms: expected a finite number > 0, got {budget_s * 1e3}")
        self.budget = float(budget_s)
        self.bound = float(min(max(bound, BOUND_MIN), BOUND_MAX))
        self.step = MAX_STEP
        self._last_dir = 0
        self._run = 0
        self._held_cost = None
        self._pending = 0
        self._last_cost = None  # the cost of the last frame reported (at the bound before the last move)
        self._backoff = 0  # frames of the current refusal hold (0: no refusal in a row)
        self._no_lower = 0  # frames left in which the bound is not lowered
        self._probing = False  # the last move lowered the bound (a refusal follows in the same frame, if any)

    def refuse(self, bound: float) -> None:
        """The bound just lowered from ``bound`` is predicted to pass the budget: back to ``bound``, held there
        until the cost at it changes by more than :data:`HOLD_RELEASE` (the view changed), as a reversal at the
        smallest step is held, and in any case not lowered for :data:`REFUSE_HOLD` frames, doubled at each
        refusal in a row up to :data:`REFUSE_HOLD_MAX`; the next probe starts from :data:`MAX_STEP`."""
        self.bound = float(min(max(bound, BOUND_MIN), BOUND_MAX))
        self._held_cost = self._last_cost
        self.step = MAX_STEP
        self._last_dir = 0
        self._run = 0
        self._pending = 0
        self._backoff = min(REFUSE_HOLD_MAX, 2 * self._backoff) if self._backoff else REFUSE_HOLD
        self._no_lower = self._backoff
        self._probing = False

    def update(self, cost: float) -> float:
        """Adapt the bound to a frame's ``cost`` (seconds); returns the new bound."""
        cost = float(cost)
        if not math.isfinite(cost) or cost < 0.0:
            return self.bound
        self._last_cost = cost
        if self._probing:  # the bound lowered last frame was drawn: the refusals in a row end
            self._probing = False
            self._backoff = 0
        held_back = self._no_lower > 0  # within a refusal's back-off
        self._no_lower = max(0, self._no_lower - 1)
        if self._held_cost is not None:
            if abs(cost - self._held_cost) <= HOLD_RELEASE * max(self._held_cost, 1e-12):
                return self.bound
            self._held_cost = None
            self.step = MAX_STEP
            self._last_dir = 0
        if cost > self.budget * (1.0 + UP_TOLERANCE):
            d = 1
        elif cost < self.budget * (1.0 - DOWN_TOLERANCE):
            d = -1
        else:
            self._run = 0
            self._pending = 0
            return self.bound
        if d < 0 and held_back:
            self._pending = 0
            return self.bound
        urgent = cost > self.budget * URGENT or cost < self.budget / URGENT
        self._pending = self._pending + d if self._pending * d > 0 else d
        if abs(self._pending) < PERSIST and not urgent:
            return self.bound
        self._pending = 0
        if (d > 0 and self.bound >= BOUND_MAX) or (d < 0 and self.bound <= BOUND_MIN):
            return self.bound
        if self._last_dir and d != self._last_dir:
            if d < 0 and self.step <= MIN_STEP * (1 + 1e-9):
                self._held_cost = cost  # neighbouring bounds straddle the band: keep the cheaper one
                return self.bound
            self.step = max(MIN_STEP, math.sqrt(self.step))
            self._run = 0
        else:
            self._run += 1
            if self._run >= 3:  # a long run in one direction: the view changed, speed up again
                self.step = min(MAX_STEP, self.step * self.step)
        self._last_dir = d
        self._probing = d < 0
        self.bound = float(min(max(self.bound * (self.step if d > 0 else 1.0 / self.step), BOUND_MIN), BOUND_MAX))
        return self.bound


__all__ = ["BudgetController", "choose"]
