"""LOD mode ``"auto"``: per instance, the cheapest representation within the error bound.

For every visible instance and every option of every candidate
representation (:mod:`lod.auto_candidates`: the levels of the character's
discrete triangle chain, its VDR-AM cluster cut, its Wand & Straßer point
hierarchy), the projected error (pixels; the splat size for points) and the
predicted cost (seconds, :mod:`lod.cost_model`) are computed; the instance
gets the cheapest option whose error is at most the bound, and full detail
(triangle level 0) when none is or when the bound is 0 (issue 7, "lod.mode =
auto"; the per-object cost/benefit choice of Funkhouser & Séquin, SIGGRAPH
1993, §4, with the accuracy constraint as a hard bound instead of a benefit
term). Instances are culled once, by the full-detail selector over the
triangle reps, so every instance inside the frustum is drawn by exactly one
candidate.

The per-instance cost of an option is ``c_tri * triangles + c_splat * points
+ c_cluster * clusters + c_inst`` of what that option would draw for that
instance (cluster cuts and point traversals are computed for every visible
instance, so these counts are exact); the per-batch cost ``c_draw`` is
shared by a batch and ignored in the per-instance choice. The candidates in
play are the ``[lod] candidates`` key (default all three); without
``ClustersCandidate``/``PointsCandidate`` (``candidates = "triangles"``) the
mode is the triangle-chain choice of the first version.

A point hierarchy's error is its splat size (issue 7) plus, by default
(``points_error = "splat+keyframes"``), the projected deviation of its
keyframe-interpolated poses from the skinned mesh
(:func:`lod.auto_candidates.keyframe_deviation`); the point pass over the
whole viewport is a per-frame cost, so points are used in a frame only when
the instances' savings pay for it.

The cost model is the stored calibration of this machine; with ``adapt``
(default) it is rescaled after every frame the engine reports through
:meth:`AutoSelector.observe` (:func:`lod.cost_model.refine`: one factor, the
median measured / predicted ratio of the last ``ADAPT_FRAMES`` frames), so
predictions follow the load the engine really runs under while the relative
costs that decide the choices stay the calibration's.

Departure: Wand & Straßer's super-hierarchies (§3.6, far groups of
hierarchical instances chosen as a whole) are not used; every instance is
chosen on its own.

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

Telemetry: ``DrawList.stats["auto"]`` = {"levels": instances per triangle
chain level (full-detail fallbacks at 0), "representations": instances per
candidate name, "options": instances per "candidate:option" label,
"predicted_ms": predicted frame cost, "bound": pixels used this frame,
"budget_ms": the budget or 0}.
"""
from __future__ import annotations

import math

import numpy as np

from lod import auto_candidates as ac
from lod import cost_model
from lod import triangles_mode as tm
from lod.cluster_cut import viewport_scale
from lod.drawlist import DrawList
from lod.nolod import NoLodSelector
from sim.params import Param

#: candidate representations mode "auto" can choose among (``[lod] candidates``)
CANDIDATES = ("triangles", "clusters", "points")

#: ``[lod]`` keys of mode "auto"
PARAMS: dict = {
    "poe": Param("float", 1.0, min=0.0, max=1000.0,
                 doc="pixels of error: each instance gets the cheapest representation whose error projects below "
                     "this (the start value of the bound in budget mode)"),
    "budget_ms": Param("float", 0.0, min=0.0, max=10000.0,
                       doc="frame-time budget in ms; 0 = fixed bound poe, > 0 = the bound adapts to the budget"),
    "candidates": Param("str", ",".join(CANDIDATES),
                        doc="comma-separated representations to choose among: triangles (always), clusters, points"),
    "max_splat": Param("int", 3, min=1, max=3, doc="largest splat size (pixels) of the point candidate"),
    "points_error": Param("str", "splat+keyframes", choices=("splat", "splat+keyframes"),
                          doc="error of the point candidate: its splat size (issue 7's definition), or the splat "
                              "size plus the projected keyframe-interpolation deviation of the baked poses "
                              "(bounds the image error against the skinned mesh)"),
    "adapt": Param("bool", True, doc="rescale the cost model to the measured frames as they come "
                                     "(lod.cost_model.refine); false keeps the stored calibration"),
    "levels": tm.PARAMS["levels"],
    "ratio": tm.PARAMS["ratio"],
    "keyframes": Param("int", 9, min=2, max=256,
                       doc="poses baked per clip for the point candidate's hierarchies (mode points' keyframes)"),
}


def parse_candidates(value) -> tuple:
    """``[lod] candidates`` as a tuple of names in :data:`CANDIDATES` order
    ("triangles" always included); ValueError naming the key otherwise."""
    names = [v.strip() for v in str(value).split(",") if v.strip()]
    bad = [n for n in names if n not in CANDIDATES]
    if bad or not names:
        raise ValueError(f"[lod] candidates: expected a comma-separated subset of {', '.join(CANDIDATES)}, "
                         f"got {value!r}")
    return tuple(c for c in CANDIDATES if c in names or c == "triangles")


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
#: observed frames the online cost-model refit keeps (the most recent)
ADAPT_FRAMES = 32

#: clamp of the adaptive bound, pixels
BOUND_MIN = 0.25
BOUND_MAX = 1000.0


#: (k, L) pixels of error of each chain level per instance (see :func:`lod.auto_candidates.projected_errors`)
projected_errors = ac.projected_errors


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
    """Cull and pack as the full-detail mode, then choose per instance among
    the candidates (module docstring).

    Parameters
    ----------
    reps : list aligned with ``CrowdState.character`` (:class:`lod.triangles_mode.TrianglesRep`
        for skinned characters, full-detail reps for the others): the master
        selection and the triangle candidate
    static_reps : StaticRep scenery
    poe : pixels of error >= 0 (fixed bound, or the start of the adaptive one)
    budget_ms : 0 for a fixed bound, > 0 for a frame-time budget
    model : :class:`lod.cost_model.CostModel` (default: this host's stored
        calibration, else the defaults)
    cull : frustum culling on (default)
    candidates : further :class:`lod.auto_candidates.Candidate` objects
        (clusters, points, ...) besides the triangle candidate, which is
        always first
    adapt : rescale the cost model to the frames reported through
        :meth:`observe` (the last ``ADAPT_FRAMES``; :func:`lod.cost_model.refine`)
    """

    def __init__(self, reps, static_reps=(), poe: float = 1.0, budget_ms: float = 0.0, model=None,
                 cull: bool = True, candidates=(), adapt: bool = False):
        if not (np.isfinite(poe) and float(poe) >= 0.0):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {poe}")
        if not (np.isfinite(budget_ms) and float(budget_ms) >= 0.0):
            raise ValueError(f"[lod] budget_ms: expected a finite number >= 0, got {budget_ms}")
        self.poe = float(poe)
        self.budget_ms = float(budget_ms)
        self.model = model if model is not None else cost_model.load_any()
        #: the calibration the online refit is pulled towards
        self.prior = self.model
        self.adapt = bool(adapt)
        self._obs_x: list = []
        self._obs_y: list = []
        self._last_features = None
        self.reps = list(reps)
        self.cull = bool(cull)
        self._rep_index = {r.key: i for i, r in enumerate(self.reps)}
        self._chains = {r.key: r for r in self.reps if isinstance(r, tm.TrianglesRep)}
        self._inner = NoLodSelector(self.reps, static_reps=static_reps, cull=cull)
        self._n_levels = max([r.n_levels for r in self._chains.values()] or [1])
        self.candidates = [ac.TrianglesCandidate(self.reps), *candidates]
        self.controller = BudgetController(self.budget_ms * 1e-3, self.poe) if self.budget_ms > 0 else None
        self._measured = None
        self._uses_measured = False

    @property
    def candidate_reps(self) -> list:
        """Every representation the candidates draw (to upload), master reps first."""
        out, seen = [], set()
        for c in self.candidates:
            for r in c.reps:
                if r.key not in seen:
                    seen.add(r.key)
                    out.append(r)
        return out

    @property
    def bound(self) -> float:
        """Pixels of error the next frame is selected with."""
        return self.controller.bound if self.controller is not None else self.poe

    def observe(self, seconds: float) -> None:
        """Report the measured rendering time of the last selected frame
        (budget mode uses it instead of the prediction for the next update;
        with ``adapt`` the cost model is rescaled with it)."""
        self._measured = float(seconds)
        self._uses_measured = True
        if self.adapt and self._last_features is not None and np.isfinite(seconds) and seconds > 0:
            self._obs_x.append(self._last_features)
            self._obs_y.append(float(seconds))
            del self._obs_x[:-ADAPT_FRAMES], self._obs_y[:-ADAPT_FRAMES]
            self.model = cost_model.refine(self.prior, np.asarray(self._obs_x), np.asarray(self._obs_y))
            self._last_features = None

    def select(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList (see :meth:`lod.nolod.NoLodSelector.select`):
        every instance inside the frustum in exactly one batch of the
        candidate it was given; batches sorted by (rep, part, level);
        ``stats["auto"]`` holds the telemetry (module docstring)."""
        if self.controller is not None and self._measured is not None:
            self.controller.update(self._measured)
            self._measured = None
        bound = float(self.bound)
        if not (np.isfinite(bound) and bound >= 0.0):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {bound}")
        dl = self._inner.select(state, camera, size, statics)
        w, h = max(1, int(size[0])), max(1, int(size[1]))
        frame = ac.Frame(state, camera, (w, h), camera.frustum_planes(w / h), viewport_scale(h, camera.fov_y), bound,
                         self.model, self.cull)
        levels = np.zeros(self._n_levels, np.int64)
        per_cand = {c.name: 0 for c in self.candidates}
        tel = ac.Telemetry()
        out = []
        groups = []  # (group, [(candidate, options, first column)], cost, err)
        for b in dl.batches:
            ri = self._rep_index.get(b.rep)
            if ri is None or b.n_instances == 0 or int(b.instance_ids[0]) < 0:  # scenery
                out.append(b)
                continue
            rows = np.asarray(b.instance_data, np.float32)[:, :12].astype(np.float64).reshape(-1, 3, 4)
            g = ac.Group(ri, b, rows)
            opts, a = [], 0
            for c in self.candidates:
                o = c.options(frame, g) if (c is self.candidates[0] or bound > 0.0) else None
                if o is not None and o.cost.shape[1]:
                    opts.append((c, o, a))
                    a += o.cost.shape[1]
            cost = np.concatenate([o.cost for _, o, _ in opts], axis=1)
            err = np.concatenate([o.error for _, o, _ in opts], axis=1)
            groups.append((g, opts, cost, err))
        # a candidate with a per-frame cost (the point pass) is used only when its savings pay for it
        choices: dict = {}  # group index -> choice, valid until columns are masked
        for c in self.candidates[1:]:
            fc = c.frame_cost(frame) if bound > 0.0 else 0.0
            if fc <= 0.0:
                continue
            saving = 0.0
            for gi, (g, opts, cost, err) in enumerate(groups):
                cols = [(a, a + o.cost.shape[1]) for cc, o, a in opts if cc is c]
                if not cols:
                    continue
                ch = choices[gi] if gi in choices else choose(cost, err, bound)
                choices[gi] = ch
                (a0, a1), = cols
                mine = np.flatnonzero((ch >= a0) & (ch < a1))
                if mine.size:
                    e2 = err[mine].copy()
                    e2[:, a0:a1] = np.inf
                    ch2 = choose(cost[mine], e2, bound)
                    saving += float((cost[mine, ch2] - cost[mine, ch[mine]]).sum())
            if saving <= fc:
                choices.clear()
                for g, opts, cost, err in groups:
                    for cc, o, a in opts:
                        if cc is c:
                            err[:, a:a + o.cost.shape[1]] = np.inf
        for gi, (g, opts, cost, err) in enumerate(groups):
            if bound <= 0.0:
                choice = np.zeros(g.k, np.int64)
            else:
                choice = choices[gi] if gi in choices else choose(cost, err, bound)
            for c, o, a in opts:
                m = o.cost.shape[1]
                mine = np.flatnonzero((choice >= a) & (choice < a + m))
                if mine.size:
                    local = choice[mine] - a
                    out.extend(c.emit(frame, g, o, mine, local))
                    per_cand[c.name] += int(mine.size)
                    cnt = np.bincount(local, minlength=m)
                    for j in np.flatnonzero(cnt).tolist():
                        tel.add(c.name, o.labels[j] if j < len(o.labels) else str(j), int(cnt[j]))
                    if c is self.candidates[0]:
                        if g.batch.rep in self._chains:
                            levels[:m] += cnt
                        else:
                            levels[0] += int(mine.size)
        out.sort(key=lambda x: (x.rep, x.part, x.level))
        dl.batches = out
        dl.stats["points"] = 0
        for c in self.candidates:
            c.finish(frame, dl)
        dl.stats["triangles"] = int(sum(x.triangles for x in out))
        dl.stats["batches"] = len(out)
        dl.stats["levels"] = [int(x) for x in levels]
        predicted = self.model.predict(dl)
        self._last_features = cost_model.features(dl)
        dl.stats["auto"] = {"levels": [int(x) for x in levels], "representations": per_cand, "options": tel.counts,
                            "predicted_ms": 1e3 * predicted, "bound": bound, "budget_ms": self.budget_ms}
        if self.controller is not None and not self._uses_measured:
            self.controller.update(predicted)
        return dl


def build(characters, names, fps, params, static_reps=(), progress=None, cache: bool = True, model=None,
          points_params=None):
    """Mode "auto" for ``lod.modes``: the "triangles" mode's reps (full-detail
    reps for non-skinned characters), the cluster hierarchies and point
    hierarchies of the characters when those candidates are asked for, and
    an :class:`AutoSelector`.

    Parameters
    ----------
    characters, names, fps, params, static_reps, progress : see ``lod.modes``
    cache : use the on-disk chain and cluster caches (default); point
        hierarchies always use theirs (``lod.points_mode.HierarchyCache``)
    model : a :class:`lod.cost_model.CostModel` (default: stored calibration or defaults)
    points_params : further ``[lod]`` keys of mode "points" for the point
        candidate's hierarchies (e.g. ``{"intervals": 1}``)

    Returns
    -------
    reps : every representation to upload (triangle reps first, aligned with
        the characters; then the clusters and points reps)
    selector : AutoSelector
    """
    params = dict(params or {})
    poe = float(params.get("poe", PARAMS["poe"].default))
    budget = float(params.get("budget_ms", PARAMS["budget_ms"].default))
    names_c = parse_candidates(params.get("candidates", PARAMS["candidates"].default))
    tri_params = {k: params[k] for k in ("levels", "ratio") if k in params}
    tri_params["poe"] = poe
    reps, _ = tm.build(characters, names, fps, tri_params, static_reps=static_reps, progress=progress, cache=cache)
    extra = []
    if "clusters" in names_c and any(getattr(c, "kind", "") == "skinned" for c in characters):
        from lod import clusters_mode

        creps, _ = clusters_mode.build(characters, names, fps, {}, static_reps=static_reps, progress=progress,
                                       cache=cache)
        extra.append(ac.ClustersCandidate(creps))
    if "points" in names_c and characters:
        from lod import points_mode

        pp = {**dict(points_params or {}), "keyframes": int(params.get("keyframes", PARAMS["keyframes"].default))}
        preps, _ = points_mode.build(characters, names, fps, pp, static_reps=static_reps, progress=progress)
        strict = str(params.get("points_error", PARAMS["points_error"].default)) == "splat+keyframes"
        dev = [ac.keyframe_deviation(ch, pp["keyframes"]) if strict else 0.0 for ch in characters]
        extra.append(ac.PointsCandidate(preps, [r.kind for r in reps],
                                        max_splat=int(params.get("max_splat", PARAMS["max_splat"].default)),
                                        deviation=dev, spheres=[getattr(r, "clip_sphere", None) for r in reps]))
    sel = AutoSelector(reps, static_reps=static_reps, poe=poe, budget_ms=budget, model=model, candidates=extra,
                       adapt=bool(params.get("adapt", PARAMS["adapt"].default)))
    return sel.candidate_reps, sel


__all__ = ["PARAMS", "CANDIDATES", "AutoSelector", "BudgetController", "build", "choose", "parse_candidates",
           "projected_errors"]
