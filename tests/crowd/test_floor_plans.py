"""Floor plans from files (issue 47, item 1 in part: WKT and GeoJSON): ``[[effects]] name = "routing"`` with
``walkable_file`` gives the walkable area the typed polygons give, the formats agree with each other, and a file
that is empty, not closed, self-intersecting or of an unknown format is one sentence naming the file, exit 2."""
import json
from pathlib import Path

import pytest
from crowd_testutil import REPO, run_cli, tiny_scene

from crowd.errors import SceneError
from crowd.scene import load_scene
from sim.routing.floor_plan import FloorPlanError, load_walkable

#: a room 8 x 6 m with a pillar (hole) and a side room joined by a door
WKT = ("MULTIPOLYGON (((-2 -2, 6 -2, 6 4, -2 4, -2 -2), (2 0, 3 0, 3 1, 2 1, 2 0)), "
       "((6 0.5, 9 0.5, 9 3, 6 3, 6 0.5)))")
#: the same area typed as the scene file takes it (the side room is joined to the room: one polygon)
TYPED = ('walkable = [{ points = [[-2.0, -2.0], [6.0, -2.0], [6.0, 0.5], [9.0, 0.5], [9.0, 3.0], [6.0, 3.0], '
         '[6.0, 4.0], [-2.0, 4.0]], holes = [[[2.0, 0.0], [3.0, 0.0], [3.0, 1.0], [2.0, 1.0]]] }]')
BOTTLENECK = REPO.parent / "shared" / "data" / "pedestrian" / "bottleneck" / "walkable_area.wkt"


def _geojson(wkt: str, feature: bool) -> str:
    import shapely
    from shapely.geometry import mapping

    g = mapping(shapely.from_wkt(wkt))
    if feature:
        g = {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": g}]}
    return json.dumps(g)


def _area(walkable: list) -> float:
    from shapely.geometry import Polygon

    return sum(Polygon(p["points"], p["holes"]).area for p in walkable)


def _scene(file_line: str) -> str:
    return tiny_scene(effects='[{ name = "routing", ' + file_line + ' }]')


def test_wkt_and_geojson_give_the_typed_area(write_scene, tmp_path):
    (tmp_path / "plan.wkt").write_text(WKT)
    (tmp_path / "plan.geojson").write_text(_geojson(WKT, feature=True))
    (tmp_path / "plan.json").write_text(_geojson(WKT, feature=False))
    typed = load_scene(write_scene(_scene(TYPED), "typed.toml"))
    want = _area(next(e for e in typed.effects if e.name == "routing").params["walkable"])
    assert want == pytest.approx(8 * 6 - 1 + 3 * 2.5)
    for name in ("plan.wkt", "plan.geojson", "plan.json"):
        sc = load_scene(write_scene(_scene(f'walkable_file = "{name}"'), f"{name}.toml"))
        r = next(e for e in sc.effects if e.name == "routing").params
        assert r["walkable_file"] == str((tmp_path / name).resolve())
        assert len(r["walkable"]) == 1 and len(r["walkable"][0]["holes"]) == 1  # the side room joined on
        assert _area(r["walkable"]) == pytest.approx(want, rel=1e-9), name
        # the walls follow the file's outline: the obstacles effect got them, as with typed polygons
        obs = next(e for e in sc.effects if e.name == "obstacles").params
        assert len(obs["polygons"]) == len(next(e for e in typed.effects if e.name == "obstacles").params["polygons"])


def test_a_scene_with_a_floor_plan_runs(write_scene, tmp_path):
    (tmp_path / "plan.wkt").write_text(WKT)
    path = write_scene(_scene('walkable_file = "plan.wkt"'))
    r = run_cli("run", path, "--out", tmp_path / "out", "--quiet")
    assert r.returncode == 0, r.stderr


@pytest.mark.skipif(not BOTTLENECK.is_file(), reason=f"no shared pedestrian data at {BOTTLENECK}")
def test_the_bottleneck_experiment_in_wkt_and_geojson_gives_one_area(tmp_path):
    from shapely import from_wkt

    ref = from_wkt(BOTTLENECK.read_text())
    (tmp_path / "b.geojson").write_text(_geojson(BOTTLENECK.read_text(), feature=True))
    a, b = load_walkable(BOTTLENECK), load_walkable(tmp_path / "b.geojson")
    assert _area(a) == pytest.approx(ref.area, rel=1e-3) and _area(b) == pytest.approx(ref.area, rel=1e-3)
    assert len(a) == 1 and len(a[0]["holes"]) == 2  # the room and the two barriers of the bottleneck


@pytest.mark.parametrize("name, content, what", [
    ("empty.wkt", "", "the file is empty"),
    ("blank.geojson", "  \n", "the file is empty"),
    ("line.wkt", "LINESTRING (0 0, 4 0, 4 3)", "is a LineString, not an area (not closed)"),
    ("ring.wkt", "LINESTRING (0 0, 4 0, 4 3, 0 0)", "(a closed line: write it as a POLYGON)"),
    ("bowtie.wkt", "POLYGON ((0 0, 4 3, 4 0, 0 3, 0 0))", "is not a simple area: Self-intersection"),
    ("bad.wkt", "POLYGON ((0 0, 1 0", "not valid WKT"),
    ("bad.json", "{ nope", "not valid JSON"),
    ("point.geojson", json.dumps({"type": "Point", "coordinates": [1, 2]}), "is a Point, not an area"),
    ("plan.dwg", "x", "unknown floor-plan format '.dwg'"),
])
def test_bad_floor_plans_are_one_sentence_naming_the_file(write_scene, tmp_path, name, content, what):
    f = tmp_path / name
    f.write_text(content)
    with pytest.raises(FloorPlanError) as e:
        load_walkable(f)
    assert str(e.value).startswith(f"{f}: ") and what in str(e.value) and "\n" not in str(e.value)
    path = write_scene(_scene(f'walkable_file = "{name}"'))
    r = run_cli("validate", path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "Traceback" not in r.stderr
    assert f"{path}: effects[0].walkable_file: {f}: " in lines[0] and what in lines[0], lines[0]


def test_a_missing_file_and_two_sources_of_the_area_are_refused(write_scene, tmp_path):
    with pytest.raises(SceneError, match=r"walkable_file: .*nowhere\.wkt: file not found"):
        load_scene(write_scene(_scene('walkable_file = "nowhere.wkt"')))
    (tmp_path / "plan.wkt").write_text(WKT)
    with pytest.raises(SceneError, match="exactly one of .*; got bounds, walkable_file"):
        load_scene(write_scene(_scene('bounds = [0.0, 0.0, 5.0, 5.0], walkable_file = "plan.wkt"'), "two.toml"))
    assert not Path("nowhere.wkt").exists()


# ---------------------------------------------------------------------------------------------------- DXF
def _dxf(path: Path, wkt: str, layer: str = "walkable", hatch: bool = False, extra=()) -> Path:
    """The area of ``wkt`` drawn as closed polylines (outer rings and holes) or as one hatch per polygon."""
    import ezdxf
    import shapely

    doc = ezdxf.new()
    msp = doc.modelspace()
    g = shapely.from_wkt(wkt)
    for poly in getattr(g, "geoms", [g]):
        rings = [list(poly.exterior.coords)] + [list(h.coords) for h in poly.interiors]
        if hatch:
            h = msp.add_hatch(dxfattribs={"layer": layer})
            for r in rings:
                h.paths.add_polyline_path([(x, y) for x, y in r[:-1]], is_closed=True)
        else:
            for r in rings:
                msp.add_lwpolyline([(x, y) for x, y in r[:-1]], close=True, dxfattribs={"layer": layer})
    msp.add_line((0, 0), (50, 50), dxfattribs={"layer": layer})  # not an area: left out
    msp.add_lwpolyline([(100, 100), (104, 100), (104, 103), (100, 103)], close=True, dxfattribs={"layer": "furniture"})
    for pts, closed, lay in extra:
        msp.add_lwpolyline(pts, close=closed, dxfattribs={"layer": lay})
    doc.saveas(path)
    return path


@pytest.mark.parametrize("hatch", [False, True])
def test_dxf_polylines_and_hatches_give_the_wkts_area(tmp_path, hatch):
    from shapely import from_wkt

    f = _dxf(tmp_path / "plan.dxf", WKT, hatch=hatch)
    got = load_walkable(f, layer="walkable")
    assert _area(got) == pytest.approx(from_wkt(WKT).area, rel=1e-9)
    assert len(got) == 1 and len(got[0]["holes"]) == 1
    every = load_walkable(f)  # every layer: the furniture layer's closed outline is an area too
    assert _area(every) == pytest.approx(from_wkt(WKT).area + 12.0, rel=1e-9)


@pytest.mark.skipif(not BOTTLENECK.is_file(), reason=f"no shared pedestrian data at {BOTTLENECK}")
def test_the_bottleneck_in_dxf_wkt_and_geojson_gives_one_area_within_a_thousandth(tmp_path):
    from shapely import from_wkt

    ref = from_wkt(BOTTLENECK.read_text())
    (tmp_path / "b.geojson").write_text(_geojson(BOTTLENECK.read_text(), feature=True))
    areas = [_area(load_walkable(BOTTLENECK)), _area(load_walkable(tmp_path / "b.geojson")),
             _area(load_walkable(_dxf(tmp_path / "b.dxf", BOTTLENECK.read_text()), layer="walkable")),
             _area(load_walkable(_dxf(tmp_path / "h.dxf", BOTTLENECK.read_text(), hatch=True), layer="walkable"))]
    for a in areas:
        assert a == pytest.approx(ref.area, rel=1e-3)


def test_a_dxf_with_an_open_polyline_or_a_self_intersection_names_layer_and_entity(write_scene, tmp_path):
    f = _dxf(tmp_path / "open.dxf", WKT, extra=[([(20, 0), (24, 0), (24, 3)], False, "walls")])
    with pytest.raises(FloorPlanError, match=r"open\.dxf: layer 'walls', LWPOLYLINE \(handle \w+\) is an open "
                                             r"polyline, not an area"):
        load_walkable(f)
    assert _area(load_walkable(f, layer="walkable")) > 0  # the open one is on another layer
    g = _dxf(tmp_path / "bow.dxf", WKT, extra=[([(20, 0), (24, 3), (24, 0), (20, 3)], True, "walls")])
    with pytest.raises(FloorPlanError, match=r"layer 'walls', LWPOLYLINE \(handle \w+\) is not a simple area: "
                                             r"Self-intersection"):
        load_walkable(g)
    path = write_scene(_scene('walkable_file = "bow.dxf"'))
    r = run_cli("validate", path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "layer 'walls', LWPOLYLINE" in lines[0], r.stderr
    with pytest.raises(FloorPlanError, match="no closed polyline or hatch on layer 'nope' \\(layers: "):
        load_walkable(f, layer="nope")
    (tmp_path / "junk.dxf").write_text("this is not a drawing\n")
    with pytest.raises(FloorPlanError, match="junk.dxf: not a readable DXF drawing"):
        load_walkable(tmp_path / "junk.dxf")
    (tmp_path / "plan.wkt").write_text(WKT)
    with pytest.raises(SceneError, match="only a DXF drawing has layers"):
        load_scene(write_scene(_scene('walkable_file = "plan.wkt", walkable_layer = "a"'), "lay.toml"))
    with pytest.raises(SceneError, match="walkable_layer: only with `walkable_file`"):
        load_scene(write_scene(_scene('bounds = [0.0, 0.0, 5.0, 5.0], walkable_layer = "a"'), "lay2.toml"))


def test_a_scene_runs_on_a_dxf_floor_plan(write_scene, tmp_path):
    _dxf(tmp_path / "plan.dxf", WKT)
    path = write_scene(_scene('walkable_file = "plan.dxf", walkable_layer = "walkable"'))
    r = run_cli("run", path, "--out", tmp_path / "out", "--quiet")
    assert r.returncode == 0, r.stderr


PEDESTRIAN = REPO.parent / "shared" / "data" / "pedestrian"


@pytest.mark.skipif(not (PEDESTRIAN / "jupedsim").is_dir(), reason=f"no shared pedestrian data at {PEDESTRIAN}")
@pytest.mark.parametrize("rel, area", [("jupedsim/trajectories.sqlite", 104.0),
                                       ("vadere/vadere_bottleneck.scenario", 59.5)])
def test_the_geometry_stored_with_a_recording(rel, area):
    got = load_walkable(PEDESTRIAN / rel)
    assert _area(got) == pytest.approx(area, rel=1e-3)


def test_a_broken_recording_is_one_sentence(tmp_path):
    f = tmp_path / "run.sqlite"
    f.write_bytes(b"not a database at all" * 10)
    with pytest.raises(FloorPlanError, match=r"run\.sqlite: no walkable area in it \("):
        load_walkable(f)
    g = tmp_path / "s.scenario"
    g.write_text("{}")
    with pytest.raises(FloorPlanError, match=r"s\.scenario: no walkable area in it \("):
        load_walkable(g)


def test_obstacles_from_a_floor_plan_file(write_scene, tmp_path):
    """The obstacles effect's ``file``: its areas become solid polygons; the agents keep out of them."""
    import numpy as np

    from crowd.engine import Engine

    (tmp_path / "pillars.wkt").write_text("MULTIPOLYGON (((3 -1, 4 -1, 4 3, 3 3, 3 -1)), ((6 0, 7 0, 7 1, 6 1, 6 0)))")
    text = tiny_scene(effects='["animation", { name = "obstacles", file = "pillars.wkt", agent_radius = 0.2 }]')
    sc = load_scene(write_scene(text))
    obs = next(e for e in sc.effects if e.name == "obstacles").params
    assert len(obs["polygons"]) == 2 and obs["file"] == str((tmp_path / "pillars.wkt").resolve())
    with Engine(sc, quiet=True) as eng:
        o = eng.world.resources["obstacles"]
        d, _, _ = o.sdf(np.array([3.5, 6.5, 0.0]), np.array([1.0, 0.5, 0.0]))
        assert d[0] < 0 and d[1] < 0 and d[2] > 0  # inside each pillar, outside at the origin
    (tmp_path / "ring.wkt").write_text(WKT)
    with pytest.raises(SceneError, match="area 0 has a hole; an obstacle is solid"):
        load_scene(write_scene(tiny_scene(effects='[{ name = "obstacles", file = "ring.wkt" }]'), "ring.toml"))
    with pytest.raises(SceneError, match=r"effects\[0\]\.layer: only with `file`"):
        load_scene(write_scene(tiny_scene(effects='[{ name = "obstacles", layer = "x" }]'), "lay.toml"))
    with pytest.raises(SceneError, match=r"effects\[0\]\.file: .*nope\.wkt: file not found"):
        load_scene(write_scene(tiny_scene(effects='[{ name = "obstacles", file = "nope.wkt" }]'), "nope.toml"))
