"""[[props]] in scene files: bad prop files are one-line errors with exit code 2 from `crowd validate`
and `crowd run`; `obstacle = true` props stop agents at their footprint; telemetry and memory count props."""
import numpy as np
import pytest
from crowd_testutil import run_cli, tiny_scene
from prop_files import write_prop, write_skinned_gltf

from crowd.engine import Engine
from crowd.scene import load_scene


def _prop(file, extra=""):
    return f'\n[[props]]\nfile = "{file}"\npositions = [[0.0, 0.0, 0.0]]\n{extra}\n'


@pytest.mark.parametrize("make, file, key, words", [
    (None, "nowhere.obj", "props[0].file", "file not found"),
    (lambda d: (d / "junk.ply").write_bytes(b"ply\nformat nonsense\n"), "junk.ply", "props[0].file", "cannot read"),
    (lambda d: (d / "empty.obj").write_text("v 0 0 0\n"), "empty.obj", "props[0].file", "no triangles"),
    (lambda d: write_skinned_gltf(d / "rig.gltf"), "rig.gltf", "props[0].file", "skinned glTF is not a static prop"),
    (None, "model.fbx", "props[0].file", "expected a mesh file"),
])
@pytest.mark.parametrize("command", ["validate", "run"])
def test_bad_prop_files_are_one_line_exit_2(tmp_path, make, file, key, words, command):
    if make is not None:
        make(tmp_path)
    scene = tmp_path / "s.toml"
    scene.write_text(tiny_scene(append=_prop(file)))
    out = tmp_path / "out"
    args = [command, scene] + (["--out", out] if command == "run" else [])
    r = run_cli(*args, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert f"{key}:" in lines[0] and words in lines[0] and str(scene) in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("table, key", [
    ('[[props]]\nfile = "b.obj"\npositions = [[0, 0, 0]]\nfootprint = "blob"\n', "props[0].footprint"),
    ('[[props]]\nfile = "b.obj"\n', "props[0].positions"),
    ('[[props]]\nfile = "b.obj"\nkind = "grid"\nrows = 0\n', "props[0].rows"),
    ('[[props]]\nfile = "b.obj"\npositions = [[0, 0, 0]]\ncolour = [1, 0, 0]\n', "props[0].colour"),
    ('[render]\nground = "yes"\n', "render.ground"),
])
def test_malformed_prop_keys(tmp_path, table, key):
    write_prop(tmp_path / "b", "obj")
    text = tiny_scene(append="\n" + table)
    if table.startswith("[render]"):
        text = tiny_scene().replace("[render]\n", "[render]\nground = \"yes\"\n")
    (tmp_path / "s.toml").write_text(text)
    r = run_cli("validate", tmp_path / "s.toml", cwd=tmp_path)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and f"{key}:" in r.stderr, r.stderr


def test_a_flat_prop_cannot_be_a_hull_obstacle(tmp_path):
    (tmp_path / "wall.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")  # no extent along z
    (tmp_path / "s.toml").write_text(tiny_scene(append=_prop("wall.obj", "obstacle = true")))
    r = run_cli("validate", tmp_path / "s.toml", cwd=tmp_path)
    assert r.returncode == 2 and "props[0].footprint:" in r.stderr and "no area" in r.stderr


@pytest.mark.parametrize("footprint", ["hull", "circle", "box"])
def test_obstacle_props_stop_agents_at_their_footprint(tmp_path, footprint):
    """An agent walking a path straight through a 2 m prop stops at the footprint's edge (the
    obstacles effect is listed for the prop when the scene has none)."""
    write_prop(tmp_path / "crate", "glb", size=(2.0, 1.0, 2.0))
    text = tiny_scene(effects='["animation", {name = "goals", paths = [[[-6.0, 0.0], [6.0, 0.0]]], loop = false, '
                              'speed = 2.0}]',
                      replace={"rows = 2": "rows = 1", "cols = 2": "cols = 1",
                               "spacing = [1.5, 1.5]": "origin = [-6.0, 0.0, 0.0]"},
                      append=_prop("crate.glb", f'obstacle = true\nfootprint = "{footprint}"\nyaw = 45.0'))
    (tmp_path / "s.toml").write_text(text)
    scene = load_scene(tmp_path / "s.toml")
    assert "obstacles" in scene.effect_names
    with Engine(scene, quiet=True) as e:
        obs = e.world.resources["obstacles"]
        radius = 0.4  # the obstacles effect's default agent_radius
        xs = []
        for _ in range(120):
            e.step()
            p = e.world.state.position[0]
            d, _, _ = obs.sdf(np.array([p[0]]), np.array([p[2]]))
            assert d[0] >= radius - 1e-6
            xs.append(p[0])
    edge = {"hull": np.sqrt(2.0), "box": np.sqrt(2.0), "circle": np.sqrt(2.0)}[footprint]  # yaw 45: corner at -sqrt(2)
    assert xs[-1] == pytest.approx(-edge - radius, abs=0.05)  # stopped in front of the prop, not past it


def test_run_counts_prop_triangles_and_memory(tmp_path):
    write_prop(tmp_path / "crate", "stl", size=(1.0, 1.0, 1.0))
    (tmp_path / "s.toml").write_text(tiny_scene(append=_prop("crate.stl")))
    r = run_cli("run", tmp_path / "s.toml", "--out", tmp_path / "out", "--quiet", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    rows = (tmp_path / "out" / "frames.csv").read_text().splitlines()
    cols = rows[0].split(",")
    props = [int(line.split(",")[cols.index("props")]) for line in rows[1:]]
    assert props == [12] * 3  # one 12-triangle crate in view each frame
    from crowd.memory import estimate_scene

    assert estimate_scene(load_scene(tmp_path / "s.toml")).parts["props"] > 12 * 3 * 40


def test_with_terrain_the_terrain_is_the_ground_and_solids_stand_on_it(tmp_path):
    text = tiny_scene(effects='["animation", {name = "obstacles", circles = [{center = [3.0, 4.0], radius = 1.0, '
                              'height = 2.0}]}]',
                      append='\n[terrain]\nsize = [40.0, 40.0]\norigin = [-20.0, 0.0, -20.0]\nresolution = 33\n'
                             'height_scale = 6.0\n')
    (tmp_path / "s.toml").write_text(text)
    with Engine(load_scene(tmp_path / "s.toml"), quiet=True) as e:
        assert e.scenery.selector.ground is None  # the terrain (a static rep) is drawn instead
        (rep, rows, _, _), = e.scenery.selector.groups
        world = rep.positions.astype(np.float64) + rows[0, :, 3]
        terrain = e.world.resources["terrain"]
        ring = world[world[:, 1] < world[:, 1].max() - 1e-3]  # the bottom corners
        h = terrain.height(ring[:, 0], ring[:, 2])
        assert np.allclose(ring[:, 1], h - 0.05, atol=1e-4)  # sunk a little into the terrain: no gap
        assert world[:, 1].max() == pytest.approx(terrain.height(ring[:, 0], ring[:, 2]).max() + 2.0, abs=1e-4)


def test_world_batches_follow_the_drawlist_camera():
    """A keyframed selection in "delayed" mode draws with an earlier camera: the world's batches are
    relative to the DrawList's origin, not to the camera handed in."""
    from crowd.world import Scenery
    from lod.drawlist import DrawList
    from lod.props.chain import PropChainRep
    from lod.props.select import WorldSelector
    from lod.props.solids import GroundRep
    from lod.view import Camera

    rep = PropChainRep("props:0:x", np.zeros((3, 3), np.float32), np.zeros((3, 3), np.float32),
                       np.ones((3, 4), np.float32), np.arange(3, dtype=np.uint32).reshape(1, 3),
                       np.zeros(1, np.int64), np.ones(1, np.int64), np.zeros(1), np.array([0.0, 0, 0, 1]))
    rows = np.zeros((1, 3, 4))
    rows[0, :, :3] = np.eye(3)
    sc = Scenery(WorldSelector([(rep, rows)], GroundRep()))
    drawn = Camera.look_at((0.0, 2.0, 10.0), (0.0, 0.0, 0.0))
    later = Camera.look_at((3.0, 5.0, 12.0), (0.0, 0.0, 0.0))
    dl = DrawList(origin=drawn.position, view=drawn.view_matrix().astype(np.float32),
                  proj=drawn.projection(2.0).astype(np.float32), size=(64, 32))
    sc.add(dl, later, (64, 32), 1.0, "none")
    prop = next(b for b in dl.batches if b.rep == "props:0:x")
    ground = next(b for b in dl.batches if b.rep == "world:ground")
    assert np.allclose(prop.instance_data[0, [3, 7, 11]], -drawn.position, atol=1e-5)
    assert ground.instance_data[0, 7] == pytest.approx(-2.0)
