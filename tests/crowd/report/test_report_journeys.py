"""``crowd report`` of a scene whose agents enter and leave (crowd.report.population, PedPy on trajectories with
a changing agent count).

A source on a 2 m line at z = -12 lets one agent in per second (uniform); each walks at 1 m/s along +z (no
avoidance) and leaves through a 2 m door at z = 0: the door's flow is 1 person/s, every crossing is an exit, and
the entered count is the rate's to the agent.
"""
import json
import re

import pytest
from crowd_testutil import run_cli

pytest.importorskip("pedpy")

SCENE = """\
name = "door_flow"
seed = 1
dt = 0.1
frames = 200
effects = ["animation", { name = "journeys", speed = 1.0 }]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "grid"
character = "walker"
rows = 1
cols = 1
spacing = [1.0, 1.0]
origin = [30.0, 0.0, 30.0]

[[stages]]
name = "door"
kind = "exit"
line = [[-1.0, 0.0], [1.0, 0.0]]

[[journeys]]
name = "through"
stages = ["door"]

[[sources]]
name = "gate"
character = "walker"
journey = "through"
rate = 1.0
line = [[-0.5, -12.0], [0.5, -12.0]]

[[measurement]]
name = "door"
line = [[-1.0, 0.0], [1.0, 0.0]]

[camera]
position = [0.0, 20.0, -6.0]
target = [0.0, 0.0, -6.0001]

[render]
size = [64, 48]
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    d = tmp_path_factory.mktemp("flow")
    scene = d / "door_flow.toml"
    scene.write_text(SCENE)
    out = d / "report"
    r = run_cli("report", scene, "--cluster", "none", "--out", out, "--quiet", timeout=600)
    assert r.returncode == 0, r.stderr
    return out


def test_population_section_counts_sources_and_exits(report):
    data = json.loads((report / "report.json").read_text())
    (sc,) = data["scenes"]
    p = sc["population"]
    (src,) = p["sources"]
    assert src["entered"] == 20 and src["expected"] == 20.0 and src["deviation"] == 0.0  # t = 0, 1, ..., 19 s
    assert p["exits"] == {"door": 8}  # 12 m at 1 m/s: the agents of t = 0 .. 7 s are out by 20 s
    assert p["agents_start"] == 1 and p["entered"] == 20 and p["exited"] == 8
    html = (report / "index.html").read_text()
    assert "Agents entering and leaving" in html and "+0.0 %" in html
    assert (report / p["plot"]).stat().st_size > 1000 and f"<img src='{p['plot']}'" in html


def test_pedpy_sees_every_exit_cross_the_door(report):
    data = json.loads((report / "report.json").read_text())
    (m,) = data["scenes"][0]["pedestrian"]["measurements"]
    assert m["line"]["crossings"] == 8
    assert m["line"]["mean_flow"] == pytest.approx(1.0, abs=1e-9)  # 1 m/s, 1 m apart
