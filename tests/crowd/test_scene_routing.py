"""The ``routing`` effect in scene files: bad walkable geometry, goals and agents are one line naming the file and
the key, exit 2, nothing written; a good one runs and draws its walls; a scene without it never imports it."""
import pytest
from crowd_testutil import run_cli, run_python, tiny_scene

# the tiny scene's four agents stand at x, z in {0, 1.5}
ROOM = "{ name = \"routing\", bounds = [-2.0, -2.0, 6.0, 4.0] }"
GOALS = "{ name = \"goals\", paths = [[[5.0, 1.0]]], loop = false }"
BOX = "{ name = \"obstacles\", agent_radius = 0.25, boxes = [{ center = [3.5, 1.0], size = [0.4, 2.0] }] }"


def scene(*effects, append=""):
    return tiny_scene(effects="[" + ", ".join(effects) + "]", append=append)


CASES = [
    ("self-intersecting-walkable",
     scene('{ name = "routing", walkable = [{ points = [[-2.0, -2.0], [6.0, 4.0], [6.0, -2.0], [-2.0, 4.0]] }] }'),
     "effects[0].walkable[0].points", ["walkable polygon intersects itself near (2, 1)"]),
    ("hole-outside-walkable",
     scene('{ name = "routing", walkable = [{ points = [[-2.0, -2.0], [6.0, -2.0], [6.0, 4.0], [-2.0, 4.0]], '
           'holes = [[[8.0, 0.0], [9.0, 0.0], [9.0, 1.0]]] }] }'),
     "effects[0].walkable[0]", ["hole outside its outer ring"]),
    ("goal-inside-an-obstacle", scene(ROOM, '{ name = "goals", paths = [[[3.5, 1.5]]] }', BOX),
     "effects[1].paths[0][0]", ["waypoint (3.5, 1.5) lies inside an obstacle"]),
    ("goal-outside-the-area", scene(ROOM, '{ name = "goals", paths = [[[0.0, 0.0], [9.0, 1.0]]] }'),
     "effects[1].paths[0][1]", ["waypoint (9, 1) lies outside the walkable area"]),
    ("walkable-and-bounds", scene('{ name = "routing", bounds = [-2.0, -2.0, 6.0, 4.0], walkable = [{ points = '
                                  '[[-2.0, -2.0], [6.0, -2.0], [6.0, 4.0]] }] }'),
     "effects[0]", ["exactly one of `walkable`", "`bounds`"]),
    ("no-area", scene('{ name = "routing" }'), "effects[0]", ["exactly one of `walkable`"]),
    ("bounds-inverted", scene('{ name = "routing", bounds = [6.0, -2.0, -2.0, 4.0] }'), "effects[0].bounds",
     ["x0 < x1"]),
    ("clearance-below-agent-radius", scene('{ name = "routing", bounds = [-2.0, -2.0, 6.0, 4.0], clearance = 0.1 }',
                                           BOX), "effects[0].clearance", [">= the obstacles' agent_radius 0.25"]),
    ("area-covered", scene(ROOM, '{ name = "obstacles", boxes = [{ center = [2.0, 1.0], size = [9.0, 7.0] }] }'),
     "effects[0]", ["walkable area is empty"]),
    ("agent-outside-the-area", scene('{ name = "routing", bounds = [-2.0, -2.0, 1.0, 4.0] }'), "placement[0]",
     ["agent 1 at (1.5, 0) lies outside the walkable area (and 1 more)"]),
    ("agent-inside-an-obstacle", scene(ROOM, '{ name = "obstacles", circles = [{ center = [1.5, 1.5], radius = '
                                       '0.3 }] }'), "placement[0]", ["agent 3 at (1.5, 1.5) lies inside an obstacle"]),
    ("goal-unreachable", scene(ROOM, GOALS, '{ name = "obstacles", agent_radius = 0.25, boxes = [{ center = [3.5, '
                                            '1.0], size = [0.4, 8.0] }] }'),
     "placement[0]", ["agent 0 at (0, 0) cannot reach its waypoint (5, 1)", "no route", "(and 3 more)"]),
]


@pytest.mark.parametrize("text, key, words", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_routing_input_is_one_line_exit_2_nothing_written(tmp_path, write_scene, text, key, words):
    path = write_scene(text)
    out = tmp_path / "out"
    r = run_cli("run", path, "--out", out, "--quiet")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert f"{path}: {key}: " in lines[0], lines[0]
    for w in words:
        assert w in lines[0], lines[0]
    assert "Traceback" not in r.stderr and not out.exists()


def test_a_routed_scene_runs_and_draws_its_walls(tmp_path, write_scene):
    path = write_scene(scene('"animation"', ROOM, GOALS, BOX))
    r = run_cli("run", path, "--out", tmp_path / "out", "--quiet")
    assert r.returncode == 0, r.stderr
    assert len(list((tmp_path / "out" / "frames").glob("*.png"))) == 3


CHECK_IMPORTS = """
import sys
from crowd.scene import load_scene
from crowd.plan import plan
from sim.world import World
sc = load_scene(sys.argv[1])
pl = plan(sc)
w = World(state=pl.state, characters=pl.characters, seed=sc.seed)
for e in sc.effects:
    w.install(e.name, e.params)
w.step(sc.dt)
print(sorted(m for m in sys.modules if m.startswith(("sim.routing", "crowd.scene_routing", "shapely"))))
print([e.name for e in sc.effects])
"""


def test_a_scene_without_routing_never_imports_it(write_scene, tmp_path):
    plain = write_scene(scene('"animation"', '{ name = "goals", paths = [[[5.0, 1.0]]] }'), "plain.toml")
    r = run_python(CHECK_IMPORTS, plain)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[0] == "[]"
    routed = write_scene(scene('"animation"', GOALS, ROOM), "routed.toml")
    r = run_python(CHECK_IMPORTS, routed)
    assert r.returncode == 0, r.stderr
    mods, names = r.stdout.splitlines()
    assert "sim.routing.router" in mods and "crowd.scene_routing" in mods
    assert names == "['obstacles', 'routing', 'animation', 'goals']"  # walls' obstacles and routing first
