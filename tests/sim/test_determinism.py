"""Determinism of the crowd simulation across numba thread counts, and
zero cost of effects a scene does not list."""
import json
import os
import subprocess
import sys
import textwrap


ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

RUN = textwrap.dedent("""
    import json, sys
    import numpy as np
    from sim.params import validate
    from sim.placement import PLACEMENTS, concat_states
    from sim.systems import effect_module
    from sim.world import World

    rng = np.random.default_rng(11)
    groups = []
    for t in ({"kind": "random", "character": "a", "count": 1500, "size": [60, 60], "heading": "random", "speed": 1.0},
              {"kind": "grid", "character": "a", "rows": 20, "cols": 25, "spacing": [0.5, 0.5],
               "origin": [-5, 0, -5]}):
        schema, fn = PLACEMENTS[t["kind"]]
        groups.append(fn(validate(schema, t, "p"), 0, 0, rng))
    w = World(state=concat_states(groups), characters=[], seed=11)
    effects = [("goals", {"paths": [[[20, 0], [0, 20], [-20, 0]], [[0, -20], [20, 20]]]}),
               ("boids", {"bounds": [-40, -40, 40, 40]}),
               ("obstacles", {"circles": [{"center": [5, 5], "radius": 3}],
                              "boxes": [{"center": [-10, 8], "size": [6, 2], "yaw": 25}]})]
    for name, cfg in effects:
        w.install(name, validate(effect_module(name).PARAMS, cfg, name))
    for _ in range(500):
        w.step(1 / 30)
    w.state.check_finite()
    import numba
    print(json.dumps({"digest": w.state.digest(), "threads": numba.get_num_threads()}))
""")

ONLY_ANIMATION = textwrap.dedent("""
    import json, sys
    import numpy as np
    from sim.state import CrowdState
    from sim.world import World
    w = World(state=CrowdState.empty(10), characters=[])
    installed = []
    for name in ("animation", "instancing", "terrain_follow"):
        try:
            if name == "instancing":
                continue  # needs a hierarchy placement
            if name == "terrain_follow":
                from sim.terrain import Terrain
                w.resources["terrain"] = Terrain(np.zeros((2, 2)))
            w.install(name, {"rate": 1.0} if name == "animation" else {"offset": 0.0})
            installed.append(name)
        except ImportError:
            pass
    for _ in range(10):
        w.step(1 / 30)
    print(json.dumps({"installed": installed,
                      "modules": sorted(m for m in sys.modules if m in ("sim.boids", "sim.grid", "sim.obstacles",
                                                                        "sim.goals")),
                      "resources": sorted(w.resources)}))
""")


def _run(code, threads):
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), PYTHONPATH=ROOT)
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_same_seed_same_bytes_with_one_and_two_threads():
    a, b = _run(RUN, 1), _run(RUN, 2)
    assert a["threads"] == 1 and b["threads"] == 2
    assert a["digest"] == b["digest"]


def test_world_without_boids_never_builds_grid_or_imports_kernel():
    r = _run(ONLY_ANIMATION, 2)
    assert r["installed"], "no non-boids effect could be installed"
    assert r["modules"] == []
    assert not any(k.startswith("boids") for k in r["resources"])
