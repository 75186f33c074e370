"""sim.placement: schemas, the kinds, concat_states (kind trajectories: tests/sim/test_replay.py)."""
import math
import os

import numpy as np
import pytest

from sim.params import ParamError, validate
from sim.placement import PLACEMENTS, concat_states
from sim.state import CrowdState


def build(table, ci=2, clip=1, seed=0, dur=None):
    schema, fn = PLACEMENTS[table["kind"]]
    cfg = validate(schema, table, "placement[0]")
    st = fn(cfg, ci, clip, np.random.default_rng(seed), clip_duration=dur)
    st.check_finite()
    return st


def test_every_kind_has_common_keys_and_defaults():
    for kind, (schema, fn) in PLACEMENTS.items():
        for key in ("kind", "character", "clip", "heading", "phase", "scale", "scale_jitter"):
            if key == "heading" and kind == "trajectories":  # recorded people face where they walk (sim.replay)
                assert key not in schema and "speed" not in schema
                continue
            assert key in schema, (kind, key)
        assert schema["character"].required and not schema["clip"].required
        assert schema["clip"].default == ""


def test_grid_positions_heading_scale():
    st = build({"kind": "grid", "character": "w", "rows": 3, "cols": 4, "spacing": [2.0, 3.0],
                "origin": [1.0, 0.5, -1.0], "heading": 90.0, "phase": "zero", "scale": 1.5, "speed": 2.0})
    assert st.n == 12
    np.testing.assert_allclose(st.position[5], [1.0 + 2.0, 0.5, -1.0 + 3.0])  # row 1, col 1
    np.testing.assert_allclose(st.heading, math.pi / 2)
    np.testing.assert_allclose(st.velocity[:, 0], 2.0)
    np.testing.assert_allclose(st.velocity[:, 2], 0.0, atol=1e-12)
    assert (st.scale == np.float32(1.5)).all() and (st.anim_time == 0).all()
    assert (st.character == 2).all() and (st.clip == 1).all()
    assert st.position.dtype == np.float64 and st.clip.dtype == np.int16


def test_random_heading_phase_and_scale_jitter_are_seeded():
    t = {"kind": "grid", "character": "w", "rows": 10, "cols": 10, "heading": "random", "phase": "random",
         "scale_jitter": 0.2}
    a, b, c = build(t, seed=1, dur=1.2), build(t, seed=1, dur=1.2), build(t, seed=2, dur=1.2)
    assert a.digest() == b.digest() != c.digest()
    assert np.abs(a.heading).max() <= math.pi and a.heading.std() > 1.0
    assert (a.anim_time >= 0).all() and (a.anim_time < 1.2).all()
    assert a.scale.min() >= 0.8 - 1e-6 and a.scale.max() <= 1.2 + 1e-6


def test_heading_rejects_other_strings():
    with pytest.raises(ParamError, match="heading"):
        build({"kind": "grid", "character": "w", "rows": 1, "cols": 1, "heading": "north"})
    with pytest.raises(ParamError, match="rows"):
        build({"kind": "grid", "character": "w", "rows": 0, "cols": 1})
    with pytest.raises(ParamError, match="character"):
        build({"kind": "grid", "rows": 1, "cols": 1})


def test_list_and_random():
    st = build({"kind": "list", "character": "w", "positions": [[0, 0, 0], [1, 2, 3]], "headings": [0, 180]})
    np.testing.assert_allclose(st.position[1], [1, 2, 3])
    assert abs(st.heading[1]) == pytest.approx(math.pi)
    with pytest.raises(ParamError, match="headings"):
        build({"kind": "list", "character": "w", "positions": [[0, 0, 0]], "headings": [0, 1]})
    with pytest.raises(ParamError, match="positions"):
        build({"kind": "list", "character": "w", "positions": [[0, 0]]})
    st = build({"kind": "random", "character": "w", "count": 200, "center": [100, 0, 50], "size": [40, 40],
                "min_distance": 1.5})
    assert st.n == 200
    assert np.abs(st.position[:, 0] - 100).max() <= 20 and np.abs(st.position[:, 2] - 50).max() <= 20
    p = st.position[:, [0, 2]]
    d = np.sqrt(((p[:, None] - p[None]) ** 2).sum(-1)) + np.eye(200) * 1e9
    assert d.min() >= 1.5


def test_hierarchy_placement_and_concat_keeps_hierarchies():
    t = {"kind": "hierarchy", "character": "w", "phase": "zero",
         "levels": [{"layout": "grid", "nx": 2, "nz": 2, "spacing": [1, 1], "phase_step": 0.25},
                    {"layout": "tiers", "rows": 3, "seats_per_row": 5}]}
    h = build(t, dur=1.0)
    assert h.n == 60 and h.hierarchy.n_instances == 60
    g = build({"kind": "grid", "character": "w", "rows": 2, "cols": 2})
    st = concat_states([g, h, h])
    assert st.n == 4 + 60 + 60
    assert [off for off, _ in st.hierarchies] == [4, 64]
    np.testing.assert_array_equal(st.position[4:64], h.position)
    with pytest.raises(ParamError, match=r"levels\[0\]"):
        build({"kind": "hierarchy", "character": "w", "levels": [{"layout": "ring"}]})
    with pytest.raises(ParamError, match=r"levels\[1\].rows"):
        build({"kind": "hierarchy", "character": "w",
               "levels": [{"layout": "grid", "nx": 1, "nz": 1}, {"layout": "tiers", "rows": 0, "seats_per_row": 1}]})


def test_concat_empty():
    st = concat_states([])
    assert st.n == 0 and st.hierarchies == []
    assert isinstance(concat_states([CrowdState.empty(3)]), CrowdState)


# ------------------------------------------------------- benchmark scenes
SCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "scenes")
# scene -> (agents, triangles in all) from the papers / the brief
PAPER = {
    "poser4": (4, 25_584), "horses": (2_500, 58e6), "stadium": (16_416, 105e6), "grid": (90_000, 576e6),
    "office": (200, 16.4e6), "exhibition": (1_000, 83e6), "stampede": (5_000, 242e6),
}


def _agents(p: dict) -> int:
    from sim.instancing import Hierarchy, parse_levels

    kind = p["kind"]
    if kind == "grid":
        return p["rows"] * p["cols"]
    if kind == "list":
        return len(p["positions"])
    if kind == "random":
        return p["count"]
    return Hierarchy(parse_levels(p["levels"])).n_instances


@pytest.mark.parametrize("name", sorted(PAPER))
def test_benchmark_scene_validates_and_matches_the_paper(name):
    import tomllib

    from sim import terrain
    from sim.systems import effect_module

    path = os.path.join(SCENES, f"{name}.toml")
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    tris = {c["name"]: c["triangles"] for c in doc["characters"]}
    agents = total = 0
    for i, p in enumerate(doc["placement"]):
        validate(PLACEMENTS[p["kind"]][0], p, f"placement[{i}]")
        n = _agents(p)
        agents += n
        total += n * tris[p["character"]]
    for i, e in enumerate(doc.get("effects", [])):
        name_, cfg = (e, {}) if isinstance(e, str) else (e["name"], {k: v for k, v in e.items() if k != "name"})
        validate(effect_module(name_).PARAMS, cfg, f"effects[{i}]")
    if "terrain" in doc:
        validate(terrain.PARAMS, doc["terrain"], "terrain")
    want_agents, want_tris = PAPER[name]
    assert agents == want_agents
    assert abs(total - want_tris) / want_tris < 0.01
    assert doc["render"]["size"] == [1280, 720] and doc["lod"]["mode"] == "none"
    assert len(doc["camera"]["keys"]) >= 2 and doc["frames"] <= 240
