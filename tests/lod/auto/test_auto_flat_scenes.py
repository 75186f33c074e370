"""Issue 26, item 2: selection on flat arrays chooses exactly what the per-group path chose, on every shipped
scene's first frames. Each scene is run as it is written (its characters' generators and clips, placements,
effects, camera, [lod] keys) in mode auto, made lean (characters capped at 500 triangles, point hierarchies
over 2 poses per clip, a few hundred agents, a 160 x 120 view), and every frame is selected twice, by the flat path (lod/auto/flat.py) and by the per-group
path it replaced (AutoSelector.flat = False); the plans, choices and draw lists must be the same."""
import dataclasses
from pathlib import Path

import pytest

from crowd.engine import Engine
from crowd.scene import load_scene
from lod.auto import flat_plans
from lod.auto import mode as am
from lod.points import mode as pm
from test_auto_flat import _same

SCENES = sorted((Path(__file__).resolve().parents[3] / "scenes").glob("*.toml"))
SIZE = (160, 120)


def _cap_level(level: dict) -> dict:
    out = {}
    for k, v in level.items():
        if isinstance(v, int) and not isinstance(v, bool) and k in ("rows", "seats_per_row", "nx", "nz", "count"):
            v = min(v, 3)
        elif k == "children" and isinstance(v, list):
            v = v[:3]
        out[k] = v
    return out


def lean(scene):
    """The scene with small characters, few agents, a small view, in mode auto."""
    chars = tuple(dataclasses.replace(c, triangles=min(c.triangles, 500)) if c.generator and c.triangles else c
                  for c in scene.characters)
    places = []
    for p in scene.placements:
        q = dict(p.params)
        if "count" in q:
            q["count"] = min(int(q["count"]), 150)
        for k in ("rows", "cols"):
            if k in q:
                q[k] = min(int(q[k]), 12)
        if "levels" in q:
            q["levels"] = [_cap_level(dict(lv)) for lv in q["levels"]]
        places.append(dataclasses.replace(p, params=q))
    params = tuple(dict(scene.lod_params if scene.lod_mode == "auto" else (), keyframes=2).items())
    s = dataclasses.replace(scene, characters=chars, placements=tuple(places), lod_mode="auto", lod_params=params)
    return s.with_overrides(size=SIZE)


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_flat_selection_chooses_what_the_per_group_path_chose(path, monkeypatch):
    priced = []
    orig = flat_plans.price
    monkeypatch.setattr(flat_plans, "price", lambda *a, **k: priced.append(1) or orig(*a, **k))
    # per-keyframe-pair point octrees (the flat point forest's; follow hierarchies are priced group by group:
    # test_auto_flat.py::test_follow_points_run_the_per_group_path)
    monkeypatch.setattr(pm, "animation_path", lambda ch, p: ("baked", "the flat path's octrees"))
    scene = lean(load_scene(path))
    eng = Engine(scene, quiet=True)
    sel = eng.selector
    assert isinstance(sel, am.AutoSelector)
    ref = am.AutoSelector(sel.reps, poe=sel.poe, budget_ms=sel.budget_ms, model=sel.prior, cull=sel.cull,
                          candidates=sel.candidates[1:], adapt=sel.adapt)
    ref.flat = False
    n_inst = 0
    for _ in range(2):
        eng.step()
        cam = eng.camera_at(eng.world.time)
        a = sel.select(eng.world.state, cam, SIZE)
        b = ref.select(eng.world.state, cam, SIZE)
        _same(a, b)
        n_inst += a.stats["instances"]
    assert n_inst > 0, f"{path.name}: nothing in view"
    assert len(priced) == 2, "the flat path was not taken"
    assert eng.world.state.n <= 2000
