"""scenes/million.toml: a million agents, estimated before anything is built; on a machine
without the memory, `crowd run` refuses it in one sentence (exit 2) and writes nothing."""
import os

from crowd import memory
from crowd.scene import load_scene

from crowd_testutil import REPO, run_cli  # tests/fixtures


def test_million_scene_is_a_million_agents_estimated_before_building():
    sc = load_scene(REPO / "scenes" / "million.toml")
    e = memory.estimate_scene(sc)
    assert e.agents == 1_000_000 and sc.render.size == (1280, 720)
    assert sc.lod_mode == "auto" and "boids" in sc.effect_names
    # the palette is one chunk at most (render/poses/palette.py), not a million instances' worth
    assert e.parts["gpu"] < 2 * 10 ** 9


def test_million_scene_is_refused_where_it_cannot_fit(tmp_path):
    out = tmp_path / "out"
    env_before = os.environ.get(memory.MEMORY_ENV)
    os.environ[memory.MEMORY_ENV] = str(300 * 10 ** 6)
    try:
        r = run_cli("run", REPO / "scenes" / "million.toml", "--frames", "1", "--out", out, "-q")
    finally:
        if env_before is None:
            del os.environ[memory.MEMORY_ENV]
        else:
            os.environ[memory.MEMORY_ENV] = env_before
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "1,000,000 agents" in lines[0] and "Traceback" not in r.stderr
    assert not out.exists()
