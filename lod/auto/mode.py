"""LOD mode ``"auto"``: per instance, the cheapest representation within the error bound.

For every visible instance and every option of every candidate
representation (:mod:`lod.auto.candidates`: the levels of the character's
discrete triangle chain, its VDR-AM cluster cut, its Wand & Straßer point
hierarchy), the projected error (pixels; the splat size for points) and the
predicted cost (seconds, :mod:`lod.auto.cost_model`) are computed; the instance
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

Point error, a decision: issue 7 defines a point hierarchy's error as its
splat size, and ``points_error = "splat"`` uses exactly that (mode "points"
at splat size s is the same choice). But a skinned character's point
hierarchies are built over poses baked per clip and interpolated linearly
(Wand & Straßer §3), which departs from the skinned pose the other
representations and the NoLOD reference draw: for the procedural humanoid
0.27 m at 9 evenly spaced poses, 0.07 m at 33, and 0.033 m with the default
``keyframes = 0`` (the fewest poses within ``pose_error`` = 2 % of its
extent, 14-15 per clip; :mod:`lod.points.poses`). The candidate is priced
with the pose error of the poses its hierarchies were built over (a clip's
own jump at its loop point not counted). Counting only the splat
size would let auto show that departure (tens of pixels on a near
instance) under a bound of 1-3 pixels, so the default is
``points_error = "splat+keyframes"``: half the bound goes to the splat size,
and the projected deviation must fit in the rest; the image error against
the skinned mesh then stays within the bound (tests/lod/auto/test_auto_mode.py).
``scripts/bench_auto.py`` reports both ("auto" and "auto-splat").

Plans (issue 7, "auto within 10 % of the best single representation"): the
per-instance choice alone can lose to a single representation, since the
per-frame costs (the point pass, the cluster drawer's pre-pass) are shared
by all instances and the calibration's relative costs are off by ~20-30 %.
So every frame evaluates, from the same per-instance option table, the
*mixed* plan (per instance the cheapest option; a candidate with a per-frame
cost is dropped for the frame when its instances' savings do not pay for
it) and one *pure* plan per candidate (that representation wherever it has
an option within the bound, the triangle chain elsewhere), each priced as a
frame: instances + batches + the per-frame passes used + the constant. With
``adapt`` (default) the plans are priced with the costs of the online fit
(below) and :class:`lod.auto.control.PlanChooser` decides which is drawn:
the incumbent plan changes only when another's predicted gain exceeds the
measured noise for several frames (hysteresis), a plan the fit is unsure
about and that could win is tried for a few frames (bounded exploration),
and a change fades the instances that change representation over
``switch_frames`` frames (screen-door, ``DrawBatch.fade``: no pop). Without
``adapt`` the cheapest plan is drawn every frame. A plan that draws
what an earlier plan draws (the mixed plan equal to a pure one, or pure plans
that coincide, e.g. when every agent is in a super node) shares that plan's
name and measurements. The plans are priced over every group of every
character in one pass (:func:`lod.auto.plans.price_plans`: the candidates'
per-group blocks side by side, one kernel call), not group by group; the
per-group loop it replaced (:func:`lod.auto.plans.price_plans_loop`) is kept
as the reference the tests compare its choices with.

Selection work: a candidate may give a cost lower bound per instance
(:meth:`lod.auto.candidates.Candidate.cost_lower_bound`, the cluster cut:
one skinned instance); candidates without one are evaluated first, and an
instance's exact options of a bounded candidate are computed only where the
bound undercuts the cheapest admissible option found so far. A plan priced
with such skipped instances is optimistic; when it wins, the skipped
instances are evaluated exactly and the plans priced again, so skipping
never changes the choice (tested against a selector without the bound).

The cost model: the stored calibration of this machine (``crowd calibrate``;
the defaults when there is none or the file cannot be used) is the prior of
an online fit of the per-unit costs (:class:`lod.auto.online.OnlineCostModel`:
Bayesian recursive least squares with forgetting) to every frame the engine
reports through :meth:`AutoSelector.observe` (the counts drawn and the
rendering time), so that a wrong, stale or missing calibration is corrected
within a few dozen frames; options and plans are priced with its posterior
mean. Without ``adapt`` the calibration prices everything. A frame whose
draw made GL objects (a program compiled on its first use, a buffer grown:
:attr:`lod.drawlist.DrawList.warm_up`) carries a one-time cost and is left
out of the fit, the plans' measurements and the budget (issue 50, item 3:
on the quickstart at 640x360 the first frame of an explored point plan
took 229 ms, its next frames 96-104 ms).

Far groups (issue 7; Wand & Straßer §3.6): before the per-instance
choice, each candidate may draw whole groups of instances
(:meth:`lod.auto.candidates.Candidate.wholes`). The point candidate draws
the far nodes of the simulation's instancing groups from their
super-hierarchies, exactly the nodes mode points draws at the same splat
size: a node qualifies only when its finest super-hierarchy leaves project
within the splat size, so its few points undercut any per-instance option
of its hundreds of members (each costs at least one instance). Those
agents get no per-instance option; every plan includes the node draws and
their point pass. With ``points_error = "splat+keyframes"`` no node is
drawn this way (the keyframe deviation is projected per instance only).

Accuracy is asked for in one of two ways:

- ``budget_ms = 0`` (default): a fixed bound, ``poe`` pixels.
- ``budget_ms > 0``: a frame-time budget; the bound adapts once per frame to
  the last frame's measured (else predicted) cost with hysteresis
  (:class:`lod.auto.budget.BudgetController`, its module docstring).

Telemetry: ``DrawList.stats["auto"]`` = {"levels": instances per triangle
chain level (full-detail fallbacks at 0), "representations": instances per
candidate name, "options": instances per "candidate:option" label,
"predicted_ms": predicted rendering time of the frame (the fit's costs of
the counts drawn, times the plan's measured bias), "predicted_sd_ms": its
standard deviation (fit and frame noise), "bound": pixels used this frame,
"budget_ms": the budget or 0, "plan": the plan drawn, "state": the
chooser's state ("steady", "pending", "switch", "transition", "explore",
"return"; "fixed" without ``adapt``), "incumbent", "fade_from" and
"fade_t" (the plan faded out and the weight of a transition), "threshold":
the relative gain another plan needs, "plans_ms": every plan's prediction,
"plans_sd_ms": the standard deviation of its difference to the incumbent,
"select_ms": this selection's own time; with ``explain``: "groups" (per
master group "character/part", instances per "candidate:option") and "model" (the
fit's per-unit costs, their prior and standard deviation, the noise)}.
"""
from __future__ import annotations

import math
import time

import numpy as np

from lod.auto import candidates as ac
from lod.auto import cost_model
from lod.auto import flat, flat_plans
from lod.auto.budget import BudgetController
from lod.auto.control import SWITCH_FRAMES, Decision, PlanChooser
from lod.auto.delegate import Delegates, delegated_stats
from lod.auto.online import OnlineCostModel, RouteShare
from lod.auto.plans import _Block, price_plans, price_plans_loop
from lod.chains import chain as tm_chain
from lod.clusters.cut import viewport_scale
from lod.drawlist import FADE_IN, FADE_OUT, DrawList
from lod.far.build import merge, subset
from lod.full.mode import NoLodSelector

#: (k, L) pixels of error of each chain level per instance (see :func:`lod.auto.candidates.projected_errors`)
projected_errors = ac.projected_errors


class AutoSelector:
    """Cull and pack as the full-detail mode, then choose per instance among
    the candidates (module docstring).

    Parameters
    ----------
    reps : list aligned with ``CrowdState.character`` (:class:`lod.chains.chain.TrianglesRep`
        for skinned characters, full-detail reps for the others): the master
        selection and the triangle candidate
    static_reps : StaticRep scenery
    poe : pixels of error >= 0 (fixed bound, or the start of the adaptive one)
    budget_ms : 0 for a fixed bound, > 0 for a frame-time budget
    model : :class:`lod.auto.cost_model.CostModel` (default: this host's stored
        calibration, else the defaults)
    cull : frustum culling on (default)
    candidates : further :class:`lod.auto.candidates.Candidate` objects
        (clusters, points, ...) besides the triangle candidate, which is
        always first
    adapt : fit the per-unit costs online to the frames reported through
        :meth:`observe` (:mod:`lod.auto.online`) and choose the frame plan
        with hysteresis and exploration (:mod:`lod.auto.control`)
    explore : try uncertain plans (with ``adapt``)
    switch_frames : frames of a faded plan switch (with ``adapt``; 0: at once)
    """

    def __init__(self, reps, static_reps=(), poe: float = 1.0, budget_ms: float = 0.0, model=None,
                 cull: bool = True, candidates=(), adapt: bool = False, explore: bool = True,
                 switch_frames: int = SWITCH_FRAMES, delegates=None, far=None):
        if not (np.isfinite(poe) and float(poe) >= 0.0):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {poe}")
        if not (np.isfinite(budget_ms) and float(budget_ms) >= 0.0):
            raise ValueError(f"[lod] budget_ms: expected a finite number >= 0, got {budget_ms}")
        self.poe = float(poe)
        self.budget_ms = float(budget_ms)
        #: the calibration (the online fit's prior)
        self.prior = model if model is not None else cost_model.load_any()
        self.adapt = bool(adapt)
        #: the online fit of the per-unit costs (:mod:`lod.auto.online`; None without ``adapt``)
        self.fit = OnlineCostModel(self.prior) if self.adapt else None
        #: the share of the triangles the renderer rasterises in compute, as drawn (lod.auto.online.RouteShare)
        self.route = RouteShare()
        #: the costs the options and plans are priced with: the fit's posterior mean (the prior without ``adapt``)
        self.model = self.fit.cost_model() if self.fit is not None else self.prior
        #: the plan decision (:mod:`lod.auto.control`; None without ``adapt``: the cheapest plan is drawn)
        self.chooser = PlanChooser(switch_frames, explore, self.prior.is_default) if self.adapt else None
        #: the single modes' selectors a held pure plan is drawn with once verified (:mod:`lod.auto.delegate`)
        self.delegates = Delegates(delegates if self.chooser is not None else {})
        #: per-group counts and the fit's state in ``stats["auto"]`` (``crowd run --explain-lod``)
        self.explain = False
        self._last = None
        self._means = {}
        self.reps = list(reps)
        self.cull = bool(cull)
        self._rep_index = {r.key: i for i, r in enumerate(self.reps)}
        self._chains = {r.key: r for r in self.reps if isinstance(r, tm_chain.TrianglesRep)}
        self._inner = NoLodSelector(self.reps, static_reps=static_reps, cull=cull)
        self._n_levels = max([r.n_levels for r in self._chains.values()] or [1])
        self.candidates = [ac.TrianglesCandidate(self.reps), *candidates]
        self.controller = BudgetController(self.budget_ms * 1e-3, self.poe) if self.budget_ms > 0 else None
        self._measured = None
        self._uses_measured = False
        #: frames left out of the fit as warm-ups (:meth:`observe`)
        self.warm_frames = 0
        self.explore = bool(explore)
        #: seconds the last :meth:`select` took (what :meth:`observe` subtracts to get the rendering time)
        self.last_select_seconds = 0.0
        self._frames = 0
        #: the far tier's split (``lod.far.select.FarSplit``, ``[lod] far_pixels``) or None
        self.far = far

    @property
    def switch_frames(self) -> int:
        """Frames of a faded plan switch (0: none; a keyframed selection blends keyframes itself)."""
        return self.chooser.switch_frames if self.chooser is not None else 0

    @switch_frames.setter
    def switch_frames(self, n: int) -> None:
        if self.chooser is not None:
            self.chooser.switch_frames = max(0, int(n))

    def cluster_hierarchies(self) -> dict:
        """{rep key: ClusterHierarchy} of the cluster candidate's characters (for geomorphs
        between keyframe cuts, :mod:`lod.temporal.selection`)."""
        return {r.key: r.hierarchy for r in self.candidate_reps if getattr(r, "kind", "") == "clusters"}

    def chain_reps(self) -> dict:
        """{rep key: TrianglesRep} of the triangle chains with vertex collapses (for geomorphs
        between keyframe levels, :mod:`lod.temporal.selection`)."""
        return {k: r for k, r in self._chains.items() if getattr(r, "collapse_next", None) is not None}

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

    def set_budget(self, budget_ms: float) -> None:
        """Change the frame-time budget while running (``crowd fly``): 0 = the fixed bound ``poe``; > 0 = the
        bound adapts to it (:class:`lod.auto.budget.BudgetController`, starting from the current bound)."""
        if not (np.isfinite(budget_ms) and float(budget_ms) >= 0.0):
            raise ValueError(f"[lod] budget_ms: expected a finite number >= 0, got {budget_ms}")
        bound = self.bound
        self.budget_ms = float(budget_ms)
        self.controller = BudgetController(self.budget_ms * 1e-3, bound) if self.budget_ms > 0 else None

    @property
    def bound(self) -> float:
        """Pixels of error the next frame is selected with."""
        return self.controller.bound if self.controller is not None else self.poe

    def observe(self, seconds: float, select_seconds: float | None = None, drawlist=None) -> None:
        """Report the measured cost of the last selected frame.

        Parameters
        ----------
        seconds : selection + rendering of the frame (what ``crowd.engine``
            measures): budget mode adapts the bound to it
        select_seconds : the selection's share of ``seconds``; default: the
            selector's own timing of its last :meth:`select`
            (``last_select_seconds``). With ``adapt`` the rest (the
            rendering, what the cost model predicts) is a row of the online
            fit (:class:`lod.auto.online.OnlineCostModel`) and, when the frame
            drew the plan alone, a measurement of that plan's bias
            (:class:`lod.auto.control.PlanChooser`)
        drawlist : the DrawList drawn (default: the last one selected); its
            counts are the fit's row. A list other than the selector's own
            (a keyframed selection's blend) feeds the fit, not the plans.
            A draw that made GL objects (:attr:`lod.drawlist.DrawList.warm_up`:
            a program's first use, a buffer grown) is a warm-up frame: its
            time carries a one-time cost, so it feeds neither the fit, nor a
            plan's measurements, nor the budget (``warm_frames`` counts them).
        """
        last, self._last = self._last, None
        # the share of triangles the renderer rasterised in compute is the incumbent's (an explored plan's or a
        # fade's would reprice the incumbent's triangles: 1,024 Foxes, triangles 70 -> 117 ms after 3 point frames)
        route = last is None or last.get("incumbent", True)
        if drawlist is not None and drawlist.warm_up:
            self.warm_frames += 1
            if route:
                self.route.observe(drawlist.stats)  # a share of what was drawn, not a time
            if self.chooser is not None and last is not None:
                self.chooser.warm_frame()  # an exploration measures its plan on another frame
            return
        self._measured = float(seconds)
        self._uses_measured = True
        sel_s = self.last_select_seconds if select_seconds is None else float(select_seconds)
        render = float(seconds) - (sel_s if np.isfinite(sel_s) and sel_s > 0 else 0.0)
        if not (self.fit is not None and np.isfinite(render) and render > 0):
            return
        own = last is not None and (drawlist is None or drawlist is last["dl"])
        if own:  # under a budget: the plan's last measurement, and a pull-back after a frame far over it
            self.chooser.measured(last["plans"], render, last["clean"])
        if drawlist is not None:
            if route:
                self.route.observe(drawlist.stats)
            x = cost_model.features(drawlist, extended=True)  # as drawn: scenery and other counts included
        elif last is not None:
            x = last["x"]
        else:
            return
        if self.fit.update(x, render) is not None and own:  # the row as the fit took it (load-free)
            self.chooser.observed(last["plans"], self.fit.last_z, self.fit.last_u, last["clean"], last.get("content"))
        self.model = self.fit.cost_model(self.route.share)

    def _options(self, frame, g, bound):
        """Every candidate's options for group ``g``: a list of :class:`_Block` (module docstring,
        "Selection work": a candidate with a cost lower bound is asked only for the instances where that
        bound is below the cheapest option within the bound found so far)."""
        opts, a = [], 0
        best = None
        tri = self.candidates[0]
        for c in self._order():
            if c is not tri and not bound > 0.0:
                continue
            skipped = None
            lb = c.cost_lower_bound(frame, g) if best is not None else None
            if lb is not None:
                need = lb < best
                skipped = ~need
                o = c.options(frame, g, need) if skipped.any() else c.options(frame, g)
                if not skipped.any():
                    skipped = None
            else:
                o = c.options(frame, g)
            if o is None or not o.cost.shape[1]:
                continue
            blk = _Block.of(c, o, a, skipped, bound, c is tri)
            opts.append(blk)
            a += blk.m
            best = blk.bmin if best is None else np.minimum(best, blk.bmin)
        return opts

    @staticmethod
    def _has_lb(c) -> bool:
        return type(c).cost_lower_bound is not ac.Candidate.cost_lower_bound

    def _order(self) -> list:
        """The candidates in the order :meth:`_options` asks them (their blocks' order in a group):
        the triangles, those without a cost lower bound, then those with one."""
        tri = self.candidates[0]
        return [tri] + [c for c in self.candidates[1:] if not self._has_lb(c)] + \
            [c for c in self.candidates[1:] if self._has_lb(c)]

    def _plans(self, frame, groups, bound, fixed=(0.0, frozenset()), one_pass: bool = True):
        """The frame plans (module docstring, "Plans"): name -> :class:`_Plan`; ``fixed``: (seconds,
        candidate names) of the whole-group draws every plan includes (:meth:`Candidate.wholes`).

        Every pure plan and the mixed one are priced over all groups of all characters in one pass
        (:func:`lod.auto.plans.price_plans`: the candidates' blocks, each block's cheapest admissible
        option per instance computed once, side by side; the mixed plan is the argmin over the blocks
        in use, ties to the lower column, as :func:`choose`). ``one_pass=False``: the per-group loop it
        replaced (:func:`lod.auto.plans.price_plans_loop`), kept as the reference the tests compare."""
        fc = {cand.name: (cand.frame_cost(frame) if bound > 0.0 else 0.0) for cand in self.candidates[1:]}
        coef = frame.model.coefficients
        if not one_pass:
            return price_plans_loop(self.candidates, groups, coef, fc, fixed)
        if isinstance(groups, flat.FlatGroups) and not groups.stale:  # from the flat rows (lod.auto.flat)
            return flat_plans.price(self.candidates, groups, coef, fc, fixed, order=self._order())
        return price_plans(self.candidates, groups, coef, fc, fixed, order=self._order())

    #: per-instance options over flat arrays of all instances (:mod:`lod.auto.flat`); False: group by group
    #: (:meth:`_options`, the reference the tests compare with)
    flat = True

    def _groups(self, frame, dl, bound, out) -> list:
        """The agent batches of the master list ``dl`` as [(group, [_Block per candidate], columns)] (the
        scenery batches go to ``out`` as they are): over flat arrays of all instances (:mod:`lod.auto.flat`)
        when :attr:`flat` and every candidate has a flat form, else group by group (:meth:`_options`)."""
        agents = []
        for b in dl.batches:
            ri = self._rep_index.get(b.rep)
            if ri is None or b.n_instances == 0 or int(b.instance_ids[0]) < 0:  # scenery
                out.append(b)
            else:
                agents.append((ri, b))
        groups = flat.groups(self, frame, agents, bound) if self.flat else None
        if groups is not None:
            return groups
        groups = []
        for ri, b in agents:
            rows = np.asarray(b.instance_data, np.float32)[:, :12].astype(np.float64).reshape(-1, 3, 4)
            g = ac.Group(ri, b, rows)
            opts = self._options(frame, g, bound)
            groups.append((g, opts, sum(x.m for x in opts)))
        return groups

    def select(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList: the far tier's agents first (``lod.far``, ``[lod] far_pixels``: one splat each,
        a rule before the choice, not one of its candidates), then the rest (:meth:`_select_rest`)."""
        if self.far is None or not self.far.active or not state.n:
            return self._select_rest(state, camera, size, statics)
        t0 = time.perf_counter()
        w, h = max(1, int(size[0])), max(1, int(size[1]))
        near, far_batches, _ = self.far.split(state, camera, size, viewport_scale(h, camera.fov_y),
                                              camera.frustum_planes(w / h))
        split_s = time.perf_counter() - t0
        dl = self._select_rest(state if near is None else subset(state, near), camera, size, statics)
        merge(dl, state.n, near, far_batches, remap=True)
        a = dl.stats.get("auto")
        if isinstance(a, dict):
            a.setdefault("representations", {})["far"] = dl.stats["far"]
        if self._last is not None and self._last.get("dl") is dl:  # the fit's row counts the far splats
            self._last["x"] = cost_model.features(dl, extended=True)
        self.last_select_seconds += split_s
        return dl

    def _select_rest(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList (see :meth:`lod.full.mode.NoLodSelector.select`):
        every instance inside the frustum in exactly one batch of the
        candidate it was given; batches sorted by (rep, part, level);
        ``stats["auto"]`` holds the telemetry (module docstring).

        Under a budget, a bound the controller lowered this frame whose selection is predicted to pass the
        rendering seconds the budget leaves is refused before anything is drawn: the frame is selected again
        at the bound before (:meth:`lod.auto.budget.BudgetController.refuse`; ``stats["auto"]["refused_bound"]``).
        Points have a cliff there: the horses' 600 K points at 2.25 px were 2.7 M at 1.84 px, a 210 ms frame
        under a 70 ms budget, which the prediction saw coming."""
        c = self.controller
        before = c.bound if c is not None else None
        dl = self._select(state, camera, size, statics)
        a = dl.stats.get("auto")
        limit = self._render_budget()
        if (c is not None and limit is not None and isinstance(a, dict) and float(a["bound"]) < before
                and 1e-3 * float(a["predicted_ms"]) > limit):
            refused = float(a["bound"])
            c.refuse(before)
            dl = self._select(state, camera, size, statics)
            dl.stats["auto"]["refused_bound"] = refused
        return dl

    def _render_budget(self) -> float | None:
        """The rendering seconds the budget leaves after the last selection (at most half of it), or None
        without a budget."""
        b = self.budget_ms * 1e-3
        return b - min(self.last_select_seconds, 0.5 * b) if b > 0 else None

    def _select(self, state, camera, size, statics=()) -> DrawList:
        t_start = time.perf_counter()
        if self.controller is not None and self._measured is not None:
            self.controller.update(self._measured)
            self._measured = None
        bound = float(self.bound)
        if not (np.isfinite(bound) and bound >= 0.0):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {bound}")
        if self.chooser is not None:  # (lod.auto.control, issue 49)
            self.chooser.budget = self._render_budget()
        held = self._held()  # steady on a pure plan: the others are not priced (lod.auto.control)
        if held is not None and self.delegates.ready(held):  # or the single mode's own selector
            dl = self.delegates.select(held, state, camera, size, statics, bound, self.candidates)
            if dl is not None:
                return self._delegated(dl, held, bound, t_start)
        w, h = max(1, int(size[0])), max(1, int(size[1]))
        frame = ac.Frame(state, camera, (w, h), camera.frustum_planes(w / h), viewport_scale(h, camera.fov_y), bound,
                         self.model, self.cull)
        levels = np.zeros(self._n_levels, np.int64)
        per_cand = {c.name: 0 for c in self.candidates}
        tel = ac.Telemetry()
        out = []
        # whole groups first (§3.6 super-hierarchies): their agents get no per-instance option
        wholes, taken, fixed_s, fixed_used, represented = [], None, 0.0, set(), 0
        if bound > 0.0:
            for c in self.candidates[1:]:
                wb, tk, sec = c.wholes(frame)
                if wb:
                    wholes.extend(wb)
                    fixed_s += sec
                    fixed_used.add(c.name)
                    taken = tk if taken is None else taken | tk
                    n_rep = int(sum(getattr(x, "represented", x.n_instances) for x in wb))
                    per_cand[c.name] += n_rep
                    represented += n_rep
                    tel.add(c.name, "super", n_rep)
        if taken is not None and taken.any():
            # only the agents no whole group draws are culled and packed (as mode points does): a far view
            # of 90,000 instancing agents drawn from super nodes packs none of them
            dl = self._inner.select(state, camera, size, statics, agents=np.flatnonzero(~taken))
            dl.stats["instances"] += represented
            dl.stats["culled"] = int(state.n - dl.stats["instances"])
        else:
            dl = self._inner.select(state, camera, size, statics)
        groups = self._groups(frame, dl, bound, out)
        plans = self._plans(frame, groups, bound, (fixed_s, fixed_used))
        if held is not None:
            if not plans[held].exact:
                groups = self._exact(frame, groups, bound)
                plans = self._plans(frame, groups, bound, (fixed_s, fixed_used))
            dec = self.chooser.hold(plans[held].content)
            self._means = {held: (plans[held].seconds, 0.0)}
        else:
            dec, plans, groups = self._decide(frame, plans, groups, bound, (fixed_s, fixed_used))
        plan_name = plans[dec.plan].measured_as(dec.plan)
        old = plans[dec.fade_from] if dec.fade_from is not None else None
        gc = {} if self.explain else None
        for gi, (g, opts, ncols) in enumerate(groups):
            choice = plans[dec.plan].choices[gi]
            if old is None:
                self._emit(frame, g, opts, choice, None, None, out, (per_cand, tel, levels, gc))
                continue
            prev = old.choices[gi]
            moved = choice != prev
            self._emit(frame, g, opts, choice, ~moved, None, out, (per_cand, tel, levels, gc))
            if moved.any():  # both representations, complementary screen-door patterns (no pop)
                self._emit(frame, g, opts, choice, moved, (dec.t, FADE_IN), out, (per_cand, tel, levels, gc))
                self._emit(frame, g, opts, prev, moved, (dec.t, FADE_OUT), out, None)
        out.extend(wholes)
        out.sort(key=lambda x: (x.rep, x.part, x.level))
        dl.batches = out
        dl.stats["points"] = 0
        for c in self.candidates:
            c.finish(frame, dl)
        dl.stats["triangles"] = int(sum(x.triangles for x in out))
        dl.stats["batches"] = len(out)
        dl.stats["levels"] = [int(x) for x in levels]
        x = cost_model.features(dl, extended=True)  # once: the prediction is linear in these counts
        self._last = {"x": x, "dl": dl, "clean": old is None, "content": plans[dec.plan].content,
                      "plans": [n for n in plans if plans[n].measured_as(n) == plan_name],
                      "incumbent": old is None and plan_name == plans[dec.incumbent].measured_as(dec.incumbent)
                      if dec.incumbent in plans else old is None}
        predicted, sd = self._predicted(x, plan_name, old is None)
        a = {"levels": [int(v) for v in levels], "representations": per_cand, "options": tel.counts,
             "predicted_ms": 1e3 * predicted, "predicted_sd_ms": 1e3 * sd, "bound": bound,
             "budget_ms": self.budget_ms, "plan": plan_name, "state": dec.state,
             "incumbent": dec.incumbent, "fade_t": dec.t, "threshold": dec.threshold,
             "fade_from": plans[dec.fade_from].measured_as(dec.fade_from) if old is not None else None,
             "plans_ms": {n: 1e3 * v[0] for n, v in self._means.items()},
             "plans_sd_ms": {n: 1e3 * v[1] for n, v in self._means.items()},
             "unmeetable": bool(self.chooser is not None and self.chooser.unmeetable)}
        if gc is not None:
            a["groups"] = gc
            a["model"] = self.fit.state() if self.fit is not None else None
        dl.stats["auto"] = a
        if self.controller is not None and not self._uses_measured:
            self.controller.update(predicted)
        self._frames += 1
        self.last_select_seconds = time.perf_counter() - t_start
        a["select_ms"] = 1e3 * self.last_select_seconds
        if held is not None and self.delegates.pending(held):  # does the single mode draw the same? (once)
            self.delegates.verify(held, dl, state, camera, size, statics, bound, self.candidates)
        return dl

    def _delegated(self, dl, plan: str, bound: float, t_start: float):
        """A held frame drawn by the single mode's selector (:mod:`lod.auto.delegate`): its telemetry."""
        self.chooser.hold()
        x = cost_model.features(dl, extended=True)
        self._last = {"x": x, "dl": dl, "clean": True, "plans": [plan]}
        predicted, sd = self._predicted(x, plan, True)
        self._means = {plan: (predicted, 0.0)}
        dl.stats["auto"] = a = delegated_stats(dl, plan, predicted, sd, bound, self)
        if self.controller is not None and not self._uses_measured:
            self.controller.update(predicted)
        self._frames += 1
        self.last_select_seconds = time.perf_counter() - t_start
        a["select_ms"] = 1e3 * self.last_select_seconds
        return dl

    # ------------------------------------------------------------------------------------- plan choice
    def _held(self):
        """The pure plan (its candidate's name) the chooser holds this frame without pricing the others
        (:meth:`lod.auto.control.PlanChooser.can_hold`), or None: every candidate is asked."""
        if self.chooser is None or not self.chooser.can_hold():
            return None
        inc = self.chooser.incumbent
        return inc if any(c.name == inc for c in self.candidates) else None

    def _exact(self, frame, groups, bound):
        """``groups`` with every instance a candidate skipped (its cost lower bound) priced exactly."""
        out = list(groups)
        for gi, (g, opts, ncols) in enumerate(groups):
            if any(x.skipped is not None for x in opts):
                full = [x if x.skipped is None else
                        _Block.of(x.cand, x.cand.options(frame, g), x.a, None, bound, x.cand is self.candidates[0])
                        for x in opts]
                out[gi] = (g, full, ncols)
        return out

    def _decide(self, frame, plans, groups, bound, fixed):
        """(:class:`lod.auto.control.Decision`, plans, groups) of this frame. A plan priced optimistically
        (instances at a candidate's cost lower bound) is priced exactly before it can win or be drawn, so
        skipping never changes the choice (module docstring, "Selection work").

        With ``adapt`` the :class:`lod.auto.control.PlanChooser` decides (hysteresis, exploration, faded
        switches) on the plans priced with the online fit's costs; without it the cheapest plan is drawn."""
        def cheapest(ps):
            return min(ps, key=lambda n: (ps[n].seconds, n != "mixed"))

        best = cheapest(plans)
        inc = self.chooser.incumbent if self.chooser is not None else None
        if (not plans[best].exact or (inc in plans and not plans[inc].exact)
                or (self.chooser is not None and self.chooser.pulling_back)):  # a pull-back chooses on exact prices
            groups = self._exact(frame, groups, bound)
            plans = self._plans(frame, groups, bound, fixed)
            best = cheapest(plans)
        if self.chooser is None:
            self._means = {n: (p.seconds, 0.0) for n, p in plans.items()}
            return Decision(best, state="fixed", incumbent=best), plans, groups
        canon = {n: p.measured_as(n) for n, p in plans.items()}
        dec = self.chooser.choose({n: p.seconds for n, p in plans.items()}, self.fit,
                                  equal=lambda u, v: canon[u] == canon[v],
                                  content={n: p.content for n, p in plans.items() if p.content is not None})
        self._means = {n: (m, sd) for n, (m, sd, _) in self.chooser.last.items()}
        if dec.state == "steady" and dec.plan == dec.incumbent and plans[dec.plan].alias is not None:
            # the incumbent draws what a pure plan draws (the mixed plan that settled on one representation): it
            # goes by that plan's name, so it is held and drawn by the single mode's selector (lod.auto.delegate)
            self.chooser.rename(dec.plan, plans[dec.plan].alias)
        if any(not plans[n].exact for n in (dec.plan, dec.fade_from) if n is not None):
            groups = self._exact(frame, groups, bound)
            plans = self._plans(frame, groups, bound, fixed)
            undone = self.chooser.veto(dec, plans[dec.plan].seconds)  # under a budget (lod.auto.control)
            dec = undone if undone is not None else dec
        return dec, plans, groups

    def _emit(self, frame, g, opts, choice, rows, fade, out, tally) -> None:
        """The batches of group ``g`` drawing ``choice`` (option column per instance) for the instances
        ``rows`` (bool mask; None: all), with ``DrawBatch.fade`` = ``fade``; ``tally`` = (instances per
        candidate, option telemetry, chain levels, per-group counts or None) counts what is drawn (None:
        nothing, the outgoing copies of a transition)."""
        for x in opts:
            c, o, a, m = x.cand, x.options, x.a, x.m
            inb = (choice == a) if m == 1 else ((choice >= a) & (choice < a + m))
            mine = np.flatnonzero(inb if rows is None else inb & rows)
            if not mine.size:
                continue
            local = choice[mine] - a
            bs = c.emit(frame, g, o, mine, local)
            if fade is not None:
                for b in bs:
                    b.fade = fade
            out.extend(bs)
            if tally is None:
                continue
            per_cand, tel, levels, gc = tally
            per_cand[c.name] += int(mine.size)
            cnt = np.bincount(local, minlength=m)
            for j in np.flatnonzero(cnt).tolist():
                label = o.labels[j] if j < len(o.labels) else str(j)
                tel.add(c.name, label, int(cnt[j]))
                if gc is not None:
                    key = f"{g.batch.rep.split(':', 1)[-1]}/{int(g.batch.part)}"  # the character, not its rep
                    d = gc.setdefault(key, {})
                    d[f"{c.name}:{label}"] = d.get(f"{c.name}:{label}", 0) + int(cnt[j])
            if c is self.candidates[0]:
                if g.batch.rep in self._chains:
                    levels[:m] += cnt
                else:
                    levels[0] += int(mine.size)

    def _predicted(self, x, plan: str, clean: bool) -> tuple[float, float]:
        """(seconds, sd) the drawn list's rendering is predicted to take: the fit's costs of its counts ``x``
        (times the plan's measured bias on a clean frame), else the fixed model's."""
        if self.fit is None:
            v = self.model.vector
            return float(v[0] + v[1:] @ x[:len(cost_model.FEATURES)]), 0.0
        m, sd = self.fit.predict(self.route.split(x))
        if clean and self.chooser is not None:
            m *= math.exp(self.chooser.bias(plan, self.fit)[0])
        return m, math.sqrt(sd ** 2 + (self.fit.noise * m) ** 2)

__all__ = ["AutoSelector", "projected_errors"]
