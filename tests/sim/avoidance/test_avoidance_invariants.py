"""Effect avoidance on degenerate and extreme inputs: coincident starts, head-on pairs, 10,000 agents
in a 10 m square, a crowd 1e6 m from the origin, thread-count independence."""
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from avoid_testutil import REPO, min_gap_ratio, run_checked, world_from_arrays

MODELS = ("cfsm", "orca")


def _goals_to(targets):
    return ("goals", {"paths": [[[float(x), float(z)]] for x, z in targets], "loop": False, "speed": 1.3,
                      "arrive_radius": 0.5})


def _speeds(w):
    return np.hypot(w.state.velocity[:, 0], w.state.velocity[:, 2])


@pytest.mark.parametrize("model", MODELS)
def test_coincident_start_parts_without_nan_or_speed(model):
    """20 agents at exactly one point, each heading for a different point 10 m away."""
    n = 20
    xz = np.full((n, 2), 3.0)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    targets = 3.0 + 10.0 * np.stack([np.cos(ang), np.sin(ang)], 1)
    w = world_from_arrays(xz, [_goals_to(targets), ("avoidance", {"model": model, "radius": 0.25})])
    w.step(0.05)  # the first step parts them (resolve); from then on no overlap
    w.state.check_finite()
    assert min_gap_ratio(w) >= 0.99
    run_checked(w, 300, 0.05)
    assert _speeds(w).max() <= 1.3 + 1e-9
    d = np.hypot(w.state.position[:, 0] - targets[:, 0], w.state.position[:, 2] - targets[:, 1])
    assert d.max() < 0.5  # everyone arrived within 15 s


@pytest.mark.parametrize("model", MODELS)
def test_head_on_pairs_pass_each_other(model):
    """Five exactly symmetric head-on pairs 8 m apart (lanes 3 m apart): no deadlock."""
    a = np.array([[0.0, 3.0 * k] for k in range(5)])
    b = a + [8.0, 0.0]
    xz = np.concatenate([a, b])
    targets = np.concatenate([b, a])
    w = world_from_arrays(xz, [_goals_to(targets), ("avoidance", {"model": model})])
    run_checked(w, 400, 0.05)
    d = np.hypot(w.state.position[:, 0] - targets[:, 0], w.state.position[:, 2] - targets[:, 1])
    assert d.max() < 0.5, f"not arrived within 20 s: {d.max():.2f} m left"


@pytest.mark.parametrize("model", MODELS)
def test_ten_thousand_agents_in_a_ten_metre_square(model):
    """100 per m^2 (far beyond any physical density): finite, speeds within the preferred speed, the
    crowd unfolds outwards step by step and nobody is thrown away."""
    rng = np.random.default_rng(7)
    xz = rng.uniform(0, 10, (10_000, 2))
    w = world_from_arrays(xz, [("goals", {"paths": [[[5.0, 100.0]]], "loop": False, "speed": 1.3}),
                               ("avoidance", {"model": model, "radius": 0.25})])
    prev = w.state.position.copy()
    for _ in range(3):
        w.step(0.05)
        w.state.check_finite()
        assert _speeds(w).max() <= 1.3 + 1e-9
        move = np.hypot(*(w.state.position - prev)[:, [0, 2]].T)
        # the model moves an agent by at most v dt, the resolve by at most its radius per pass
        assert move.max() <= 1.3 * 0.05 + 50 * 0.25 + 1e-9
        prev = w.state.position.copy()
    x, z = w.state.position[:, 0], w.state.position[:, 2]
    assert x.min() > -30 and x.max() < 40 and z.min() > -30 and z.max() < 40


@pytest.mark.parametrize("model", MODELS)
def test_far_from_origin_crowd_moves_as_at_the_origin(model):
    rng = np.random.default_rng(3)
    xz = rng.uniform(0, 12, (150, 2))
    targets = rng.uniform(0, 12, (150, 2))
    runs = []
    for off in (0.0, 1e6):
        w = world_from_arrays(xz + off, [_goals_to(targets + off), ("avoidance", {"model": model})])
        run_checked(w, 100, 0.05)
        runs.append(w.state.position[:, [0, 2]] - off)
    # only the rounding of absolute coordinates near 1e6 (ulp 1.2e-10) differs
    assert np.abs(runs[0] - runs[1]).max() < 1e-4


_THREADS = textwrap.dedent("""
    import sys, numpy as np
    sys.path.insert(0, {here!r})
    from avoid_testutil import world_from_arrays
    rng = np.random.default_rng(5)
    xz = rng.uniform(0, 15, (600, 2)); xz[1:4] = xz[0]
    tg = rng.uniform(0, 15, (600, 2))
    eff = [("goals", {{"paths": [[[float(a), float(b)]] for a, b in tg], "loop": False}}),
           ("avoidance", {{"model": {model!r}}}),
           ("obstacles", {{"circles": [{{"center": [7.0, 7.0], "radius": 1.5}}],
                           "boxes": [{{"center": [3.0, 10.0], "size": [4.0, 0.5], "yaw": 30.0}}]}})]
    w = world_from_arrays(xz, eff)
    for _ in range(60):
        w.step(0.05)
    print(w.state.digest())
""")


@pytest.mark.parametrize("model", MODELS)
def test_bit_identical_for_one_and_two_threads(model):
    code = _THREADS.format(here=os.path.dirname(__file__), model=model)
    out = []
    for threads in ("1", "2"):
        env = dict(os.environ, NUMBA_NUM_THREADS=threads, PYTHONPATH=str(REPO))
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=REPO,
                           timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
        out.append(r.stdout.strip().splitlines()[-1])
    assert out[0] == out[1]
