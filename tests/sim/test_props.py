"""sim.props: reading prop files of every format, refusing bad ones, placements and footprints."""
import math

import numpy as np
import pytest
from prop_files import FORMATS, write_prop, write_skinned_gltf

from sim.errors import AssetError
from sim.obstacles import PARAMS as OBSTACLE_PARAMS
from sim.obstacles import ObstacleSet
from sim.params import ParamError, validate
from sim.props import footprint, load_prop_mesh, model_rows, placed_obstacles, prop_instances, validate_prop


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_format_reads_its_triangles_and_extent(tmp_path, fmt):
    p = write_prop(tmp_path / "box", fmt, size=(2.0, 1.0, 0.5))
    m = load_prop_mesh(p)
    assert m.n_triangles == 12
    assert np.allclose(m.positions.min(0), [-1.0, 0.0, -0.25], atol=1e-6)
    assert np.allclose(m.positions.max(0), [1.0, 1.0, 0.25], atol=1e-6)
    assert m.colors.shape == (len(m.positions), 4) and np.isfinite(m.colors).all()
    if fmt != "stl":  # STL has no colours: the default grey
        assert np.allclose(m.colors[:, :3], [0.9, 0.2, 0.1], atol=0.01)


def test_up_z_turns_a_z_up_file_upright(tmp_path):
    p = write_prop(tmp_path / "tall", "stl", size=(1.0, 1.0, 3.0))  # 3 m along z
    m = load_prop_mesh(p, up="z")
    ext = m.positions.max(0) - m.positions.min(0)
    assert np.allclose(ext, [1.0, 3.0, 1.0], atol=1e-6)


@pytest.mark.parametrize("make, words", [
    (lambda d: d / "missing.obj", "file not found"),
    (lambda d: (d / "junk.glb").write_bytes(b"not a glb at all") and d / "junk.glb", "cannot read"),
    (lambda d: (d / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n") and d / "points.obj", "no triangles"),
    (lambda d: write_skinned_gltf(d / "skinned.gltf"), "skinned glTF is not a static prop"),
    (lambda d: write_skinned_gltf(d / "anim.gltf", animated_only=True), "animated glTF is not a static prop"),
])
def test_bad_files_are_one_sentence_asset_errors(tmp_path, make, words):
    with pytest.raises(AssetError) as e:
        load_prop_mesh(make(tmp_path))
    msg = str(e.value)
    assert words in msg and "\n" not in msg


def test_grid_and_list_placements():
    cfg = validate_prop({"file": "x.obj", "kind": "grid", "rows": 2, "cols": 3, "spacing": [2.0, 5.0],
                         "origin": [1.0, 0.5, -1.0], "yaw": 90.0, "scale": 2.0}, "props[0]")
    pos, yaw, scale = prop_instances(cfg)
    assert pos.shape == (6, 3) and np.allclose(pos[4], [3.0, 0.5, 4.0])
    assert np.allclose(yaw, math.pi / 2) and np.allclose(scale, 2.0)
    rows = model_rows(pos, yaw, scale)
    # yaw 90 degrees maps local +Z to +X (as the characters' heading), scaled by 2
    assert np.allclose(rows[0, :, :3] @ [0.0, 0.0, 1.0], [2.0, 0.0, 0.0], atol=1e-12)
    cfg = validate_prop({"file": "x.obj", "positions": [[0, 0, 0], [1, 0, 1]], "yaws": [0.0, 180.0]}, "p")
    assert np.allclose(prop_instances(cfg)[1], [0.0, math.pi])
    with pytest.raises(ParamError, match="yaws"):
        validate_prop({"file": "x.obj", "positions": [[0, 0, 0]], "yaws": [1.0, 2.0]}, "p")
    with pytest.raises(ParamError, match="positions"):
        validate_prop({"file": "x.obj"}, "p")


@pytest.mark.parametrize("kind", ["hull", "circle", "box"])
def test_footprints_contain_the_floor_projection(tmp_path, kind):
    m = load_prop_mesh(write_prop(tmp_path / "b", "obj", size=(2.0, 1.0, 1.0)))
    fp = footprint(m, kind)
    pos, yaw, scale = np.array([[10.0, 0.0, -4.0]]), np.array([math.radians(30.0)]), np.array([1.5])
    obs_cfg = placed_obstacles(fp, pos, yaw, scale)
    cfg = validate(OBSTACLE_PARAMS, obs_cfg, "effects[0]")
    obs = ObstacleSet.from_config(cfg)
    assert obs.count == 1
    assert not obs.circle_draw[:, 1].any() and not obs.poly_draw[:, 1].any()  # props draw themselves
    # every placed vertex of the mesh lies inside (or on) the obstacle
    world = np.einsum("ij,vj->vi", model_rows(pos, yaw, scale)[0][:, :3], m.positions) + pos[0]
    d, _, _ = obs.sdf(world[:, 0], world[:, 2])
    assert (d <= 1e-9).all()
    if kind == "hull":  # the hull is tight: its corners are the box's
        assert abs(min(d)) < 1e-9


def test_obstacle_shapes_take_height_and_visible():
    cfg = validate(OBSTACLE_PARAMS, {"circles": [{"center": [0, 0], "radius": 1.0, "height": 2.5}],
                                     "boxes": [{"center": [3, 0], "size": [1, 1], "visible": False}],
                                     "polygons": [{"points": [[0, 5], [1, 5], [0, 6]], "height": 0.5}]}, "e")
    obs = ObstacleSet.from_config(cfg)
    assert obs.circle_draw.tolist() == [[2.5, 1.0]]
    assert obs.poly_draw.tolist() == [[1.0, 0.0], [0.5, 1.0]]
    with pytest.raises(ParamError, match="expected >= 0"):
        validate(OBSTACLE_PARAMS, {"circles": [{"center": [0, 0], "radius": 1.0, "height": -1}]}, "e")
    with pytest.raises(ParamError, match="points"):
        validate(OBSTACLE_PARAMS, {"polygons": [{"points": [[0, 5], [1, 5], [0, 6]], "colour": 1}]}, "e")


def test_non_finite_vertices_never_reach_a_prop(tmp_path):
    """trimesh drops the faces of a NaN vertex (then the file holds no triangles); whichever check
    refuses it, the error is one sentence and nothing non-finite is returned."""
    p = tmp_path / "nan.obj"
    p.write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(AssetError, match="no triangles|NaN, infinite") as e:
        load_prop_mesh(p)
    assert "\n" not in str(e.value)
