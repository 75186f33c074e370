"""scripts/bench_avoidance.py: its arithmetic and a tiny run of its own logic without JuPedSim (no timings)."""
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_avoidance.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_avoidance", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_avoidance"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_weidmann_curve(bench):
    w = bench.weidmann_speed
    assert float(w(5.4)) == 0.0
    assert float(w(2.0)) == pytest.approx(1.34 * (1 - math.exp(-1.913 * (0.5 - 1 / 5.4))))
    assert bench.weidmann_error(2.0, float(w(2.0)) * 1.2) == pytest.approx(0.2)


def test_door_flow_of_a_steady_stream(bench):
    # N agents of speed v, 0.5 m apart in single file, cross a line: flow = v / spacing = 2.6 /s
    v, gap, n = 1.3, 0.5, 21
    times = [3.0 + i * gap / v for i in range(n)] + [None]  # one never crossed
    f = bench.door_flow(times)
    assert f["crossed"] == n and f["evacuation_time"] == pytest.approx(3.0 + 20 * gap / v)
    assert f["mean_flow"] == pytest.approx(v / gap) and f["steady_flow"] == pytest.approx(v / gap)
    assert bench.door_flow([None, 1.0])["mean_flow"] is None
    assert bench.door_flow([2.0, 2.0])["mean_flow"] is None  # one instant: no flow
    assert bench.relative_difference(1.1, 1.0) == pytest.approx(0.1)


def test_positions(bench):
    p = bench.dart_positions(120, (-5.0, 5.0, -2.0, 2.0), 0.42, seed=3)
    assert p.shape == (120, 2) and p[:, 0].min() >= -5 and p[:, 1].max() <= 2
    d = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1)) + np.eye(120) * 9
    assert d.min() >= 0.42
    assert np.array_equal(p, bench.dart_positions(120, (-5.0, 5.0, -2.0, 2.0), 0.42, seed=3))  # deterministic
    with pytest.raises(bench.BenchError, match="do not fit"):
        bench.dart_positions(100, (0, 1, 0, 1), 0.5, seed=0, max_tries=5000)
    pos, (x0, x1, z0, z1), (tx, tz) = bench.room_positions(1000)
    assert pos.shape == (1000, 2) and len({tuple(q) for q in pos}) == 1000
    assert x0 < pos[:, 0].min() and pos[:, 0].max() <= 0 < tx < x1 and z0 < pos[:, 1].min() and tz == 0


def test_tiny_bottleneck_and_corridor_without_jupedsim(bench):
    import numba

    prev = numba.get_num_threads()
    numba.set_num_threads(1)  # as the script's behaviour runs
    try:
        pos = bench.dart_positions(6, (-3.0, -1.0, -1.0, 1.0), 0.5, seed=1)
        r = bench.square_bottleneck_ours(pos, 60.0)
        c = bench.corridor_ours(0.5, window=(0.5, 2.0))
    finally:
        numba.set_num_threads(prev)
    f = bench.door_flow(r["crossing_times"])
    assert f["crossed"] == 6 and 0 < f["evacuation_time"] < 60 and f["mean_flow"] > 0
    assert r["min_distance"] >= 2 * bench.RADIUS * 0.99  # no overlap
    assert c["agents"] == 72 and 0 < c["density"] < 1.0 and 0 < c["speed"] <= bench.V0 + 1e-6
    assert c["error"] == pytest.approx(abs(c["speed"] - c["weidmann"]) / c["weidmann"])


def test_options_and_missing_peers(bench, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(bench.PEERS_ENV, str(tmp_path / "nope"))
    assert bench.main(["--quick", "--no-write"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "make bench-peers" in err
    assert bench.main(["--quick", "--no-peers", "--sizes", "1,x"]) == 2
    assert bench.main(["--quick", "--no-peers", "--densities", "9"]) == 2


def test_the_shipped_bottleneck_scene_loads(bench):
    b = bench.load_bottleneck(bench.ROOT / "scenes" / "bottleneck.toml")
    n = b["positions"].shape[0]
    assert n == b["scene"].placements[0].params["count"] and np.all(b["positions"][:, 0] < 0)  # inside the room
    assert np.allclose(b["radius"], b["radius"][0]) and len(b["polygons"]) >= 1
    assert all(len(p) >= 3 for p in b["polygons"])
    with pytest.raises(bench.BenchError):
        bench.load_bottleneck(bench.ROOT / "scenes" / "quickstart.toml")  # no avoidance/obstacles
