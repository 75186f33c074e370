"""Effect avoidance: registration, schedule order, body radii, scene keys and their errors."""
import subprocess
import sys

import numpy as np
import pytest

from avoid_testutil import REPO, world_from_arrays


def test_schedule_order_with_every_mover():
    from sim.procedural import humanoid

    w = world_from_arrays(np.zeros((2, 2)) + [[0, 0], [3, 0]],
                          [("animation", {}), ("avoidance", {}), ("goals", {"paths": [[[10.0, 0.0]]]}),
                           ("boids", {}), ("obstacles", {"circles": [{"center": [5.0, 5.0], "radius": 1.0}]})],
                          characters=[humanoid(triangles=1000, seed=1)])
    order = [s.name for s in w.schedule.order()]
    pos = {n: i for i, n in enumerate(order)}
    assert pos["avoidance.record"] < pos["goals"] < pos["boids"] < pos["avoidance"] < pos["obstacles.project"]
    assert pos["obstacles.record"] < pos["goals"]
    assert pos["obstacles.project"] < pos["avoidance.resolve"] < pos["animation"]


def test_body_radius_footprint_character_key_override_and_scale():
    from sim.avoidance.effect import footprint_radius
    from sim.procedural import humanoid, quadruped

    h, q = humanoid(triangles=1000, seed=1), quadruped(triangles=1000, seed=1)
    assert footprint_radius(h) == pytest.approx(0.25, abs=0.01)
    assert footprint_radius(q) == pytest.approx(1.21, abs=0.02)
    from sim.avoidance.effect import PARAMS
    from sim.params import validate

    w = world_from_arrays([[0, 0], [2, 0]], [], characters=[h, q], scale=[1.0, 2.0])
    w.state.character[:] = [0, 1]
    w.install("avoidance", validate(PARAMS, {}, "avoidance"))
    w.step(0.05)
    r = w.resources["avoidance"].radius
    assert r[0] == pytest.approx(footprint_radius(h)) and r[1] == pytest.approx(2 * footprint_radius(q))
    w2 = world_from_arrays([[0, 0], [2, 0]], [], characters=[h, q], scale=[1.0, 2.0])
    w2.resources["character_radius"] = [0.3, None]
    w2.state.character[:] = [0, 1]
    w2.install("avoidance", validate(PARAMS, {}, "avoidance"))
    w2.step(0.05)
    assert w2.resources["avoidance"].radius.tolist() == pytest.approx([0.3, 2 * footprint_radius(q)])
    w3 = world_from_arrays([[0, 0], [2, 0]], [("avoidance", {"radius": 0.4})], scale=[1.0, 2.0])
    w3.step(0.05)
    assert w3.resources["avoidance"].radius.tolist() == [0.4, 0.4]


def test_standing_agents_stay_and_keep_animation_rate():
    w = world_from_arrays([[0, 0], [1, 0], [0, 1]], [("avoidance", {})])
    w.state.anim_rate[:] = 1.0
    before = w.state.position.copy()
    for _ in range(10):
        w.step(0.05)
    assert (w.state.position == before).all() and (w.state.anim_rate == 1.0).all()


def test_unlisted_effect_is_never_imported():
    code = ("import sys; from crowd.scene import load_scene; load_scene('scenes/stampede.toml'); "
            "print('sim.avoidance' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO,
                       env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}, timeout=300)
    assert r.returncode == 0, r.stderr[-1000:]
    assert r.stdout.strip().splitlines()[-1] == "False"


@pytest.mark.parametrize("edit, key, words", [
    ('model = "cfsm"', "effects[2].model", "expected one of 'cfsm', 'orca'"),
    ("time_gap = 1.0", "effects[2].time_gap", "expected >= 0.1"),
    ("radius = 0.2\n", "characters[0].radius", "expected >= 0.001"),
])
def test_bad_keys_are_one_line_errors(tmp_path, edit, key, words):
    text = (REPO / "scenes" / "corridor.toml").read_text()
    bad = {'model = "cfsm"': 'model = "rvo"', "time_gap = 1.0": "time_gap = 0.0",
           "radius = 0.2\n": "radius = -1.0\n"}[edit]
    assert edit in text
    p = tmp_path / "bad.toml"
    p.write_text(text.replace(edit, bad, 1))
    r = subprocess.run([sys.executable, "-m", "crowd", "validate", str(p)], capture_output=True, text=True,
                       cwd=REPO, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}, timeout=300)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{key}: " in lines[0] and words in lines[0] and "Traceback" not in r.stderr
