"""scripts/bench_routing.py: its arithmetic and a tiny run of its route walker (no JuPedSim, no timings)."""
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_routing.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_routing", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_routing"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_medians_and_excess(bench):
    runs = [{"evacuation_time": 10.0, "mean_flow": 1.0, "crossed": 5}, {"evacuation_time": 14.0, "mean_flow": None,
            "crossed": 4}, {"evacuation_time": 12.0, "mean_flow": 3.0, "crossed": 5}]
    m = bench.medians(runs)
    assert m == {"evacuation_time": 12.0, "mean_flow": 2.0, "crossed": 4}
    assert np.allclose(bench.excess([10.5, 9.0], [10.0, 10.0]), [0.05, -0.1])


def test_grid_agents_cover_the_floor_row_by_row(bench):
    xz = bench.grid_agents(10_000, 100.0, seed=1)
    assert xz.shape == (10_000, 2) and np.abs(xz).max() <= 100.0
    assert np.all(np.diff(xz[:100, 0]) > 0)  # the first row runs along x
    assert np.array_equal(xz, bench.grid_agents(10_000, 100.0, seed=1))


def test_walker_follows_a_router_round_a_wall(bench):
    from sim.obstacles import ObstacleSet
    from sim.routing.geometry import Walkable
    from sim.routing.router import Router

    wall = [{"center": [0.0, 0.0], "size": [0.4, 6.0]}]
    w = Walkable.from_config({"bounds": [-5.0, -5.0, 5.0, 5.0]}, {"boxes": wall})
    r = Router(w, 0.25, use_cache=False)
    gid = r.goal(("point", (3.0, 0.0)))
    L, done = bench.walk(r, gid, [(-3.0, 0.0)], (3.0, 0.0), ObstacleSet(boxes=wall), 0.25)
    assert done.all()
    # round the wall's end, 0.25 m clear: 9.032 m (two tangents, the arcs and the wall's top; the exact shortest
    # path of tests/sim/routing/routing_testutil.py); the straight line (6 m) goes through the wall
    assert 9.032 <= L[0] < 9.032 * 1.005
