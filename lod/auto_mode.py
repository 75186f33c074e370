"""LOD mode ``"auto"``: per instance, the cheapest representation within the error bound.

For every visible instance and every candidate representation/level, the
projected error (pixels) and the predicted cost (seconds, :mod:`lod.cost_model`)
are computed; the instance gets the cheapest candidate whose projected error is
at most the bound, and full detail when none is (issue 7, "lod.mode = auto";
the per-object cost/benefit choice of Funkhouser & Séquin, SIGGRAPH 1993,
§4, with the accuracy constraint as a hard bound instead of a benefit term).

Candidates (this first version): the levels of the character's discrete
triangle chain (:mod:`lod.triangles_mode`, level 0 = the full mesh, so a bound
of 0 draws exactly what mode "none" draws). Cluster cuts and point splats are
not candidates yet: they plug in as further columns of the cost/error matrices
of :func:`choose` once their per-instance error and cost are exposed.
Keyframed characters are drawn at full detail.

The per-instance cost of level k is ``c_tri * triangles_k + c_inst``; the
per-batch cost ``c_draw`` is shared by all instances of a (character, clip,
level) batch and ignored in the per-instance choice.

Accuracy is asked for in one of two ways:

- ``budget_ms = 0`` (default): a fixed bound, ``poe`` pixels.
- ``budget_ms > 0``: a frame-time budget. The bound adapts once per frame
  from the last frame's cost (measured, when the caller reports it through
  :meth:`AutoSelector.observe`, else predicted) with hysteresis: it is
  multiplied by ``step`` when the cost exceeds the budget by more than
  ``UP_TOLERANCE`` (5 %), divided by ``step`` when it is below by more than
  ``DOWN_TOLERANCE`` (15 %), and left alone inside that band. ``step`` is
  square-rooted at every change of direction (a damped, bisection-like
  search) down to ``MIN_STEP``; a reversal from over- to under-budget at the
  smallest step holds the bound (the cost jumps across the band between two
  neighbouring bounds: the under-budget one is kept) until the cost at the
  held bound changes by more than ``HOLD_RELEASE`` (the view changed). The
  bound is clamped to ``[BOUND_MIN, BOUND_MAX]`` pixels. A cost outside the
  band moves the bound only after ``PERSIST`` consecutive frames on the same
  side (a single noisy measurement does not), or at once when it is off the
  budget by more than a factor ``URGENT``.

Telemetry: ``DrawList.stats["auto"]`` = {"levels": instances per chain level,
"predicted_ms": predicted frame cost, "bound": pixels used this frame,
"budget_ms": the budget or 0}.
"""
from __future__ import annotations

import math

import numpy as np

from lod import cost_model
from lod import triangles_mode as tm
from lod.cluster_cut import viewport_scale
from lod.drawlist import DrawList
from lod.nolod import NoLodSelector
from sim.params import Param

#: ``[lod]`` keys of mode "auto"
PARAMS: dict = {
    "poe": Param("float", 1.0, min=0.0, max=1000.0,
                 doc="pixels of error: each instance gets the cheapest level whose error projects below this "
                     "(the start value of the bound in budget mode)"),
    "budget_ms": Param("float", 0.0, min=0.0, max=10000.0,
                       doc="frame-time budget in ms; 0 = fixed bound poe, > 0 = the bound adapts to the budget"),
    "levels": tm.PARAMS["levels"],
    "ratio": tm.PARAMS["ratio"],
}

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
#: a held bound is released when the cost at it changes by more than this fraction
HOLD_RELEASE = 0.10
#: clamp of the adaptive bound, pixels
BOUND_MIN = 0.25
BOUND_MAX = 1000.0


def projected_errors(errors, rows, sphere, scale_px: float) -> np.ndarray:
    """(k, L) float64 pixels of error of each level per instance.

    Same rule as :func:`lod.triangles_mode.choose_levels`: ``error_k * s *
    scale_px / d`` with d the distance to the scaled clip sphere; inside the
    sphere level 0 projects 0 and every other level +inf.
    """
    rows = np.asarray(rows, np.float64).reshape(-1, 3, 4)
    e = np.asarray(errors, np.float64)
    s = np.linalg.norm(rows[:, :, :3], axis=1).max(axis=1)
    c = rows[:, :, :3] @ np.asarray(sphere[:3], np.float64) + rows[:, :, 3]
    d = np.linalg.norm(c, axis=1) - float(sphere[3]) * s
    inside = ~(d > 0.0)
    px = e[None, :] * (s * scale_px / np.where(inside, 1.0, d))[:, None]
    px[inside] = np.where(e > 0.0, np.inf, 0.0)[None, :]
    return px


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

    def update(self, cost: float) -> float:
        """Adapt the bound to a frame's ``cost`` (seconds); returns the new bound."""
        cost = float(cost)
        if not math.isfinite(cost) or cost < 0.0:
            return self.bound
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
        self.bound = float(min(max(self.bound * (self.step if d > 0 else 1.0 / self.step), BOUND_MIN), BOUND_MAX))
        return self.bound


class AutoSelector:
    """Cull and pack as the full-detail mode, then choose per instance
    (module docstring).

    Parameters
    ----------
    reps : list aligned with ``CrowdState.character`` (:class:`lod.triangles_mode.TrianglesRep`
        for skinned characters, full-detail reps for the others)
    static_reps : StaticRep scenery
    poe : pixels of error >= 0 (fixed bound, or the start of the adaptive one)
    budget_ms : 0 for a fixed bound, > 0 for a frame-time budget
    model : :class:`lod.cost_model.CostModel` (default: this host's stored
        calibration, else the defaults)
    cull : frustum culling on (default)
    """

    def __init__(self, reps, static_reps=(), poe: float = 1.0, budget_ms: float = 0.0, model=None,
                 cull: bool = True):
        if not (np.isfinite(poe) and float(poe) >= 0.0):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {poe}")
        if not (np.isfinite(budget_ms) and float(budget_ms) >= 0.0):
            raise ValueError(f"[lod] budget_ms: expected a finite number >= 0, got {budget_ms}")
        self.poe = float(poe)
        self.budget_ms = float(budget_ms)
        self.model = model if model is not None else cost_model.load_any()
        self.reps = list(reps)
        self._chains = {r.key: r for r in self.reps if isinstance(r, tm.TrianglesRep)}
        self._inner = NoLodSelector(self.reps, static_reps=static_reps, cull=cull)
        self._n_levels = max([r.n_levels for r in self._chains.values()] or [1])
        self.controller = BudgetController(self.budget_ms * 1e-3, self.poe) if self.budget_ms > 0 else None
        self._measured = None
        self._uses_measured = False

    @property
    def bound(self) -> float:
        """Pixels of error the next frame is selected with."""
        return self.controller.bound if self.controller is not None else self.poe

    def observe(self, seconds: float) -> None:
        """Report the measured rendering time of the last selected frame
        (budget mode uses it instead of the prediction for the next update)."""
        self._measured = float(seconds)
        self._uses_measured = True

    def select(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList (see :meth:`lod.nolod.NoLodSelector.select`);
        chained characters' batches are :class:`lod.triangles_mode.TriangleDrawBatch`
        sorted by (rep, clip, level); ``stats["auto"]`` holds the telemetry."""
        if self.controller is not None and self._measured is not None:
            self.controller.update(self._measured)
            self._measured = None
        bound = self.bound
        dl = self._inner.select(state, camera, size, statics)
        scale_px = viewport_scale(max(1, int(size[1])), camera.fov_y)
        c = self.model.coefficients

        def levels_of(r, b, rows):
            err = projected_errors(r.level_error, rows, r.clip_sphere[b.part], scale_px)
            cost = c["triangles"] * r.level_count.astype(np.float64) + c["instances"]
            return choose(cost, err, bound)

        counts = tm.split_by_level(dl, self._chains, self._n_levels, levels_of)
        predicted = self.model.predict(dl)
        dl.stats["auto"] = {"levels": [int(x) for x in counts], "predicted_ms": 1e3 * predicted, "bound": bound,
                            "budget_ms": self.budget_ms}
        if self.controller is not None and not self._uses_measured:
            self.controller.update(predicted)
        return dl


def build(characters, names, fps, params, static_reps=(), progress=None, cache: bool = True, model=None):
    """Mode "auto" for ``lod.modes``: the "triangles" mode's reps (full-detail
    reps for non-skinned characters) and an :class:`AutoSelector`.

    Parameters
    ----------
    characters, names, fps, params, static_reps, progress : see ``lod.modes``
    cache : use the on-disk chain cache (default)
    model : a :class:`lod.cost_model.CostModel` (default: stored calibration or defaults)
    """
    params = dict(params or {})
    poe = float(params.get("poe", PARAMS["poe"].default))
    budget = float(params.get("budget_ms", PARAMS["budget_ms"].default))
    tri_params = {k: params[k] for k in ("levels", "ratio") if k in params}
    tri_params["poe"] = poe
    reps, _ = tm.build(characters, names, fps, tri_params, static_reps=static_reps, progress=progress, cache=cache)
    return reps, AutoSelector(reps, static_reps=static_reps, poe=poe, budget_ms=budget, model=model)


__all__ = ["PARAMS", "AutoSelector", "BudgetController", "build", "choose", "projected_errors"]
