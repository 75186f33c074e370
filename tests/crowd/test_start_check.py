"""Agents that start inside an obstacle or outside the walkable area: ``crowd validate`` warns (one line per
placement, with counts, exit 0) and ``crowd run`` says it once (crowd/start_check.py, issue 48)."""
from crowd_testutil import run_cli, tiny_scene

from crowd.plan import plan
from crowd.scene import load_scene
from crowd.start_check import start_warnings

SECOND = """
[[placement]]
kind = "grid"
character = "walker"
rows = 2
cols = 2
spacing = [1.0, 1.0]
origin = [20.0, 0.0, 20.0]
"""


def _scene(effects: str) -> str:
    """tiny_scene with a 4 x 5 grid at 1 m (x 0..4, z 0..3), a second 2 x 2 grid far away, and ``effects``."""
    return tiny_scene(effects=effects, replace={"rows = 2": "rows = 4", "cols = 2": "cols = 5",
                                                "spacing = [1.5, 1.5]": "spacing = [1.0, 1.0]"}, append=SECOND)


# a box over columns 1..2 of rows 0..3 of the first grid (x 0.5..2.5): 8 agents inside; the second grid is clear
OBSTACLE = _scene('["animation", { name = "obstacles", boxes = [{ center = [1.5, 1.5], size = [2.0, 10.0], '
                  'yaw = 0.0 }] }]')

# a room of x 0..10, z -1..2.5 (rows 0..2 of the first grid inside, row 3 at z = 3 outside: 5 agents), the second
# grid far outside: with routing an error of the scene, at validate as at run
ROOM = _scene('["animation", { name = "routing", walkable = [{ points = [[-1.0, -1.0], [10.0, -1.0], [10.0, 2.5], '
              '[-1.0, 2.5]] }] }, "obstacles"]')


def test_validate_warns_of_agents_inside_an_obstacle(write_scene):
    path = write_scene(OBSTACLE)
    r = run_cli("validate", path)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: ") and "placement[0]" in lines[0]
    assert "placement[0]: 8 of its 20 agents start inside an obstacle" in lines[0], lines[0]
    assert r.stdout.startswith("OK ")


def test_run_says_it_once_and_a_clear_scene_says_nothing(write_scene, tmp_path):
    path = write_scene(OBSTACLE)
    scene = load_scene(path)
    p = plan(scene)
    (line,) = start_warnings(scene, p.state, p.agents_per_placement)
    assert "placement[0]: 8 of its 20 agents start inside an obstacle" in line
    r = run_cli("run", path, "--out", tmp_path / "out")
    assert r.returncode == 0, r.stderr
    assert [x for x in r.stderr.splitlines() if "warning:" in x] == [line]  # once, not per frame
    assert run_cli("run", path, "--out", tmp_path / "q", "--quiet").stderr.strip() == ""
    clear = write_scene(OBSTACLE.replace("center = [1.5, 1.5]", "center = [1.5, -8.0]"), "clear.toml")
    s = load_scene(clear)
    q = plan(s)
    assert start_warnings(s, q.state, q.agents_per_placement) == []
    assert run_cli("validate", clear).stderr.strip() == ""


def test_with_routing_validate_refuses_what_run_refuses(write_scene, tmp_path):
    path = write_scene(ROOM)
    v = run_cli("validate", path)
    r = run_cli("run", path, "--out", tmp_path / "out")
    for x in (v, r):
        lines = x.stderr.strip().splitlines()
        assert x.returncode == 2 and len(lines) == 1 and "Traceback" not in x.stderr
        assert "placement[0]" in lines[0] and "lies outside the walkable area (and 8 more)" in lines[0], lines[0]
    assert v.stderr.split("error: ", 1)[1] == r.stderr.split("error: ", 1)[1]
    assert not (tmp_path / "out").exists()
