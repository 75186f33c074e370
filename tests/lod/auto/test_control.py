"""lod/auto/control.py: the plan decision of mode auto on synthetic frames (plans as fixed count vectors, the
machine as a known cost model with noise): no switching on alternating noisy measurements, a better plan found
by bounded exploration and kept, exploration within its budget and never on one frame, faded switches."""
import math

import numpy as np
import pytest

from lod.auto import control as ctl
from lod.auto import cost_model as cm
from lod.auto.online import OnlineCostModel

#: per-plan counts (cost_model.FEATURES order): a triangle-heavy plan and a point-heavy plan
PLANS = {
    "triangles": np.array([3e5, 0, 12, 800, 0, 0, 0, 0, 0], float),
    "points": np.array([2e4, 6e5, 6, 50, 0, 921600, 3686400, 750, 0], float),
    "mixed": np.array([1.5e5, 3e5, 10, 420, 0, 921600, 3686400, 380, 0], float),
}


def _run(chooser, fit, true, frames, noise=None, rng=None):
    """Drive ``chooser`` for ``frames`` frames; the machine's seconds are ``true.predict_counts(counts of the
    drawn plan, or the mean of both during a transition)`` times ``noise(frame)``. Returns the decisions."""
    out = []
    for f in range(frames):
        means = {p: fit.predict(x)[0] for p, x in PLANS.items()}
        d = chooser.choose(means, fit)
        x = PLANS[d.plan] if d.fade_from is None else PLANS[d.plan] + PLANS[d.fade_from]
        y = float(true.predict_counts(*x)) * (noise(f) if noise else 1.0)
        fit.update(x, y)
        if d.fade_from is None:
            chooser.observed(d.plan, fit.last_z, fit.last_u, True)
        out.append(d)
    return out


def _true(tri_factor=1.0, pts_factor=1.0):
    c = dict(cm.DEFAULTS)
    for k in ("triangles", "instances", "batches"):
        c[k] *= tri_factor
    for k in ("points", "splat_pixels", "splat_area", "point_instances"):
        c[k] *= pts_factor
    return cm.CostModel(c)


def _switches(ds):
    return sum(1 for a, b in zip(ds, ds[1:]) if a.incumbent != b.incumbent)


def test_alternating_noisy_measurements_do_not_switch():
    """The triangle and point plans cost the same; every other frame is measured 35 % slower (another process
    running in bursts). After its bounded exploration the incumbent never changes, and no plan is drawn
    for a single frame."""
    true = _true(pts_factor=1.0)
    m_tri = float(true.predict_counts(*PLANS["triangles"]))
    m_pts = float(true.predict_counts(*PLANS["points"]))
    true = _true(tri_factor=m_pts / m_tri)  # equal cost of the two pure plans
    fit = OnlineCostModel(cm.CostModel(key="calibrated"))
    ch = ctl.PlanChooser(switch_frames=4)
    ds = _run(ch, fit, true, 160, noise=lambda f: 1.35 if f % 2 else 1.0)
    assert _switches(ds[60:]) == 0, [(d.plan, d.state) for d in ds]
    runs, cur = [], None
    for d in ds:
        if d.plan != cur:
            runs.append(1)
            cur = d.plan
        else:
            runs[-1] += 1
    assert min(runs[:-1] or [99]) >= 2  # no plan drawn for one frame only
    assert ch.explored <= ctl.EXPLORE_FRACTION * len(ds) + ctl.EXPLORE_ALLOWANCE


def test_a_better_plan_is_explored_and_kept():
    """The calibration prices points 1.6x too dear, and they really cost 0.6x (against triangles: the 2.5x of
    the loaded calibration in scripts/bench_auto.md runs K-M): the mixed and point plans look worse than
    triangles. Bounded exploration tries a plan with points, the fit learns their costs, the
    chooser switches and stays; every switch is a faded transition of switch_frames frames (an exploration
    and its return are cuts)."""
    fit = OnlineCostModel(cm.CostModel(_true(pts_factor=1.6).coefficients, key="calibrated"))
    true = _true(pts_factor=0.6)
    ch = ctl.PlanChooser(switch_frames=3)
    ds = _run(ch, fit, true, 90, noise=lambda f: 1.0 + 0.05 * np.sin(1.7 * f))
    assert ds[0].plan == "triangles"
    assert ds[-1].incumbent in ("points", "mixed") and _switches(ds[40:]) == 0
    best = min(float(true.predict_counts(*x)) for x in PLANS.values())
    assert float(true.predict_counts(*PLANS[ds[-1].plan])) == pytest.approx(best)
    changes = [i for i in range(1, len(ds)) if ds[i].plan != ds[i - 1].plan]
    for i in changes:  # every change fades in over switch_frames frames (explorations: at most 2), t rising
        n = min(3, ctl.EXPLORE_FADE) if ds[i].state in ("explore", "return") else 3
        assert [ds[i + r].fade_from for r in range(n)] == [ds[i - 1].plan] * n
        assert [ds[i + r].t for r in range(n)] == pytest.approx([(r + 1) / (n + 1) for r in range(n)])
    assert ch.explorations >= 1 and ch.explored <= ctl.EXPLORE_FRACTION * 90 + ctl.EXPLORE_ALLOWANCE


def test_an_exploration_is_a_cut_measured_on_frames_without_warm_ups():
    """Issue 50, item 3: an exploration draws its plan alone (no fade drawing both plans), for EXPLORE_RUN frames
    plus one for each of its frames whose draw carried a one-time cost (a warm-up: the fit did not take it), at
    most EXPLORE_WARM more; the cut back draws the incumbent and is not counted as explored. The setting of
    test_a_better_plan_is_explored_and_kept (points priced too dear: explored)."""
    fit = OnlineCostModel(cm.CostModel(_true(pts_factor=1.6).coefficients, key="calibrated"))
    true = _true(pts_factor=0.6)
    ch = ctl.PlanChooser(switch_frames=3)
    ds, warm = [], 0
    for f in range(90):
        means = {p: fit.predict(x)[0] for p, x in PLANS.items()}
        d = ch.choose(means, fit)
        ds.append(d)
        if d.state == "explore" and ds[-2].state != "explore" and warm < 1:  # the first explored frame compiles
            warm += 1
            ch.warm_frame()
            continue
        x = PLANS[d.plan] if d.fade_from is None else PLANS[d.plan] + PLANS[d.fade_from]
        fit.update(x, float(true.predict_counts(*x)))
        if d.fade_from is None:
            ch.observed(d.plan, fit.last_z, fit.last_u, True)
    runs, cur = [], None
    for i, d in enumerate(ds):
        if d.state == "explore":
            assert d.fade_from is None and d.plan != d.incumbent
            if cur is None or i != cur[1] + 1:
                cur = [i, i]
                runs.append(cur)
            cur[1] = i
    assert ch.explorations == len(runs) >= 1 and warm == 1
    assert runs[0][1] - runs[0][0] + 1 == ctl.EXPLORE_RUN + 1  # one more frame for the warm-up
    assert all(b - a + 1 == ctl.EXPLORE_RUN for a, b in runs[1:])
    assert ch.explored == sum(b - a + 1 for a, b in runs)  # the returns (cuts) not counted
    assert all(d.fade_from is None for d in ds if d.state == "return")


def _hidden_saving(hidden: float, measured_rule: bool = True):
    """Decisions of 20 frames where the triangle plan's frames cost ``hidden`` times what the linear model of their
    counts says (a cost the counts do not carry, as the Foxes' pose work): points, priced right, are the incumbent
    for 6 frames (exploration off), then triangles are explored; every frame is reported to the chooser."""
    true = _true(pts_factor=0.6)
    fit = OnlineCostModel(cm.CostModel(true.coefficients, key="calibrated"))
    ch = ctl.PlanChooser(switch_frames=0)
    ch.explore = False
    if not measured_rule:
        ch._measured_gain = lambda *a: False
    out = []
    for f in range(20):
        ch.explore = f >= 6
        d = ch.choose({p: fit.predict(x)[0] for p, x in PLANS.items()}, fit)
        x = PLANS[d.plan]
        y = float(true.predict_counts(*x)) * (hidden if d.plan == "triangles" else 1.0) * (1.0 + 0.05 * np.sin(2.3 * f))
        fit.update(x, y)
        ch.observed(d.plan, fit.last_z, fit.last_u, True)
        ch.measured([d.plan], y, True)
        out.append(d)
    return out


def test_an_exploration_measured_faster_is_kept():
    """The triangle plan measures 40 % under what its counts predict: at the end of its exploration its frames are
    faster than the incumbent's beyond the incumbent's frame-to-frame spread, and it is kept at once (the 1,024
    Foxes: triangles measured 73-77 ms against the point plan's 115-125, predicted 84 against 102, and auto went
    back to points). On predictions alone the same run goes back first (the rule can fail); a plan measured no
    faster is not kept."""
    def after_exploring(ds):
        i = next(i for i, d in enumerate(ds) if d.state == "explore")
        j = next(j for j in range(i, len(ds)) if ds[j].state != "explore")
        return ds[i].plan, ds[j]

    plan, d = after_exploring(_hidden_saving(0.6))
    assert plan == "triangles" and d.state == "switch" and d.plan == "triangles"
    plan, d = after_exploring(_hidden_saving(0.6, measured_rule=False))
    assert plan == "triangles" and d.state == "return" and d.plan == "points"
    plan, d = after_exploring(_hidden_saving(1.0))
    assert plan == "triangles" and d.state == "return"


def test_exploration_is_bounded_and_waits_for_the_incumbent():
    """A plan that stays uncertain (never drawn: its lower bound always undercuts) is explored at most once per
    cooldown, never before the incumbent has been measured, and exploring takes at most the budgeted share;
    without ``explore`` nothing is tried."""
    fit = OnlineCostModel(cm.CostModel(key="calibrated"))
    true = _true()
    ch = ctl.PlanChooser(switch_frames=2)
    ds = _run(ch, fit, true, 300)
    starts = [i for i, d in enumerate(ds) if d.state == "explore" and (i == 0 or ds[i - 1].state != "explore")]
    assert starts and starts[0] >= ctl.EXPLORE_AFTER
    assert ch.explored <= ctl.EXPLORE_FRACTION * 300 + ctl.EXPLORE_ALLOWANCE
    tried = {}
    for i in starts:
        p = ds[i].plan
        assert i - tried.get(p, -10 ** 9) >= ctl.EXPLORE_COOLDOWN
        tried[p] = i
    assert all(b - a >= ctl.EXPLORE_GAP for a, b in zip(starts, starts[1:]))
    quiet = ctl.PlanChooser(switch_frames=2, explore=False)
    ds = _run(quiet, OnlineCostModel(cm.CostModel(key="calibrated")), true, 60)
    assert quiet.explorations == 0 and all(d.state in ("steady", "pending") for d in ds)


def test_plans_that_draw_the_same_are_one_plan():
    """Two names that draw the same (the mixed plan equal to the point plan) are not a switch or an
    exploration target; with switch_frames 0 a switch is immediate (no fade)."""
    fit = OnlineCostModel(cm.CostModel(key="calibrated"))
    ch = ctl.PlanChooser(switch_frames=0)
    for _ in range(20):
        d = ch.choose({"points": 0.010, "mixed": 0.010, "triangles": 0.030}, fit,
                      equal=lambda a, b: {a, b} == {"points", "mixed"} or a == b)
        assert d.fade_from is None and d.plan in ("points", "mixed") and d.state == "steady"


def test_a_plan_whose_content_changes_does_not_keep_the_old_content_s_bias():
    """Issue 50, item 2 (bias by content): the mixed plan draws what the point plan draws (content: all of its
    seconds on points) and six clean frames of it measure 2x what the fit predicts (a bias the linear model
    misses). Both names carry that bias. Then the mixed plan's content changes (mostly triangles): its bias is
    gone, until frames of its new content are measured; the point plan keeps it; a third name drawing the
    measured content gets it without ever being drawn. Keyed by names (no content given, as before), the mixed
    plan kept the points' bias after its content changed: the check the content rule passes."""
    fit = OnlineCostModel(cm.CostModel(key="calibrated"))
    pts, tri, mostly_tri = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.85, 0.0, 0.15])
    means = {"points": 0.010, "mixed": 0.010, "triangles": 0.030}
    z = fit.row(PLANS["points"])
    u = z / (2.0 * fit.predict(PLANS["points"])[0])  # measured: twice the prediction
    by_content = ctl.PlanChooser(switch_frames=0, explore=False)
    by_name = ctl.PlanChooser(switch_frames=0, explore=False)
    for _ in range(6):
        by_content.choose(means, fit, content={"points": pts, "mixed": pts, "triangles": tri})
        by_content.observed(["points", "mixed"], z, u, True)
        by_name.choose(means, fit)
        by_name.observed(["points", "mixed"], z, u, True)
    expect = math.log(2.0) * 6 / (6 + ctl.BIAS_SHRINK)
    for ch in (by_content, by_name):
        assert ch.bias("points", fit) == pytest.approx((expect, 6))
        assert ch.bias("mixed", fit) == pytest.approx((expect, 6))
    by_content.choose(means, fit, content={"points": pts, "mixed": mostly_tri, "triangles": tri, "other": pts})
    by_name.choose(means, fit)
    assert by_content.bias("mixed", fit) == (0.0, 0)  # the new content was never measured
    assert by_content.bias("points", fit) == pytest.approx((expect, 6))
    assert by_content.bias("other", fit) == pytest.approx((expect, 6))  # what it draws was measured
    assert by_name.bias("mixed", fit) == pytest.approx((expect, 6))  # the name kept the old content's bias
    by_content.observed("mixed", z, z / fit.predict(PLANS["points"])[0], True)  # a frame of the new content
    assert by_content.bias("mixed", fit) == pytest.approx((0.0, 1), abs=1e-12)
    assert by_content.bias("points", fit) == pytest.approx((expect, 6))


# -- under a frame budget (issue 49) -----------------------------------------------------------------------------------


def _run_budget(chooser, fit, true, frames, budget, slow=None):
    """As :func:`_run` with ``chooser.budget`` set and every frame's seconds reported (``chooser.measured``);
    ``slow(frame, decision)``: a factor on the machine's seconds. Returns [(decision, seconds)]."""
    out = []
    for f in range(frames):
        chooser.budget = budget
        means = {p: fit.predict(x)[0] for p, x in PLANS.items()}
        d = chooser.choose(means, fit)
        x = PLANS[d.plan] if d.fade_from is None else PLANS[d.plan] + PLANS[d.fade_from]
        y = float(true.predict_counts(*x)) * (slow(f, d) if slow else 1.0)
        fit.update(x, y)
        if d.fade_from is None:
            chooser.observed(d.plan, fit.last_z, fit.last_u, True)
        chooser.measured([d.plan] if d.fade_from is None else [d.plan, d.fade_from], y, d.fade_from is None)
        out.append((d, y))
    return out


def _prior_pts_dear():
    """The setting of test_a_better_plan_is_explored_and_kept: points priced 1.6x, really 0.6x."""
    return OnlineCostModel(cm.CostModel(_true(pts_factor=1.6).coefficients, key="calibrated")), _true(pts_factor=0.6)


def test_under_a_budget_nothing_passing_it_pessimistically_is_tried():
    """The points look too dear to fit a budget the triangles fit (pessimistically: never drawn, their
    prediction times UNMEASURED_FACTOR): they are never explored, so no frame passes the budget -- where
    without a budget (test_a_better_plan_is_explored_and_kept) the same setting explores them."""
    fit, true = _prior_pts_dear()
    tri = float(fit.predict(PLANS["triangles"])[0])
    budget = ctl.PESSIMISM * tri * 1.05
    assert all(float(fit.predict(PLANS[p])[0]) * ctl.UNMEASURED_FACTOR > budget for p in ("points", "mixed"))
    ch = ctl.PlanChooser(switch_frames=3)
    out = _run_budget(ch, fit, true, 90, budget)
    assert {d.plan for d, _ in out} == {"triangles"} and ch.explorations == 0 and not ch.unmeetable
    assert max(y for _, y in out) <= budget
    free = ctl.PlanChooser(switch_frames=3)
    fit, true = _prior_pts_dear()
    assert {d.plan for d, _ in _run_budget(free, fit, true, 90, None)} != {"triangles"}  # the test can fail


def test_a_frame_far_over_the_budget_pulls_back_at_once():
    """From frame 30 the drawn triangles cost 6x (a view the model misprices): the next frame draws the plan of
    lowest pessimistic cost, another one, without a fade, and no later frame passes OVERRUN x the budget twice
    in a row. (At 3x the triangles, measured, stay below the others' pessimistic cost: they are kept.)"""
    fit, true = _prior_pts_dear()
    budget = ctl.PESSIMISM * float(fit.predict(PLANS["triangles"])[0]) * 1.05
    ch = ctl.PlanChooser(switch_frames=3)
    out = _run_budget(ch, fit, true, 80, budget, slow=lambda f, d: 6.0 if f >= 30 and "triangles" in
                      (d.plan, d.fade_from) else 1.0)
    assert out[30][1] > ctl.OVERRUN * budget
    d31 = out[31][0]
    assert d31.state == "pullback" and d31.plan != "triangles" and d31.fade_from is None and ch.pullbacks >= 1
    over = [y > ctl.OVERRUN * budget for _, y in out[31:]]
    assert not any(a and b for a, b in zip(over, over[1:]))


def test_a_budget_no_plan_can_meet_is_said_and_the_cheapest_is_drawn():
    fit = OnlineCostModel(cm.CostModel(key="calibrated"))
    ch = ctl.PlanChooser(switch_frames=2)
    out = _run_budget(ch, fit, _true(), 40, 1e-4)
    assert ch.unmeetable and ch.explorations == 0
    cheapest = min(PLANS, key=lambda p: float(_true().predict_counts(*PLANS[p])))
    assert out[-1][0].plan == cheapest


def test_under_a_budget_a_change_fades_only_when_both_plans_fit_together(monkeypatch):
    """A fade draws the changed instances in both plans. With a budget that every plan fits alone, even
    priced pessimistically as never drawn, but no two together, the explorations and their returns happen at
    once, where without a budget the same run fades (the rule can fail). Explorations are cuts by default
    (EXPLORE_FADE = 0); faded ones, as a switch fades, are what the rule is checked on."""
    monkeypatch.setattr(ctl, "EXPLORE_FADE", 2)
    def setting():
        true = _true(pts_factor=0.6)
        return OnlineCostModel(cm.CostModel(true.coefficients, key="calibrated")), true

    fit, true = setting()
    pred = sorted(float(fit.predict(x)[0]) for x in PLANS.values())
    budget = 1.01 * ctl.UNMEASURED_FACTOR * pred[-1]
    assert ctl.PESSIMISM * (pred[0] + pred[1]) > budget  # no two fit together, even measured
    ch = ctl.PlanChooser(switch_frames=3)
    out = _run_budget(ch, fit, true, 120, budget)
    assert ch.explorations >= 2 and all(d.fade_from is None for d, _ in out)
    assert max(y for _, y in out) <= budget
    free = ctl.PlanChooser(switch_frames=3)
    fit, true = setting()
    assert any(d.fade_from is not None for d, _ in _run_budget(free, fit, true, 120, None))


def test_a_pullback_goes_to_a_plan_priced_within_the_budget_now(monkeypatch):
    """Triangles and mixed were explored and measured within the budget; from frame 30 the points drawn cost 6x
    and the triangles' content grows 4x (a plan's content follows the bound, its name stays): the pullback goes
    to mixed, not to the triangles their old measurement names the cheapest."""
    true = _true(pts_factor=0.6)
    fit = OnlineCostModel(cm.CostModel(true.coefficients, key="calibrated"))
    budget = 1.01 * ctl.UNMEASURED_FACTOR * max(float(fit.predict(x)[0]) for x in PLANS.values())
    ch = ctl.PlanChooser(switch_frames=3)
    out = _run_budget(ch, fit, true, 30, budget)
    assert out[-1][0].incumbent == "points" and {d.plan for d, _ in out} >= {"triangles", "mixed"}
    monkeypatch.setitem(PLANS, "triangles", PLANS["triangles"] * 4.0)
    assert ctl.PESSIMISM * float(fit.predict(PLANS["triangles"])[0]) > budget
    out = _run_budget(ch, fit, true, 3, budget, slow=lambda f, d: 6.0 if d.plan == "points" else 1.0)
    d = next(d for d, _ in out if d.state == "pullback")
    assert d.plan == "mixed"


def test_a_steady_incumbent_drawing_a_pure_plan_goes_by_its_name():
    """The mixed plan that settled on one representation draws what the pure plan draws: renamed, it can be held
    and delegated to the single mode's selector (lod.auto.mode); never during an exploration."""
    fit = OnlineCostModel(cm.CostModel(key="calibrated"))
    ch = ctl.PlanChooser(switch_frames=0)
    d = ch.choose({"mixed": 0.010, "triangles": 0.011, "points": 0.030}, fit)
    assert d.incumbent == "mixed"
    ch.rename("mixed", "triangles")
    assert ch.incumbent == "triangles"
    ch._exploring = ["points", 1]
    ch.rename("triangles", "mixed")
    assert ch.incumbent == "triangles"
