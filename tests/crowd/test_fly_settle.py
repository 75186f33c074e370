"""crowd fly's frame budget on a machine the test defines: a scene too heavy for the budget in its own mode
settles under it in mode auto within :data:`SETTLE_FRAMES` frames, says so on the HUD, and says when no plan
can meet it; a scene that fits keeps its mode (issue 49's acceptance).

Nothing here is timed: each frame's cost is a fixed linear function of what it drew (:data:`MACHINE`, seconds per
count of :func:`lod.auto.cost_model.features`), reported to the fly-through in place of the measured seconds
(``Engine.observe``), with a fixed selection time. Auto's cost model starts from its prior and must learn this
machine from the frames, as it learns the real one; the budget's decisions see only these costs.
"""
import pytest
from crowd_testutil import tiny_scene

from crowd.engine import Engine
from crowd.fly import FlyApp
from crowd.scene import load_scene
from lod.auto.cost_model import ONLINE_FEATURES, features
from render.window import Window

SIZE = (320, 240)
#: the test's machine: seconds per frame and per count drawn (the hardware path's triangles dear, as on llvmpipe)
MACHINE = {"frame": 2e-3, "triangles": 150e-9, "points": 40e-9, "batches": 1e-4, "raster_triangles": 400e-9,
           "posed_vertices": 20e-9, "clusters": 2e-6}
#: the selection's seconds every frame
SELECT_S = 1e-3
#: frames after which every frame is within the budget
SETTLE_FRAMES = 10
FRAMES = 40


def machine_seconds(dl, scale: float) -> float:
    """Selection + rendering seconds of the frame that drew ``dl`` on the test's machine (slowed by ``scale``)."""
    x = features(dl, extended=True)
    return SELECT_S + scale * (MACHINE["frame"] + sum(MACHINE.get(k, 0.0) * v for k, v in zip(ONLINE_FEATURES, x)))


@pytest.fixture
def heavy(display, tmp_path):
    """fly(budget_ms, scale) -> (FlyApp after FRAMES frames, [(mode, ms) per frame]): 256 walkers at full detail
    in mode none (~62 ms a frame on the test's machine at scale 1), flown on the machine of ``scale``."""
    p = tmp_path / "heavy.toml"
    p.write_text(tiny_scene(replace={"rows = 2": "rows = 16", "cols = 2": "cols = 16",
                                     "size = [64, 48]": f"size = [{SIZE[0]}, {SIZE[1]}]",
                                     "position = [1.0, 2.0, 7.0]": "position = [12.0, 6.0, 40.0]",
                                     "target = [1.0, 0.8, 1.0]": "target = [12.0, 0.8, 12.0]"}))
    opened = []

    def fly(budget_ms: float, scale: float = 1.0):
        window = Window(SIZE, title="test_fly_settle")
        engine = Engine(load_scene(p), quiet=True)
        frames = []

        def observe(dl, select_seconds, timings):
            s = machine_seconds(dl, scale)
            dl.stats["gl_created"] = 0  # the test's machine has no one-time costs (lod.drawlist.DrawList.warm_up)
            sel = getattr(engine.selector, "inner", engine.selector)  # inside a keyframed selection
            if hasattr(sel, "observe"):
                sel.last_select_seconds = SELECT_S  # what the budget's rendering share is computed from
                sel.observe(s, select_seconds=SELECT_S, drawlist=dl)
            frames.append((engine.settings.lod_mode, 1e3 * s))
            return s

        engine.observe = observe
        app = FlyApp(engine, window, tmp_path / "fly-out", echo=lambda _: None, budget_ms=budget_ms)
        opened.append((app, window))
        for _ in range(FRAMES):
            app.frame(0.05)
        return app, frames

    yield fly
    for app, window in opened:
        app.close()
        window.close()


@pytest.mark.parametrize("budget_ms,scale", [(15.0, 1.0), (8.0, 1.0), (5.0, 1.0), (15.0, 0.5), (30.0, 2.0),
                                             (40.0, 4.0)])
def test_a_heavy_scene_settles_under_the_budget_in_auto(heavy, budget_ms, scale):
    app, frames = heavy(budget_ms, scale)
    assert frames[0] == ("none", pytest.approx(frames[0][1])) and frames[0][1] > 2.0 * budget_ms
    late = frames[SETTLE_FRAMES:]
    assert all(mode == "auto" for mode, _ in late)
    over = [(i + SETTLE_FRAMES, ms) for i, (_, ms) in enumerate(late) if ms > budget_ms]
    assert not over, f"frames over the {budget_ms} ms budget after {SETTLE_FRAMES}: {over}"
    hud = app.hud_lines()[0]
    assert f"budget {budget_ms:g} ms (auto in place of none)" in hud and "no plan fits" not in hud
    assert any("misses the" in m for m, _ in app.controller.messages)


def test_a_budget_no_plan_meets_draws_the_cheapest_and_says_so(heavy):
    app, frames = heavy(3.0)
    late = [ms for _, ms in frames[SETTLE_FRAMES:]]
    assert min(late) > 3.0  # nothing auto draws fits 3 ms on this machine
    assert max(late) <= 1.01 * min(ms for _, ms in frames)  # and it draws the cheapest it found
    assert "no plan fits: the cheapest" in app.hud_lines()[0]
    assert any("no plan of mode auto fits the 3 ms budget" in m for m, _ in app.controller.messages)


def test_a_scene_that_fits_the_budget_is_drawn_in_its_own_mode(heavy):
    app, frames = heavy(100.0)
    assert all(mode == "none" for mode, _ in frames) and max(ms for _, ms in frames) < 100.0
    hud = app.hud_lines()[0]
    assert "budget 100 ms" in hud and "auto" not in hud


def test_auto_s_representations_are_drawn_once_coarse_before_the_first_frame(display, tmp_path, monkeypatch):
    """With a budget, each of auto's representations (triangle chains, clusters, points) is drawn once before
    the first frame, coarse (its programs and buffers made then, not on the first frame a plan draws it:
    crowd.engine.Engine.warm_up); --budget 0 draws nothing extra."""
    p = tmp_path / "s.toml"
    p.write_text(tiny_scene(replace={"size = [64, 48]": f"size = [{SIZE[0]}, {SIZE[1]}]"}))
    for budget, want in ((70.0, {"triangles", "clusters", "points"}), (0.0, set())):
        window = Window(SIZE, title="test_fly_warm")
        engine = Engine(load_scene(p), quiet=True)
        app = FlyApp(engine, window, tmp_path / "fly-out", echo=lambda _: None, budget_ms=budget)
        drawn = []
        real = app.renderer.draw
        monkeypatch.setattr(app.renderer, "draw", lambda dl, *a, **k: (drawn.append(dl), real(dl, *a, **k))[1])
        try:
            app.frame(0.05)
        finally:
            app.close()
            window.close()
        warm = drawn[:-1]  # the last list is the frame's own
        kinds = {b.rep.split(":")[0] for dl in warm for b in dl.batches if b.n_instances}
        assert kinds >= want and len(warm) == len(want), (budget, kinds, len(warm))
        # coarse: no list draws more than the frame's own full detail
        assert all(dl.stats.get("triangles", 0) <= drawn[-1].stats.get("triangles", 0) for dl in warm)
