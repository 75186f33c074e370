"""Which frame plan mode auto draws: hysteresis on the measured noise, bounded exploration, faded switches
(issue 26, item 1).

:class:`lod.auto.mode.AutoSelector` prices a few *frame plans* every frame (the mixed per-instance plan and
one pure plan per representation, :mod:`lod.auto.plans`) with the online cost model
(:mod:`lod.auto.online`). :class:`PlanChooser` decides which one is drawn:

- **Incumbent and hysteresis.** One plan is the incumbent. Another plan ``p`` replaces it only when its
  predicted gain ``(M_c - M_p) / M_c`` exceeds ``max(MIN_GAIN, K_SWITCH · sd / M_c)`` on
  :data:`PERSIST` consecutive frames, where ``sd`` is the standard deviation of the predicted *difference*
  (the fit's posterior covariance on the difference of the two plans' counts, plus the uncertainty of each
  plan's measured bias, which scales with the measured residual noise). Noise the fit has measured widens the
  band; alternating noisy frames therefore do not make it flap, and a load that slows every plan alike
  cancels in the difference.
- **Plans' counts.** A plan's predicted mean ``M_p`` is the pricing's total under the fit's current costs,
  times the plan's measured bias: ``exp`` of the mean log residual of the last clean frames that drew what
  it draws now (at most :data:`BIAS_FRAMES`, no older than :data:`BIAS_AGE`), shrunk by
  ``n / (n + BIAS_SHRINK)`` (what the linear model misses for that content). Its counts for the covariance
  are those of the last frame it was drawn, rescaled to ``M_p``; a plan never drawn has a relative
  uncertainty of :data:`UNMEASURED_SD` and a lower bound of ``M_p /`` :data:`UNMEASURED_FACTOR`
  (:data:`UNMEASURED_FACTOR_NEUTRAL` without a calibration).
- **Bias by content** (issue 50, item 2). A measured frame updates the estimate of what it drew, not of a
  name: a plan's content is the share of its priced seconds per candidate (:attr:`lod.auto.plans._Plan.
  content`), and a clean frame counts for the bias of every plan whose content is within
  :data:`CONTENT_TOLERANCE` of the drawn one's (total variation). A plan whose content changed (the mixed
  plan that drew points alone and now draws mostly triangles, a pure plan whose options moved with the
  bound) does not keep the old content's bias; two plans that draw alike share their frames.
- **Exploration.** When the incumbent is steady and a plan's lower confidence bound
  ``M_p - EXPLORE_Z · sd`` undercuts the incumbent, measured on :data:`EXPLORE_AFTER` frames (the fit is
  unsure about a plan that could win, e.g. a representation not drawn for a while, whose uncertainty the
  forgetting lets grow back), that plan is drawn for :data:`EXPLORE_RUN` measured frames (a frame whose draw
  carried a one-time cost, a warm-up, is replaced by another, :meth:`PlanChooser.warm_frame`). It is kept if
  the hysteresis rule then prefers it, or if what its frames measured is faster than the incumbent's last
  clean frames beyond the noise (:meth:`PlanChooser._measured_gain`: where the linear model cannot tell the
  two apart, the measurements decide); else auto returns. An exploration is a cut to the plan and back
  (:data:`EXPLORE_FADE` = 0 frames of fade: a fade draws the changed instances in both representations, one
  of the plaza's or the Foxes' dearest frames, and every plan is within the error bound, so the cut changes
  the image by at most the bound; issue 50, item 3). Bounds: the frames drawing an explored plan (fades
  included) are at most ``EXPLORE_FRACTION`` of the frames (plus an allowance of :data:`EXPLORE_ALLOWANCE` for
  the start: four explorations); an exploration never starts within :data:`EXPLORE_GAP` frames of the last
  one, and never retries a plan within :data:`EXPLORE_COOLDOWN` frames. A single frame cannot trigger it: the
  decision rests on the posterior and a run of several frames is measured before anything is kept (the rule
  of run M in ``scripts/bench_auto.md``, which explored and switched on single noisy frames, is what this
  replaces).
- **Held frames.** While the incumbent is a steady pure plan (one representation), the plans are compared on
  every :data:`REPRICE_FRAMES`-th frame only; in between the incumbent is drawn without a decision, by the
  single mode's own selector once its list is verified to be the plan's (:mod:`lod.auto.delegate`): then auto's
  selection costs what the single mode's does.
- **Under a frame budget** (:attr:`PlanChooser.budget`, the rendering seconds a budget leaves, issue 49) every
  plan has a *pessimistic* cost: its corrected mean times :data:`PESSIMISM` (:attr:`PlanChooser.
  unmeasured_factor` for a plan never drawn), or what its last clean frame measured when that was more (no
  older than :data:`MEASURED_AGE` frames: a plan's content follows the bound). Exploration tries only plans
  whose pessimistic cost fits the budget (exploring happens inside it) and the hysteresis switches only to a
  plan that fits it or is surely cheaper than the incumbent. A frame that draws more than :data:`OVERRUN`
  times the budget pulls back on the next frame, without a fade, to the plan measured cheapest lately within the
  budget and priced within it now (else the one of lowest pessimistic cost; an exploration is cut short). When
  no plan fits (none priced pessimistically within the budget, nor measured within it on the last
  :data:`FRESH_FRAMES` frames with :data:`FRESH_MARGIN` to spare), :attr:`PlanChooser.unmeetable` says so and
  the cheapest pessimistic plan is drawn.
- **No pop.** A change of the drawn plan is a transition of ``switch_frames`` frames: the instances whose
  representation differs between the two plans are drawn by both with complementary screen-door fades
  (``DrawBatch.fade``, as :mod:`lod.temporal.selection` blends two keyframe selections), the weight
  ``t = r / (switch_frames + 1)`` rising frame by frame; 0 frames switch at once. Under a budget a change
  fades only when the two plans' pessimistic costs together fit it; otherwise it switches at once.

The chooser is pure Python on a few numbers per plan; it never sees instances.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

#: a steady pure incumbent is drawn without pricing the other plans on all but every REPRICE_FRAMES-th frame
REPRICE_FRAMES = 8
#: smallest relative gain that moves the incumbent
MIN_GAIN = 0.03
#: gain needed, in standard deviations of the predicted difference
K_SWITCH = 1.0
#: consecutive frames the gain must hold
PERSIST = 3
#: frames of a transition between two plans (screen-door fade); 0 = switch at once
SWITCH_FRAMES = 4
#: lower confidence bound of exploration, in standard deviations
EXPLORE_Z = 1.0
#: clean frames an explored plan is measured on after its fade-in, and the longest fade to and from it (0: a cut)
EXPLORE_RUN = 2
EXPLORE_FADE = 0
#: warm-up frames (lod.drawlist.DrawList.warm_up) an exploration replaces by further frames of its plan, at most
EXPLORE_WARM = 2
#: an explored plan measured faster than the incumbent by this many robust standard deviations of the incumbent's
#: frame-to-frame spread is kept (PlanChooser._measured_gain)
MEASURED_GAIN_SD = 3.0
#: share of frames exploration may take (fades included), and the allowance at the start
EXPLORE_FRACTION = 0.1
EXPLORE_ALLOWANCE = 8
#: clean frames of the incumbent measured before anything is explored
EXPLORE_AFTER = 2
#: frames between two explorations, and before the same plan is tried again
EXPLORE_GAP = 8
EXPLORE_COOLDOWN = 90
#: relative uncertainty of a plan never drawn in this run (for the hysteresis: switching to it unmeasured needs
#: a gain of K_SWITCH times this), and the factor its cost may be below the prediction (its lower bound for
#: exploration: a calibration taken under load mispriced one representation against another 2.5x,
#: scripts/bench_auto.md runs K-M)
UNMEASURED_SD = 0.5
UNMEASURED_FACTOR = 2.0
#: the same for the neutral prior (no calibration of this machine: the defaults of another one)
UNMEASURED_FACTOR_NEUTRAL = 3.0
#: clean frames (and their largest age) a plan's bias is the mean of, and its shrinkage
BIAS_FRAMES = 8
BIAS_AGE = 90
BIAS_SHRINK = 2.0
#: a measured frame counts for a plan's bias when their contents (the shares of the priced seconds per
#: candidate, :attr:`lod.auto.plans._Plan.content`) differ by at most this (total variation distance)
CONTENT_TOLERANCE = 0.15
#: clean frames kept for the biases, of every content
OBS_FRAMES = 64
#: under a budget: a measured plan's pessimistic cost is its corrected mean times this (predictions after warm-up
#: are asked to be within 25 %), or what it last measured when more, no older than MEASURED_AGE frames
PESSIMISM = 1.25
MEASURED_AGE = 30
#: a plan measured clean within FRESH_FRAMES frames (the one drawn) fits the budget when the larger of its
#: corrected mean and what it measured, plus FRESH_MARGIN, does: "no plan fits" is not said of a plan measured at
#: 26 ms under a 29 ms limit because 1.25 x its 24 ms prediction passes it
FRESH_FRAMES = 3
FRESH_MARGIN = 0.05
#: a frame over the budget by more than this factor pulls back at once
OVERRUN = 1.5


@dataclass
class Decision:
    """What to draw this frame.

    plan : the plan drawn (its name)
    fade_from : the plan faded out (None: no transition)
    t : transition weight in (0, 1) of the incoming plan (0 without a transition)
    state : "steady", "pending" (a better plan is waiting out the hysteresis), "switch" (first frame of a
        switch), "transition", "explore" (fading in or measuring an explored plan) or "return"
    incumbent : the incumbent plan
    threshold : relative gain the best other plan would need (None when there is none)
    """

    plan: str
    fade_from: str | None = None
    t: float = 0.0
    state: str = "steady"
    incumbent: str | None = None
    threshold: float | None = None


class PlanChooser:
    """The plan decision of one selector (module docstring).

    Parameters
    ----------
    switch_frames : frames of a transition (0: none)
    neutral : the fit's prior is the defaults, not a calibration of this machine (explore more widely)
    explore : try uncertain plans (bounded); False: hysteresis only
    """

    def __init__(self, switch_frames: int = SWITCH_FRAMES, explore: bool = True, neutral: bool = False):
        self.switch_frames = int(switch_frames)
        #: how much cheaper than predicted a plan never drawn may be (lower for a calibration of this machine)
        self.unmeasured_factor = UNMEASURED_FACTOR_NEUTRAL if neutral else UNMEASURED_FACTOR
        self.explore = bool(explore)
        self.incumbent: str | None = None
        self.frames = 0
        self.explored = 0
        self.switches = 0
        self.explorations = 0
        self._pending = (None, 0)
        self._since = 0  # frames since the plans were last priced
        self._transition = None  # [from, to, r]
        self._exploring = None  # [plan, frames left]
        self._warm = 0  # warm-up frames the exploration running has replaced
        self._last_explore = -10 ** 9
        self._tried: dict = {}
        self._z: dict = {}  # plan -> counts row (fit units) of its last drawn frame
        self._obs: deque = deque(maxlen=OBS_FRAMES)  # (frame, row / seconds, content, plan names) of clean frames
        self._content: dict = {}  # plan -> its content at its last pricing (lod.auto.plans._Plan.content)
        self.last = {}  # plan -> (mean, sd of the difference to the incumbent, lower bound) of the last frame
        #: rendering seconds a frame budget leaves (None: no budget; module docstring, "Under a frame budget")
        self.budget: float | None = None
        #: no plan's pessimistic cost fits the budget (the cheapest is drawn)
        self.unmeetable = False
        self.pullbacks = 0
        self.high: dict = {}  # plan -> its pessimistic cost on the last priced frame
        self._measured: dict = {}  # plan -> (frame, seconds) of its last clean frame
        self._secs: dict = {}  # plan -> deque of (frame, seconds) of its last clean frames
        self._overrun = False
        self._before = None  # the incumbent before this frame's decision

    # ------------------------------------------------------------------------------------------ measurements
    def observed(self, plans, z, u, clean: bool, content=None) -> None:
        """A drawn frame of ``plans`` (a name, or the names of the plans that drew the same list): its counts row
        ``z`` (fit units) and ``u`` = ``z`` over the measured seconds (:attr:`lod.auto.online.OnlineCostModel.
        last_u`); ``clean``: the frame drew that plan alone (no transition), so it measures the bias of what it
        drew: of every plan whose content is within :data:`CONTENT_TOLERANCE` of ``content`` (the drawn plan's
        :attr:`lod.auto.plans._Plan.content`; default: its content at its last pricing; None: of these names)."""
        names = [plans] if isinstance(plans, str) else [p for p in plans if p is not None]
        if not names:
            return
        for p in names:
            self._z[p] = np.asarray(z, np.float64)
        if clean:
            c = self._content.get(names[0]) if content is None else np.asarray(content, np.float64)
            self._obs.append((self.frames, np.asarray(u, np.float64), c, tuple(names)))

    def measured(self, plans, seconds: float, clean: bool) -> None:
        """The rendering ``seconds`` of the last frame, which drew ``plans`` (their names; ``clean``: one plan
        alone, no transition): kept per plan for its pessimistic cost; a frame over :data:`OVERRUN` times the
        budget makes the next decision pull back."""
        if not math.isfinite(seconds):
            return
        if clean:
            for p in plans:
                self._measured[p] = (self.frames, float(seconds))
                self._secs.setdefault(p, deque(maxlen=BIAS_FRAMES)).append((self.frames, float(seconds)))
        if self.budget is not None and seconds > OVERRUN * self.budget:
            self._overrun = True

    @property
    def pulling_back(self) -> bool:
        """The next decision pulls back (a frame far over the budget): the plans must be priced exactly."""
        return self.budget is not None and self._overrun

    def _high(self, p: str, mean: float, drawn: bool) -> float:
        """The pessimistic cost of plan ``p`` (module docstring)."""
        hi = mean * (PESSIMISM if drawn else self.unmeasured_factor)
        f, sec = self._measured.get(p, (None, 0.0))
        if f is not None and self.frames - f <= MEASURED_AGE:
            hi = max(hi, sec)
        return hi

    def _fits(self, p: str, mean: float, limit: float) -> bool:
        """Whether plan ``p`` (corrected mean ``mean``) can be drawn within ``limit`` seconds: its pessimistic cost
        fits, or it was measured within :data:`FRESH_FRAMES` frames and the larger of that and its mean, plus
        :data:`FRESH_MARGIN`, fits (what "no plan fits" is said by)."""
        if self.high[p] <= limit:
            return True
        f, sec = self._measured.get(p, (None, 0.0))
        return f is not None and self.frames - f <= FRESH_FRAMES and max(mean, sec) * (1.0 + FRESH_MARGIN) <= limit

    def content(self, plan: str):
        """``plan``'s content at its last pricing (None: not priced with a content)."""
        return self._content.get(plan)

    def bias(self, plan: str, fit) -> tuple[float, int]:
        """(log factor, clean frames) of ``plan``'s measured / predicted under the current fit (shrunk), over the
        last :data:`BIAS_FRAMES` clean frames that drew what it draws now (bias by content, module docstring)."""
        c = self._content.get(plan)
        obs = []
        for f, u, oc, names in reversed(self._obs):
            if self.frames - f > BIAS_AGE or len(obs) >= BIAS_FRAMES:
                break
            if (plan in names if c is None or oc is None or oc.shape != c.shape
                    else 0.5 * float(np.abs(c - oc).sum()) <= CONTENT_TOLERANCE):
                obs.append(u)
        if not obs:
            return 0.0, 0
        r = [-math.log(max(fit.relative(u), 1e-12)) for u in obs]
        n = len(r)
        return sum(r) / (n + BIAS_SHRINK), n

    def _stats(self, means: dict, fit) -> dict:
        """plan -> (corrected mean seconds, clean frames, counts row rescaled to it or None)."""
        out = {}
        for p, m in means.items():
            b, n = self.bias(p, fit)
            mc = float(m) * math.exp(b)
            z = self._z.get(p)
            if z is not None:
                pz = fit.predict_z(z)
                z = z * (mc / pz) if pz > 0 else None
            out[p] = (mc, n, z)
        return out

    def _sd_diff(self, st: dict, p: str, c: str, fit) -> float:
        mp, n_p, zp = st[p]
        mc, n_c, zc = st[c]
        if zp is None or zc is None:
            return UNMEASURED_SD * math.hypot(mp if zp is None else 0.0, mc if zc is None else 0.0)
        s2 = fit.sd_z(zp - zc) ** 2 + fit.noise ** 2 * (mp ** 2 / (n_p + BIAS_SHRINK) + mc ** 2 / (n_c + BIAS_SHRINK))
        return math.sqrt(s2)

    # ------------------------------------------------------------------------------------------ the decision
    def choose(self, means: dict, fit, equal=None, content=None) -> Decision:
        """This frame's :class:`Decision`.

        Parameters
        ----------
        means : plan name -> predicted seconds under the fit's current costs (one entry per distinct plan)
        fit : the :class:`lod.auto.online.OnlineCostModel`
        equal : optional function (a, b) -> True when plans a and b draw the same this frame
        content : optional plan name -> :attr:`lod.auto.plans._Plan.content` this frame (what its bias is kept by)
        """
        if content:
            self._content.update(content)
        self.frames += 1
        self._since = 1
        self._before = self.incumbent
        st = self._stats(means, fit)
        best = min(st, key=lambda p: st[p][0])
        if self.incumbent is None or self.incumbent not in st:
            self.incumbent = best
            self._pending = (None, 0)
            self._transition = None
            self._exploring = None
        c = self.incumbent
        same = equal or (lambda a, b: a == b)
        self.last = {}
        for p in st:
            sd = self._sd_diff(st, p, c, fit) if p != c else 0.0
            low = st[p][0] / self.unmeasured_factor if st[p][2] is None else st[p][0] - EXPLORE_Z * sd
            self.last[p] = (st[p][0], sd, low)

        def threshold(p, base):
            return max(MIN_GAIN, K_SWITCH * self.last[p][1] / max(st[base][0], 1e-12))

        def gain(p, base):
            return (st[base][0] - st[p][0]) / max(st[base][0], 1e-12)

        others = [p for p in st if p != c and not same(p, c)]
        thr = min((threshold(p, c) for p in others), default=None)
        self.high = {p: self._high(p, st[p][0], st[p][2] is not None) for p in st}
        limit = self.budget  # the frame budget's rendering seconds (None: no budget)
        self.unmeetable = limit is not None and not any(self._fits(p, st[p][0], limit) for p in st)
        if limit is not None and self._overrun:  # a frame far over the budget: pull back now, no fade
            self._overrun = False
            # (and priced within the budget now: a plan's content follows the bound, its name stays -- the
            # horses' "mixed", measured at 60 ms, had become a 325 ms frame when it was pulled back to)
            fresh = {p: sec for p, (f, sec) in self._measured.items()
                     if self.frames - f <= MEASURED_AGE and p in st and sec <= limit and self.high[p] <= limit}
            # to the plan measured cheapest lately within the budget (a prediction is what just failed), else the
            # cheapest pessimistic
            target = (min(fresh, key=lambda p: (fresh[p], p != c)) if fresh else
                      min(self.high, key=lambda p: (self.high[p], p != c)))
            drawn = self._exploring[0] if self._exploring is not None else (
                self._transition[1] if self._transition is not None else c)
            if not same(target, drawn):
                if self._exploring is not None or self._transition is not None:
                    self._last_explore = self.frames
                self._transition = None
                self._exploring = None
                self._pending = (None, 0)
                self.incumbent = target
                self.pullbacks += 1
                return Decision(target, None, 0.0, "pullback", target, thr)

        def allowed(p):  # under a budget: a plan that fits it, or one surely cheaper than the incumbent
            return limit is None or self.high[p] <= limit or self.high[p] < min(self.high[c], st[c][0])
        # a transition in progress runs to its end
        if self._transition is not None:
            a, b, r, kind, n = self._transition
            if b not in st or a not in st or same(a, b):
                self._transition = None
            else:
                r += 1
                self._transition[2] = r
                if r >= n:
                    self._transition = None
                if kind != "transition":
                    self.explored += 1
                return Decision(b, a, r / (n + 1), kind, c, thr)
        if self._exploring is not None:
            e, left = self._exploring
            if e not in st:
                self._exploring = None
            elif left > 0:
                self._exploring[1] -= 1
                self.explored += 1
                return Decision(e, None, 0.0, "explore", c, thr)
            else:  # measured: keep it only if the hysteresis rule prefers it now, or what was measured does
                self._exploring = None
                self._last_explore = self.frames
                if gain(e, c) > threshold(e, c) or self._measured_gain(e, c, fit):
                    self.incumbent = e
                    self.switches += 1
                    return Decision(e, None, 0.0, "switch", e, None)
                return self._start(e, c, "return", thr)  # (counted as explored when it fades)
        # steady: the hysteresis rule
        cand = [p for p in others if gain(p, c) > threshold(p, c) and allowed(p)]
        if cand:
            b = max(cand, key=lambda p: gain(p, c))
            n = self._pending[1] + 1 if self._pending[0] == b else 1
            self._pending = (b, n)
            if n >= PERSIST:
                self._pending = (None, 0)
                self.incumbent = b
                self.switches += 1
                return self._start(c, b, "switch", thr)
            return Decision(c, None, 0.0, "pending", c, thr)
        self._pending = (None, 0)
        # exploration: a plan whose lower bound undercuts the incumbent, within the budget
        if self.explore and others:
            cost = 2 * self._fade_frames("explore") + EXPLORE_RUN
            budget = EXPLORE_FRACTION * self.frames + EXPLORE_ALLOWANCE
            if (self.explored + cost <= budget and self.frames - self._last_explore >= EXPLORE_GAP
                    and st[c][1] >= EXPLORE_AFTER):  # the incumbent measured first: the comparison needs it
                ok = [p for p in others if self.last[p][2] < st[c][0] * (1.0 - MIN_GAIN)
                      and self.frames - self._tried.get(p, -10 ** 9) >= EXPLORE_COOLDOWN
                      and (limit is None or self.high[p] <= limit)]
                if ok:
                    e = min(ok, key=lambda p: self.last[p][2])
                    self._tried[e] = self.frames
                    self.explorations += 1
                    self._exploring = [e, EXPLORE_RUN]
                    self._warm = 0
                    self.explored += 1
                    return self._start(c, e, "explore", thr)
        return Decision(c, None, 0.0, "steady", c, thr)

    def veto(self, dec: Decision, seconds: float) -> Decision | None:
        """Under a budget, a change (exploration or switch) to a plan that was priced optimistically (a
        candidate's cost lower bound) and whose exact price ``seconds`` passes the budget pessimistically is
        undone: the plan drawn before stays (the plan is not tried again for :data:`EXPLORE_COOLDOWN` frames).
        Returns that decision, or None when the change stands."""
        if self.budget is None or dec.state not in ("explore", "switch") or self._before is None:
            return None
        if self._high(dec.plan, float(seconds), dec.plan in self._z) <= self.budget:
            return None
        self._transition = None
        self._exploring = None
        self._pending = (None, 0)
        self._tried[dec.plan] = self.frames
        self._last_explore = self.frames
        self.incumbent = self._before
        return Decision(self._before, None, 0.0, "veto", self._before, dec.threshold)

    def _fade_frames(self, state: str) -> int:
        """Frames of a transition: ``switch_frames``, at most :data:`EXPLORE_FADE` to and from an exploration."""
        n = max(0, int(self.switch_frames))
        return min(n, EXPLORE_FADE) if state in ("explore", "return") else n

    def _start(self, a: str, b: str, state: str, thr) -> Decision:
        """First frame of the change from plan a to plan b (a transition when ``switch_frames`` > 0; under a
        budget only when both plans drawn together fit it pessimistically: a fade draws the changed instances
        in both, and the office's fades to and from its explorations drew 160-360 ms frames under 70)."""
        n = self._fade_frames(state)
        if (self.budget is not None and a in self.high and b in self.high
                and self.high[a] + self.high[b] > self.budget):
            n = 0
        if n <= 0:
            if state == "explore":
                self._exploring[1] -= 1
            return Decision(b, None, 0.0, state, self.incumbent, thr)
        if state == "return":
            self.explored += 1  # a fade back draws the explored plan too
        self._transition = [a, b, 1, "transition" if state == "switch" else state, n] if n > 1 else None
        return Decision(b, a, 1.0 / (n + 1), state, self.incumbent, thr)

    def _measured_gain(self, e: str, c: str, fit) -> bool:
        """The explored plan ``e`` measured faster than the incumbent ``c`` beyond the noise: the median of its
        clean frames in this exploration more than :data:`MEASURED_GAIN_SD` robust standard deviations of the
        incumbent's own frame-to-frame spread (and at least :data:`MIN_GAIN`) below the median of the incumbent's
        last clean frames (at least 3, within :data:`MEASURED_AGE` frames). The measurements decide where the
        linear model cannot tell two plans apart (1,024 Foxes: triangles measured 73-77 ms against the point
        plan's 115-125, predicted 84 against 102, a gain under the hysteresis's 22 %: auto went back to points)."""
        se = [t for f, t in self._secs.get(e, ()) if self.frames - f <= EXPLORE_RUN + EXPLORE_WARM + 1]
        sc = [t for f, t in self._secs.get(c, ()) if self.frames - f <= MEASURED_AGE]
        if len(se) < EXPLORE_RUN or len(sc) < 3 or min(se + sc) <= 0.0:
            return False
        lc = np.log(np.asarray(sc))
        spread = 1.4826 * float(np.median(np.abs(lc - np.median(lc))))  # the incumbent's frame-to-frame noise
        gain = 1.0 - float(np.median(se)) / float(np.median(sc))
        return gain > max(MIN_GAIN, MEASURED_GAIN_SD * spread)

    def rename(self, old: str, new: str) -> None:
        """The steady incumbent ``old`` draws what plan ``new`` draws: it goes by ``new`` from now on (nothing
        happens during a transition, an exploration or a pending switch)."""
        if (self.incumbent == old and self._transition is None and self._exploring is None
                and self._pending[0] is None):
            self.incumbent = new

    def warm_frame(self) -> None:
        """The last frame's draw carried a one-time cost (:attr:`lod.drawlist.DrawList.warm_up`), so it measured
        nothing: an exploration running draws its plan for one more frame instead (at most :data:`EXPLORE_WARM`
        times per exploration)."""
        if self._exploring is not None and self._warm < EXPLORE_WARM:
            self._exploring[1] += 1
            self._warm += 1

    def can_hold(self) -> bool:
        """True when this frame may draw the incumbent without pricing the other plans: steady (no switch
        pending, no transition or exploration) and priced within the last :data:`REPRICE_FRAMES` frames."""
        return (self.incumbent is not None and self._transition is None and self._exploring is None
                and self._pending[0] is None and 0 < self._since < REPRICE_FRAMES and not self._overrun)

    def hold(self, content=None) -> Decision:
        """The decision of a held frame (:meth:`can_hold`): the incumbent, counted as a frame; ``content``: the
        incumbent's content this frame when it was priced (:attr:`lod.auto.plans._Plan.content`)."""
        if content is not None and self.incumbent is not None:
            self._content[self.incumbent] = np.asarray(content, np.float64)
        self.frames += 1
        self._since += 1
        return Decision(self.incumbent, None, 0.0, "held", self.incumbent, None)

    def summary(self) -> dict:
        return {"incumbent": self.incumbent, "frames": self.frames, "switches": self.switches,
                "explorations": self.explorations, "explored_frames": self.explored, "pullbacks": self.pullbacks}


__all__ = ["PlanChooser", "Decision", "PESSIMISM", "MEASURED_AGE", "OVERRUN", "MIN_GAIN", "K_SWITCH", "PERSIST", "SWITCH_FRAMES", "EXPLORE_RUN",
           "EXPLORE_FRACTION", "EXPLORE_ALLOWANCE", "EXPLORE_GAP", "EXPLORE_COOLDOWN", "UNMEASURED_SD"]
