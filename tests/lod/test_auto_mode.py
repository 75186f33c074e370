"""LOD mode "auto" (lod/auto_mode.py): cheapest level within the bound, equality with NoLOD at a
zero bound, every visible instance drawn once, the budget controller's convergence without
oscillation, telemetry, and a `crowd run` with the mode."""
import csv
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lod import auto_mode as am
from lod import cost_model, modes, nolod
from lod import triangles_mode as tm
from lod.view import Camera
from sim.procedural import humanoid

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
from image_checks import silhouette_error  # noqa: E402
from tiny_characters import tiny_keyframed  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SIZE = (320, 240)
MODEL = cost_model.CostModel()  # the defaults: independent of any stored calibration


@pytest.fixture(scope="module")
def char():
    return humanoid(1500, 0)


@pytest.fixture(scope="module")
def built(char):
    reps, sel = am.build([char], ["h"], [30], {"poe": 0.0}, cache=False, model=MODEL)
    full, fsel = nolod.build([char], ["h"], [30], {})
    return SimpleNamespace(rep=reps[0], reps=reps, sel=sel, full=full, fsel=fsel)


def _state(pos, heading, t):
    pos = np.asarray(pos, float).reshape(-1, 3)
    n = len(pos)
    return SimpleNamespace(n=n, character=np.zeros(n, np.int64), clip=np.zeros(n, np.int64),
                           anim_time=np.asarray(t, float), position=pos, scale=np.ones(n),
                           heading=np.asarray(heading, float))


def _crowd(n=80, seed=3, half_width=20.0, depth=80.0):
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(-half_width, half_width, n), np.zeros(n), rng.uniform(-depth, 5, n)])
    return _state(pos, rng.uniform(0, 6.3, n), rng.uniform(0, 2, n))


CAM = Camera.look_at((0, 1.6, 8.0), (0, 1.0, -10.0))


def test_registered_with_params():
    assert modes.MODES["auto"] == "lod.auto_mode"
    p = modes.mode_params("auto")
    assert p["poe"].default == 1.0 and p["budget_ms"].default == 0.0 and "levels" in p


def test_choose_cheapest_within_bound():
    cost = np.array([4.0, 2.0, 3.0, 1.0])  # not monotone: the choice is by cost, not by index
    err = np.array([[0.0, 0.5, 0.2, 3.0], [0.0, 5.0, 0.1, 9.0], [0.0, np.inf, np.inf, np.inf]])
    np.testing.assert_array_equal(am.choose(cost, err, 1.0), [1, 2, 0])
    np.testing.assert_array_equal(am.choose(cost, err, 10.0), [3, 3, 0])
    np.testing.assert_array_equal(am.choose(cost, err, 0.0), [0, 0, 0])
    assert am.choose(cost, np.zeros((0, 4)), 1.0).shape == (0,)


def test_projected_errors_match_triangles_rule(built):
    r = built.rep
    rng = np.random.default_rng(0)
    rel = np.column_stack([rng.uniform(-5, 5, 30), rng.uniform(-1, 0, 30), rng.uniform(-40, 0.5, 30)])
    rows = nolod.model_rows(rel, rng.uniform(0, 6, 30), np.full(30, 1.0)).astype(np.float64).reshape(-1, 3, 4)
    px = am.projected_errors(r.level_error, rows, r.clip_sphere[0], 300.0)
    assert px.shape == (30, r.n_levels) and not np.isnan(px).any()
    cost = MODEL.coefficients["triangles"] * r.level_count + MODEL.coefficients["instances"]
    for poe in (0.0, 0.7, 3.0, 50.0):  # costs fall along the chain: cheapest within = coarsest within
        np.testing.assert_array_equal(am.choose(cost, px, poe),
                                      tm.choose_levels(r.level_error, rows, r.clip_sphere[0], 300.0, poe))


def test_zero_bound_draws_exactly_what_nolod_draws(built):
    st = _crowd()
    built.sel.poe = 0.0
    dl = built.sel.select(st, CAM, SIZE)
    ref = built.fsel.select(st, CAM, SIZE)
    ids = np.concatenate([b.instance_ids for b in dl.batches])
    ref_ids = np.concatenate([b.instance_ids for b in ref.batches])
    np.testing.assert_array_equal(ids, ref_ids)
    assert dl.stats["triangles"] == ref.stats["triangles"] == dl.triangles
    assert all(b.level == 0 for b in dl.batches)
    for b, rb in zip(dl.batches, ref.batches):
        np.testing.assert_array_equal(b.instance_data, rb.instance_data)
    a = dl.stats["auto"]
    assert a["levels"][0] == ids.size and sum(a["levels"]) == ids.size and a["bound"] == 0.0
    assert a["predicted_ms"] == pytest.approx(1e3 * MODEL.predict(dl)) and a["budget_ms"] == 0.0


def test_every_visible_instance_drawn_once(built):
    st = _crowd(120, 7)
    ref = built.fsel.select(st, CAM, SIZE)
    ref_ids = np.sort(np.concatenate([b.instance_ids for b in ref.batches]))
    prev = None
    for poe in (0.0, 0.5, 2.0, 10.0, 1e3):
        built.sel.poe = poe
        dl = built.sel.select(st, CAM, SIZE)
        ids = np.concatenate([b.instance_ids for b in dl.batches])
        np.testing.assert_array_equal(np.sort(ids), ref_ids)  # none twice, none dropped
        assert sum(dl.stats["auto"]["levels"]) == ids.size == dl.stats["instances"]
        keys = [(b.rep, b.part, b.level) for b in dl.batches]
        assert len(set(keys)) == len(keys) and keys == sorted(keys)
        for b in dl.batches:
            assert b.index_range == (3 * built.rep.level_first[b.level], 3 * built.rep.level_count[b.level])
        p = dl.stats["auto"]["predicted_ms"]
        assert prev is None or p <= prev + 1e-12  # a looser bound never costs more
        prev = p
    assert dl.stats["auto"]["levels"][-1] > 0
    built.sel.poe = 0.0


def test_keyframed_character_at_full_detail(char):
    reps, sel = am.build([char, tiny_keyframed()], ["h", "flag"], [30, 30], {"poe": 5.0}, cache=False, model=MODEL)
    st = _crowd(40, 1)
    st.character = np.arange(40) % 2
    dl = sel.select(st, CAM, SIZE)
    kf = [b for b in dl.batches if b.rep == "triangles:flag"]
    assert kf and all(b.level == 0 for b in kf)
    assert sum(dl.stats["auto"]["levels"]) == dl.stats["instances"]


def test_bad_params():
    with pytest.raises(ValueError, match="poe"):
        am.AutoSelector([], poe=float("nan"), model=MODEL)
    with pytest.raises(ValueError, match="budget_ms"):
        am.AutoSelector([], budget_ms=-1.0, model=MODEL)
    with pytest.raises(ValueError, match="budget_ms"):
        am.BudgetController(float("inf"))


# ------------------------------------------------------------------------------------------ budget
def _run_budget(sel, st, frames=50, measured=None):
    bounds, costs = [], []
    for _ in range(frames):
        dl = sel.select(st, CAM, SIZE)
        bounds.append(dl.stats["auto"]["bound"])
        costs.append(dl.stats["auto"]["predicted_ms"])
        if measured is not None:
            sel.observe(measured(dl))
    return np.array(bounds), np.array(costs)


def test_budget_converges_without_oscillation(built):
    """Over a sweep of budgets between the coarsest and the full-detail cost, on a static view with
    measured cost = predicted cost, the bound settles within 50 frames and then never changes."""
    st = _crowd(150, 11, depth=60.0)
    full_ms = 1e3 * MODEL.predict(built.fsel.select(st, CAM, SIZE))
    coarse = am.AutoSelector(built.reps, poe=1e3, model=MODEL)
    floor_ms = coarse.select(st, CAM, SIZE).stats["auto"]["predicted_ms"]
    assert full_ms > 3 * floor_ms
    for factor in np.linspace(0.02, 0.98, 12):
        budget = floor_ms + factor * (full_ms - floor_ms)
        sel = am.AutoSelector(built.reps, poe=1.0, budget_ms=budget, model=MODEL)
        bounds, costs = _run_budget(sel, st)
        tail = bounds[-15:]
        assert np.all(tail == tail[0]), (factor, bounds)  # settled: no change over the last 15 frames
        assert costs[-1] <= budget * (1 + am.UP_TOLERANCE) + 1e-9, (factor, costs[-1], budget)
        assert am.BOUND_MIN <= tail[0] <= am.BOUND_MAX and np.isfinite(costs).all()


def test_budget_with_measured_cost_and_extremes(built):
    st = _crowd(150, 11, depth=60.0)
    # measured = predicted, reported through observe(): same convergence
    sel = am.AutoSelector(built.reps, poe=1.0, budget_ms=3.0, model=MODEL)
    bounds, _ = _run_budget(sel, st, measured=MODEL.predict)
    assert np.all(bounds[-15:] == bounds[-1])
    # a huge budget refines to the smallest bound and stays; an impossible one coarsens to the largest
    sel = am.AutoSelector(built.reps, poe=4.0, budget_ms=1e4, model=MODEL)
    bounds, _ = _run_budget(sel, st, frames=60)
    assert bounds[-1] == am.BOUND_MIN and np.all(bounds[-5:] == bounds[-1])
    sel = am.AutoSelector(built.reps, poe=4.0, budget_ms=1e-3, model=MODEL)
    bounds, _ = _run_budget(sel, st, frames=60)
    assert bounds[-1] == am.BOUND_MAX and np.all(bounds[-5:] == bounds[-1])


def test_controller_holds_when_cost_jumps_across_the_band():
    c = am.BudgetController(1.0, bound=1.0)
    cost = (lambda b: 2.0 if b < 3.0 else 0.5)  # a step from far above to far below the band
    seen = []
    for _ in range(60):
        seen.append(c.update(cost(c.bound)))
    assert seen[-1] >= 3.0 and len(set(seen[-20:])) == 1  # kept the under-budget bound, no flip-flop
    c.update(5.0)  # the view changed: released and coarsening again
    assert c.bound > seen[-1]


# ------------------------------------------------------------------------------------------ crowd run
SCENE = """\
name = "tiny"
seed = 1
dt = 0.05
frames = 3
effects = ["animation"]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "grid"
character = "walker"
rows = 2
cols = 2
spacing = [1.5, 1.5]

[camera]
position = [1.0, 2.0, 30.0]
target = [1.0, 0.8, 1.0]

[render]
size = [64, 48]
png_every = 1

[lod]
mode = "auto"
poe = 1.0
budget_ms = %s
levels = 5
"""


@pytest.mark.parametrize("budget", ["0.0", "50.0"])
def test_crowd_run_with_mode_auto(tmp_path, budget):
    scene = tmp_path / "tiny.toml"
    scene.write_text(SCENE % budget)
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["CROWD_CACHE_DIR"] = str(tmp_path / "cache")
    p = subprocess.run([sys.executable, "-m", "crowd", "run", str(scene), "--out", str(tmp_path / "out"), "--quiet"],
                       capture_output=True, text=True, cwd=REPO, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    rows = list(csv.DictReader(open(tmp_path / "out" / "frames.csv")))
    assert len(rows) == 3
    tri = [int(float(r["triangles"])) for r in rows]
    assert all(0 < t < 4 * 600 for t in tri), tri  # far away: coarser than full detail


# ------------------------------------------------------------------------------------------ rendering
BG = (0.1, 0.1, 0.12)


@pytest.fixture(scope="module")
def gl(built):
    from render.context import create_context
    from render.renderer import Renderer
    ctx = create_context()
    rs = {}
    for ss in (1, 4):
        r = Renderer((SIZE[0] * ss, SIZE[1] * ss), ctx=ctx)
        for rep in [built.rep, *built.full]:
            r.upload(rep)
        rs[ss] = r
    yield rs
    for r in rs.values():
        r.release()
    ctx.release()


def _mask(img):
    bg = np.round(np.asarray(BG) * 255).astype(int)
    return np.abs(img.astype(int) - bg).max(axis=2) > 2


def _draw(r, dl):
    r.draw(dl, background=BG)
    return r.read_pixels()


def test_zero_bound_is_pixel_identical_to_nolod(built, gl):
    st = _crowd(30, 5, half_width=5.0, depth=25.0)
    built.sel.poe = 0.0
    ref_dl = built.fsel.select(st, CAM, SIZE)
    ref, img = _draw(gl[1], ref_dl), _draw(gl[1], built.sel.select(st, CAM, SIZE))
    assert _mask(ref).sum() > 1000 and np.array_equal(img, ref)
    built.sel.poe = 50.0
    dl = built.sel.select(st, CAM, SIZE)
    assert dl.stats["triangles"] < ref_dl.stats["triangles"] and not np.array_equal(_draw(gl[1], dl), ref)
    built.sel.poe = 0.0


@pytest.mark.parametrize("poe", [1.0, 3.0])
def test_silhouette_error_within_bound(built, gl, poe):
    """One instance at distances where the bound picks coarse levels: rendered at 4x the selection
    resolution, the chosen level's silhouette stays within ``poe`` (+1 pixel of rasterisation) of
    full detail's (the measure of tests/lod/test_triangles_mode.py)."""
    
    r = gl[4]
    sel = built.sel
    seen = set()
    for z, t, heading in ((-4.0, 0.3, 0.4), (-10.0, 0.9, 1.2), (-25.0, 0.1, 2.0), (-60.0, 0.6, 0.0)):
        st = _state([[0.0, 0.0, z]], [heading], [t])
        cam = Camera.look_at((0, 1.0, 3.0), (0, 0.9, z))
        sel.poe = 0.0
        full = _mask(_draw(r, sel.select(st, cam, SIZE)))
        sel.poe = poe
        dl = sel.select(st, cam, SIZE)
        (b,) = dl.batches
        seen.add(b.level)
        a = _mask(_draw(r, dl))
        err = silhouette_error(full, a) / 4.0
        assert err <= poe + 1.0, (z, b.level, err)
    sel.poe = 0.0
    assert max(seen) > 0


def test_controller_ignores_a_single_noisy_frame():
    c = am.BudgetController(0.050, bound=2.0)
    assert c.update(0.050) == 2.0 and c.update(0.040) == 2.0  # inside the band (-15 % .. +5 %)
    assert c.update(0.060) == 2.0  # one frame 20 % over: noise, no change
    assert c.update(0.050) == 2.0
    assert c.update(0.060) == 2.0 and c.update(0.060) > 2.0  # persisting: coarsen
    b = c.bound
    assert c.update(0.200) > b  # far over budget: at once
