"""Benchmark of the ``avoidance`` effect (model ``cfsm``) against JuPedSim and pedestrian data (issue 19).

Our side runs each scenario through the simulation engine (``sim.world.World`` with the effects ``goals``,
``avoidance`` (cfsm) and ``obstacles``, stepped by ``World.step`` as ``crowd run`` does, without rendering) in this
interpreter. The JuPedSim side (its ``CollisionFreeSpeedModel``, Tordeux, Chraibi & Seyfried 2016, the model our
``cfsm`` follows) is ``scripts/bench_avoidance_jps.py`` run as a subprocess in the peers interpreter (``--peers-python``,
env ``CROWD_PEERS_PYTHON``, default ``.venv-peers/bin/python`` made by ``make bench-peers``); it prints JSON. JuPedSim
is never imported here. Both sides get the same initial positions, geometry and parameters (JuPedSim's defaults:
a = 8, D = 0.1 m, b = 5, D_w = 0.02 m, T = 1 s, v0 = 1.34 m/s, r = 0.2 m, dt = 0.05 s).

Parameter sets: the comparison with JuPedSim (bottleneck times and flows, speed) uses JuPedSim's defaults on both
sides. The figures against pedestrian data (corridor vs Weidmann, bottleneck specific flow) use one set for every
density and both scenarios: the same but the time gap T = 0.65 s (EMPIRICAL_TIME_GAP). Why: the collision-free
speed model walks at min(v0, (spacing - 2r) / T); with T = 1 s the dense corridor is 26 - 37 % slower than
Weidmann (measured at 1.5 and 2.8 /m^2) and the door passes 1.0 - 1.1 /(m s) (JuPedSim too), below the data.
T = 0.65 s was chosen once from a sweep of T = 0.5 / 0.65 / 0.8 s over the corridor densities (0.8 s: -22 % at
2.7 /m^2; 0.5 s: +35 % at 1.6 /m^2); the .md shows T = 1 s beside it.

Figures:

1. bottleneck: ``scenes/bottleneck.toml`` (``--bottleneck``; a funnel room 10 m deep emptying through a 1.0 m door at
   x = 0; its agents, walls, goals and cfsm parameters) on both sides: JuPedSim gets the scene's walls (its walkable
   area: the bounding box minus them), its agents' start positions and its goals paths as waypoint and exit stages.
   Evacuation time = the last agent's first crossing of x = 0.4 (LINE_X); mean flow = (N - 1) / (t_N - t_1) over
   the crossing times; specific flow = flow / door width. Targets: ours vs JuPedSim within 10 % (time and flow);
   specific flow in 1.2 - 2.2 /(m s) (Seyfried et al. 2009, Kretz et al. 2006).
2. corridor: 70 m x 4 m corridor, unidirectional; agents start at density rho (dart throwing, 0.42 m apart at
   least) in x in [-30, 10], z in [-1.8, 1.8] and walk to +x; PedPy (crowd.report.pedestrian.analyse on the run's
   trajectories.txt) measures the classic density and mean individual speed in the area x in [-12, -8] over
   t in [2, 12] s (inside the crowd, before the front's rarefaction arrives). The same parameter set for every
   density. Target: mean speed within 25 % of Weidmann's v(rho) = v0 (1 - exp(-gamma (1/rho - 1/rho_max))),
   v0 = 1.34 m/s, rho_max = 5.4 /m^2, gamma = 1.913 /m^2, for measured densities 0.5 - 3 /m^2.
3. speed: ms per step at 10 K / 50 K / 100 K agents, ours and JuPedSim in one run, same scenario (a square room,
   agents 1 m apart on a grid in its west half, all walking to the middle of the east wall; median of ``--steps``
   steps after ``--warmup``), target >= 10x faster at 10 K and 50 K; 1 M agents ours only (target <= 300 ms/step);
   bytes per agent (resident memory growth from before the world is built to after the steps, / n).

Usage::

    python scripts/bench_avoidance.py                       # everything; writes scripts/bench_avoidance.md
    python scripts/bench_avoidance.py --quick --no-write    # smoke run (small, short)
    python scripts/bench_avoidance.py --peers-python /work/peers-venv/bin/python
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
# numba's OpenMP threads spin while they wait by default: on this shared 2-core machine (load 10+) that made the
# 2-thread step 16x slower than with passive waiting (2,000 agents: 100 ms vs 6 ms); set before numba loads OpenMP
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from crowd.report.pedestrian import (  # noqa: E402
    WEIDMANN_GAMMA,
    WEIDMANN_RHO_MAX,
    WEIDMANN_V0,
    weidmann_speed,
)

JPS_SCRIPT = Path(__file__).resolve().parent / "bench_avoidance_jps.py"
PEERS_ENV = "CROWD_PEERS_PYTHON"
DEFAULT_PEERS = ".venv-peers/bin/python"

DT = 0.05
RADIUS = 0.2
V0 = 1.34
#: JuPedSim's CollisionFreeSpeedModel defaults; ours under the same names (sim.avoidance.effect PARAMS)
MODEL = {"strength_neighbor_repulsion": 8.0, "range_neighbor_repulsion": 0.1, "strength_geometry_repulsion": 5.0,
         "range_geometry_repulsion": 0.02}
TIME_GAP = 1.0

# bottleneck geometry
ROOM = (-10.0, 0.0, -5.0, 5.0)
WALL = (0.0, 0.4)
DOOR_WIDTH = 1.0
LINE_X = 0.4
#: first waypoint of every agent, 0.5 m beyond the door's outer face: reached (within 0.5 m) only once out of the
#: room. A waypoint at the door centre (as scenes/bottleneck.toml has) can be "reached" by an agent the crowd then
#: pushes back into the room, which then walks straight at the next target into the wall beside the door and stays
#: there (our goals steer straight, JuPedSim routes around walls): 5 of 40 agents in the quick run did.
WAYPOINT = (0.9, 0.0)
EXIT_Z = (-8.0, -4.0, 0.0, 4.0, 8.0)  # JuPedSim exits at x in [11, 12]; ours walk the same directions on to x = 30
# corridor geometry
CORRIDOR_START = (-30.0, 10.0, -1.8, 1.8)
CORRIDOR_AREA = (-12.0, -8.0, -2.0, 2.0)
CORRIDOR_WINDOW = (2.0, 12.0)
DENSITIES = (0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0)
JUDGED = (0.5, 3.0)
#: the one parameter set of the figures against pedestrian data (corridor vs Weidmann, bottleneck specific flow):
#: JuPedSim's defaults but the time gap T (see the module docstring); the comparison with JuPedSim uses T = TIME_GAP
EMPIRICAL_TIME_GAP = 0.65


class BenchError(Exception):
    """Bad option or missing peer interpreter: one sentence, exit 2."""


# ---------------------------------------------------------------------------------------------------------------------
# the figures' arithmetic (tested in tests/scripts/test_bench_avoidance.py)
# ---------------------------------------------------------------------------------------------------------------------


def door_flow(crossing_times) -> dict:
    """Evacuation figures from the first crossing time of every agent (None = never crossed).

    Returns ``crossed``, ``evacuation_time`` (the last crossing, s), ``mean_flow`` ((N - 1) / (t_N - t_1), 1/s;
    None for fewer than two crossings or one instant), ``steady_flow`` (the same between the crossings at 10 % and
    90 % of N: the start and the last stragglers left out)."""
    t = np.sort(np.array([x for x in crossing_times if x is not None], np.float64))
    out = {"crossed": int(t.size), "evacuation_time": float(t[-1]) if t.size else None, "mean_flow": None,
           "steady_flow": None}
    if t.size >= 2 and t[-1] > t[0]:
        out["mean_flow"] = (t.size - 1) / float(t[-1] - t[0])
    i, j = int(round(0.1 * (t.size - 1))), int(round(0.9 * (t.size - 1)))
    if j > i and t[j] > t[i]:
        out["steady_flow"] = (j - i) / float(t[j] - t[i])
    return out


def relative_difference(a: float, b: float) -> float:
    """|a - b| / b."""
    return abs(a - b) / abs(b)


def weidmann_error(rho: float, v: float) -> float:
    """Relative difference of a measured mean speed ``v`` from Weidmann's speed at the measured density ``rho``."""
    return relative_difference(v, float(weidmann_speed(rho)))


def dart_positions(n: int, box, min_distance: float, seed: int, max_tries: int = 2_000_000) -> np.ndarray:
    """(n, 2) float64 points (x, z) uniform in ``box`` = (x0, x1, z0, z1), every pair >= ``min_distance`` apart
    (random sequential dart throwing on a cell grid). Raises BenchError when ``n`` do not fit in ``max_tries``."""
    x0, x1, z0, z1 = box
    rng = np.random.default_rng(seed)
    cell = min_distance
    nx, nz = max(1, int(math.ceil((x1 - x0) / cell))), max(1, int(math.ceil((z1 - z0) / cell)))
    grid = {}
    out = []
    tries = 0
    while len(out) < n:
        cand = rng.uniform((x0, z0), (x1, z1), (4096, 2))
        for x, z in cand:
            tries += 1
            if tries > max_tries:
                raise BenchError(f"{n} agents do not fit {min_distance} m apart in {box} ({len(out)} placed)")
            cx, cz = min(nx - 1, int((x - x0) / cell)), min(nz - 1, int((z - z0) / cell))
            ok = True
            for i in range(cx - 1, cx + 2):
                for k in range(cz - 1, cz + 2):
                    for (px, pz) in grid.get((i, k), ()):
                        if (px - x) ** 2 + (pz - z) ** 2 < min_distance * min_distance:
                            ok = False
                            break
                    if not ok:
                        break
                if not ok:
                    break
            if ok:
                grid.setdefault((cx, cz), []).append((x, z))
                out.append((x, z))
                if len(out) == n:
                    break
    return np.array(out, np.float64)


def room_positions(n: int) -> tuple:
    """The speed scenario: n agents 1 m apart on a grid in the west half of a square room.

    Returns (positions (n, 2), room (x0, x1, z0, z1), target (x, z) = middle of the east wall, 1 m inside)."""
    rows = int(math.ceil(math.sqrt(2 * n)))
    cols = int(math.ceil(n / rows))
    half = rows / 2.0 + 0.5
    i = np.arange(n)
    pos = np.empty((n, 2), np.float64)
    pos[:, 0] = -half + 1.0 + (i // rows)
    pos[:, 1] = -half + 1.0 + (i % rows)
    assert cols <= rows
    return pos, (-half, half, -half, half), (half - 1.0, 0.0)


# ---------------------------------------------------------------------------------------------------------------------
# our side
# ---------------------------------------------------------------------------------------------------------------------


def _boxes_around(x0, x1, z0, z1, t=0.5) -> list:
    """Four wall boxes of thickness ``t`` whose inner faces are the rectangle's sides."""
    w, h = x1 - x0, z1 - z0
    return [{"center": [x0 - t / 2, (z0 + z1) / 2], "size": [t, h + 2 * t]},
            {"center": [x1 + t / 2, (z0 + z1) / 2], "size": [t, h + 2 * t]},
            {"center": [(x0 + x1) / 2, z0 - t / 2], "size": [w, t]},
            {"center": [(x0 + x1) / 2, z1 + t / 2], "size": [w, t]}]


def our_world(positions: np.ndarray, paths: list, boxes: list, arrive_radius: float = 0.5,
              time_gap: float = TIME_GAP):
    """A ``sim.world.World`` of agents at ``positions`` (n, 2) with the effects goals (``paths``, assigned
    cycle), avoidance (cfsm, JuPedSim's parameters) and obstacles (``boxes``), in the scenes' order."""
    from sim.params import validate
    from sim.state import CrowdState
    from sim.systems import effect_module
    from sim.world import World

    n = positions.shape[0]
    st = CrowdState.empty(n)
    st.position[:, 0] = positions[:, 0]
    st.position[:, 2] = positions[:, 1]
    st.heading[:] = math.pi / 2
    world = World(state=st, characters=[], seed=0)
    effects = [("goals", {"paths": paths, "loop": False, "speed": V0, "arrive_radius": arrive_radius}),
               ("avoidance", {"model": "cfsm", "radius": RADIUS, "time_gap": time_gap, "v0": V0, **MODEL}),
               ("obstacles", {"agent_radius": RADIUS, "boxes": boxes})]
    for name, table in effects:
        world.install(name, validate(effect_module(name).PARAMS, table, name))
    return world


def bottleneck_boxes() -> list:
    x0, x1, z0, z1 = ROOM
    w0, w1 = WALL
    t = 0.4
    hw = DOOR_WIDTH / 2
    return [{"center": [(w0 + w1) / 2, (hw + z1 + t) / 2], "size": [w1 - w0, z1 + t - hw]},
            {"center": [(w0 + w1) / 2, -(hw + z1 + t) / 2], "size": [w1 - w0, z1 + t - hw]},
            {"center": [x0 - t / 2, 0.0], "size": [t, z1 - z0 + 2 * t]},
            {"center": [(x0 + w0) / 2, z1 + t / 2], "size": [w0 - x0 + t, t]},
            {"center": [(x0 + w0) / 2, z0 - t / 2], "size": [w0 - x0 + t, t]}]


def load_bottleneck(path, seed: int | None = None) -> dict:
    """The bottleneck scene (``scenes/bottleneck.toml``) as both sides need it: the validated scene, its agents'
    start positions (n, 2) (the scene's placement and seed, or ``seed`` instead, ``crowd.plan.plan``), the goals,
    avoidance and obstacles tables, and the obstacles as polygons and circles (``sim.obstacles.ObstacleSet``, boxes
    made polygons).

    Raises BenchError when the scene lacks one of those effects or is invalid."""
    from crowd.plan import plan
    from crowd.errors import CrowdError
    from crowd.scene import load_scene
    from sim.obstacles import ObstacleSet

    try:
        scene = load_scene(path)
    except CrowdError as e:
        raise BenchError(str(e)) from None
    eff = {e.name: e.params for e in scene.effects}
    missing = [k for k in ("goals", "avoidance", "obstacles") if k not in eff]
    if missing or eff["avoidance"]["model"] != "cfsm":
        raise BenchError(f"{path}: the bottleneck scene needs the effects goals, avoidance (model cfsm) and obstacles")
    if seed is not None:
        import dataclasses

        scene = dataclasses.replace(scene, seed=int(seed))
    pl = plan(scene)
    obs = ObstacleSet(eff["obstacles"].get("circles", ()), eff["obstacles"].get("boxes", ()),
                      eff["obstacles"].get("polygons", ()))
    polys = [obs.verts[obs.pstart[k]:obs.pstart[k + 1]].tolist() for k in range(obs.pstart.shape[0] - 1)]
    from sim.avoidance.effect import body_radii
    from sim.world import World

    w = World(state=pl.state, characters=pl.characters, seed=scene.seed)
    w.resources["character_radius"] = [c.radius for c in scene.characters]
    radius = body_radii(w, eff["avoidance"])  # as the effect sizes the bodies
    return {"scene": scene, "plan": pl, "positions": pl.state.position[:, [0, 2]].copy(), "effects": eff,
            "polygons": polys, "circles": obs.circles.tolist(), "radius": radius}


def bottleneck_ours(b: dict, max_time: float, time_gap: float | None = None) -> dict:
    """Our run of the bottleneck scene ``b`` (:func:`load_bottleneck`): its effects but animation (not needed),
    ``time_gap`` overriding the scene's; crossing times of x = LINE_X, smallest pair distance seen."""
    from scipy.spatial import cKDTree

    from sim.state import CrowdState
    from sim.world import World

    src = b["plan"].state
    st = CrowdState(**{k: v.copy() for k, v in src.arrays().items()})
    world = World(state=st, characters=b["plan"].characters, seed=b["scene"].seed)
    world.resources["character_radius"] = [c.radius for c in b["scene"].characters]
    for e in b["scene"].effects:
        if e.name == "animation":
            continue
        cfg = dict(e.params)
        if e.name == "avoidance" and time_gap is not None:
            cfg["time_gap"] = time_gap
        world.install(e.name, cfg)
    return _run_bottleneck(world, max_time)


def _run_bottleneck(world, max_time: float) -> dict:
    from scipy.spatial import cKDTree

    n = world.state.n
    crossing = np.full(n, np.nan)
    min_d = math.inf
    steps, t0 = 0, time.perf_counter()
    while steps < int(round(max_time / DT)) and np.isnan(crossing).any():
        world.step(DT)
        steps += 1
        x = world.state.position[:, 0]
        new = np.isnan(crossing) & (x > LINE_X)
        crossing[new] = steps * DT
        if steps % 10 == 0:
            p = world.state.position[:, [0, 2]]
            d, _ = cKDTree(p).query(p, k=2)
            min_d = min(min_d, float(d[:, 1].min()))
    return {"crossing_times": [None if math.isnan(c) else float(c) for c in crossing], "steps": steps,
            "min_distance": min_d, "wall_seconds": time.perf_counter() - t0}


def square_bottleneck_ours(positions: np.ndarray, max_time: float, time_gap: float = TIME_GAP) -> dict:
    """Our run of a square-room bottleneck (the tests' tiny case; ``bottleneck_boxes``): crossing times of
    x = LINE_X, smallest pair distance seen."""
    wx, wz = WAYPOINT
    # then on in the directions of JuPedSim's exits (centres (11.5, z))
    paths = [[[wx, wz], [30.0, wz + (z - wz) * (30.0 - wx) / (11.5 - wx)]] for z in EXIT_Z]
    return _run_bottleneck(our_world(positions, paths, bottleneck_boxes(), time_gap=time_gap), max_time)


def corridor_ours(density: float, seed: int = 19, window=CORRIDOR_WINDOW, time_gap: float = None) -> dict:
    """One corridor run at the nominal ``density``: PedPy's classic density and mean speed in CORRIDOR_AREA over
    ``window`` (s), from the run's trajectories (crowd.trajectories format)."""
    from crowd.measurement import MeasurementSpec
    from crowd.report.pedestrian import analyse
    from crowd.trajectories import TrajectoryWriter

    x0, x1, z0, z1 = CORRIDOR_START
    n = int(round(density * (x1 - x0) * (z1 - z0)))
    pos = dart_positions(n, CORRIDOR_START, 2 * RADIUS + 0.02, seed)
    boxes = [{"center": [0.0, -2.25], "size": [70.0, 0.5]}, {"center": [0.0, 2.25], "size": [70.0, 0.5]}]
    world = our_world(pos, [[[1000.0, 0.0]]], boxes, arrive_radius=1.0,
                      time_gap=EMPIRICAL_TIME_GAP if time_gap is None else time_gap)
    frames = int(round(window[1] / DT)) + 1
    ax0, ax1, az0, az1 = CORRIDOR_AREA
    area = MeasurementSpec("corridor", polygon=((ax0, az0), (ax1, az0), (ax1, az1), (ax0, az1)))
    with tempfile.TemporaryDirectory(prefix="bench-avoid-") as d:
        path = Path(d) / "trajectories.txt"
        with TrajectoryWriter(path, "corridor", n, DT) as w:
            for f in range(frames):
                world.step(DT)
                w.write(f, world.state.position)
        res = analyse(path, [area], voronoi=False)[0]["area"]
    t = np.asarray(res["time"])
    sel = (t >= window[0]) & (t <= window[1])
    rho = float(np.mean(np.asarray(res["density"])[sel])) if sel.any() else math.nan
    v = float(np.mean(np.asarray(res["speed"])[sel])) if sel.any() else math.nan
    return {"nominal": density, "agents": n, "density": rho, "speed": v, "weidmann": float(weidmann_speed(rho)),
            "error": weidmann_error(rho, v) if sel.any() else math.nan, "frames": int(sel.sum())}


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def timing_ours(n: int, warmup: int, steps: int, threads: int | None = None) -> dict:
    """ms per step of our speed scenario with ``threads`` numba threads (None: numba's default)."""
    import numba

    prev = numba.get_num_threads()
    numba.set_num_threads(threads or numba.config.NUMBA_NUM_THREADS)
    try:
        return _timing_ours(n, warmup, steps)
    finally:
        numba.set_num_threads(prev)


def _timing_ours(n: int, warmup: int, steps: int) -> dict:
    pos, room, target = room_positions(n)
    before = rss_bytes()
    world = our_world(pos, [[list(target)]], _boxes_around(*room))
    for _ in range(warmup):
        world.step(DT)
    ms, systems = [], {}
    for _ in range(steps):
        t = time.perf_counter()
        world.step(DT, 1, systems)
        ms.append((time.perf_counter() - t) * 1e3)
    return {"ms_per_step": ms, "state_bytes": world.state.nbytes(), "n": n,
            "systems_ms": {k: 1e3 * v / steps for k, v in systems.items()}}


def why_ours(n: int, warmup: int, steps: int) -> dict:
    """Where our step's time goes (1 thread, ms): the whole step with and without the obstacles effect (open plane),
    and the overlap check of ``avoidance.resolve`` called alone on the start positions without a grid to reuse (no
    overlap: one grid build and one scan; in a step the first pass reuses the model's grid, so this is the cost of
    every further pass when agents do overlap) with the layout ``sim.grid`` picks by default
    (``GRID_DENSE_FACTOR``: the resolve grid's 0.4 m cells are 6.25 per agent here, so it hashes them) and with the
    dense layout resolve uses (``RESOLVE_DENSE_FACTOR``)."""
    import numba

    import sim.avoidance.resolve as res
    import sim.grid as grid
    from sim.avoidance.resolve import resolve

    prev = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        pos, room, target = room_positions(n)
        out = {}
        for label, boxes in (("with walls", _boxes_around(*room)), ("open plane", [])):
            world = our_world(pos, [[list(target)]], boxes)
            for _ in range(warmup):
                world.step(DT)
            ms = []
            for _ in range(steps):
                t = time.perf_counter()
                world.step(DT)
                ms.append((time.perf_counter() - t) * 1e3)
            out[label] = statistics.median(ms)
            del world
        p = np.zeros((n, 3))
        p[:, 0], p[:, 2] = pos[:, 0], pos[:, 1]
        r = np.full(n, RADIUS)
        shipped = res.RESOLVE_DENSE_FACTOR
        for label, factor in (("resolve check, default grid (hashed)", grid.GRID_DENSE_FACTOR),
                              ("resolve check, resolve's dense grid", shipped)):
            res.RESOLVE_DENSE_FACTOR = factor
            try:
                resolve(p, r, None, None, 16)
                ts = []
                for _ in range(max(3, steps)):
                    t = time.perf_counter()
                    resolve(p, r, None, None, 16)
                    ts.append((time.perf_counter() - t) * 1e3)
            finally:
                res.RESOLVE_DENSE_FACTOR = shipped
            out[label] = statistics.median(ts)
        return out
    finally:
        numba.set_num_threads(prev)


def memory_probe(n: int) -> dict:
    """Resident memory of our speed scenario with ``n`` agents, measured in this (fresh) process: a 100-agent world
    first (imports, compiled kernels loaded), then the growth of the resident set from before the n-agent world is
    built to after two steps (``rss_bytes``), and of the peak (``peak_bytes``, VmHWM)."""
    pos, room, target = room_positions(100)
    w = our_world(pos, [[list(target)]], _boxes_around(*room))
    w.step(DT)
    w.step(DT)
    del w
    pos, room, target = room_positions(n)
    before, peak0 = rss_bytes(), _vm_hwm()
    world = our_world(pos, [[list(target)]], _boxes_around(*room))
    world.step(DT)
    world.step(DT)
    return {"rss_bytes": rss_bytes() - before, "peak_bytes": _vm_hwm() - peak0, "n": n}


def _vm_hwm() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


def memory_ours(n: int) -> dict:
    """:func:`memory_probe` in a fresh interpreter (this one has run other worlds: freed memory would hide growth)."""
    r = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--memory-probe", str(n)], capture_output=True,
                       text=True, timeout=3600, env={**os.environ, "PYTHONPATH": str(ROOT)})
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["no output"])[-1]
        raise BenchError(f"memory probe of {n} agents failed: {last}")
    return json.loads(r.stdout)


# ---------------------------------------------------------------------------------------------------------------------
# the JuPedSim side (subprocess)
# ---------------------------------------------------------------------------------------------------------------------


def peers_python(option: str | None) -> str:
    """The peers interpreter: --peers-python, else $CROWD_PEERS_PYTHON, else .venv-peers/bin/python (repo root).
    Raises BenchError when it is not an executable file."""
    p = option or os.environ.get(PEERS_ENV) or str(ROOT / DEFAULT_PEERS)
    if not (os.path.isfile(p) and os.access(p, os.X_OK)):
        raise BenchError(f"peers interpreter {p!r} not found: run `make bench-peers` (creates {DEFAULT_PEERS} with "
                         f"jupedsim), pass --peers-python PATH or set {PEERS_ENV}; or --no-peers")
    return p


def run_peer(python: str, job: dict, positions: np.ndarray, timeout: float = 3600) -> dict:
    """Run one job of scripts/bench_avoidance_jps.py in ``python``; returns its JSON."""
    with tempfile.TemporaryDirectory(prefix="bench-avoid-jps-") as d:
        np.save(Path(d) / "pos.npy", positions)
        job = {**job, "positions": str(Path(d) / "pos.npy")}
        r = subprocess.run([python, str(JPS_SCRIPT)], input=json.dumps(job), capture_output=True, text=True,
                           timeout=timeout)
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["no output"])[-1]
        raise BenchError(f"JuPedSim job {job['kind']!r} failed in {python}: {last}")
    return json.loads(r.stdout)


def scene_bottleneck_peer(python: str, b: dict, max_time: float) -> dict:
    """JuPedSim's run of the bottleneck scene ``b`` (:func:`load_bottleneck`): walkable area = the bounding box of
    agents, obstacles and waypoints grown by 2 m minus the obstacles; each goals path's waypoints but the last are
    waypoint stages (distance = arrive_radius), the last an exit (a 2 m square around it); agent i takes path
    i mod paths (the scene's ``assign = "cycle"``); the scene's cfsm parameters."""
    g, av = b["effects"]["goals"], b["effects"]["avoidance"]
    if g.get("assign", "cycle") != "cycle":
        raise BenchError("the bottleneck scene's goals must assign paths by agent (assign = \"cycle\")")
    rad = {float(r) for r in b["radius"]}
    if len(rad) != 1:
        raise BenchError("the bottleneck scene's agents must share one body radius (JuPedSim job: one radius)")
    radius = rad.pop()
    job = {"kind": "bottleneck_scene", "dt": float(b["scene"].dt),
           "model": {k: float(av[k]) for k in MODEL},
           "agent": {"time_gap": float(av["time_gap"]), "desired_speed": float(av["v0"] or g["speed"]),
                     "radius": radius},
           "polygons": b["polygons"], "circles": b["circles"], "paths": g["paths"],
           "arrive_radius": float(g["arrive_radius"]), "line_x": LINE_X, "max_time": max_time}
    return run_peer(python, job, b["positions"])


def bottleneck_peer(python: str, positions: np.ndarray, max_time: float) -> dict:
    job = {"kind": "bottleneck", "dt": DT, "model": MODEL,
           "agent": {"time_gap": TIME_GAP, "desired_speed": V0, "radius": RADIUS},
           "room": list(ROOM), "door": [WALL[0], WALL[1], DOOR_WIDTH / 2],
           "exits": [[11.0, 12.0, z - 1.0, z + 1.0] for z in EXIT_Z], "waypoint": [WAYPOINT[0], WAYPOINT[1], 0.5],
           "outside": [12.0, -12.0, 12.0], "line_x": LINE_X, "max_time": max_time}
    return run_peer(python, job, positions)


def timing_peer(python: str, n: int, warmup: int, steps: int) -> dict:
    pos, room, target = room_positions(n)
    job = {"kind": "timing", "dt": DT, "model": MODEL, "room": list(room), "target": list(target),
           "agent": {"time_gap": TIME_GAP, "desired_speed": V0, "radius": RADIUS}, "warmup": warmup, "steps": steps}
    return run_peer(python, job, pos)


# ---------------------------------------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------------------------------------


def _machine() -> str:
    import numba

    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), cpu)
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, timeout=10).stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        commit = "unknown"
    return (f"commit {commit}; {cpu}, {os.cpu_count()} logical CPUs, numba {numba.__version__} with "
            f"{numba.config.NUMBA_NUM_THREADS} threads (threading layer {numba.config.THREADING_LAYER}, "
            f"OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY')}), numpy {np.__version__}, Python "
            f"{platform.python_version()}; load average at start {os.getloadavg()[0]:.2f}")


def _f(x, fmt="{:.2f}"):
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: 40-agent bottleneck, two densities, 2,000 "
                    "agents for speed, no 1 M run")
    ap.add_argument("--peers-python", metavar="PATH", help=f"interpreter with jupedsim (default ${PEERS_ENV}, else "
                    f"{DEFAULT_PEERS})")
    ap.add_argument("--no-peers", action="store_true", help="skip the JuPedSim side")
    ap.add_argument("--bottleneck", default=str(ROOT / "scenes" / "bottleneck.toml"), metavar="SCENE",
                    help="the bottleneck scene (default scenes/bottleneck.toml)")
    ap.add_argument("--sizes", default=None, help="comma-separated agent counts of the speed figure "
                    "(default 10000,50000,100000)")
    ap.add_argument("--million", type=int, default=1_000_000, help="agents of the ours-only speed run (0 = skip)")
    ap.add_argument("--densities", default=None, help="comma-separated nominal corridor densities /m^2 "
                    "(default 0.5,0.75,1,1.5,2,2.5,3,3.5,4; quick 1,2)")
    ap.add_argument("--steps", type=int, default=None, help="timed steps per size (default 10; quick 3)")
    ap.add_argument("--warmup", type=int, default=2, help="untimed steps before (default 2)")
    ap.add_argument("--md", default=str(Path(__file__).with_suffix(".md")), help="markdown output")
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument("--no-why", dest="why", action="store_false", help="skip the 'why' table (where our time goes)")
    ap.add_argument("--memory-probe", type=int, help=argparse.SUPPRESS)  # internal: memory_ours's subprocess
    a = ap.parse_args(argv)
    if a.memory_probe:
        print(json.dumps(memory_probe(a.memory_probe)))
        return 0
    try:
        return _main(a)
    except BenchError as e:
        print(f"bench_avoidance: error: {e}", file=sys.stderr)
        return 2


def _main(a) -> int:
    q = a.quick
    steps = a.steps if a.steps is not None else (3 if q else 10)
    try:
        sizes = [int(s) for s in (a.sizes or ("2000" if q else "10000,50000,100000")).split(",")]
    except ValueError:
        raise BenchError(f"--sizes {a.sizes!r}: expected comma-separated integers") from None
    try:
        dens = tuple(float(x) for x in a.densities.split(",")) if a.densities else ((1.0, 2.0) if q else DENSITIES)
    except ValueError:
        raise BenchError(f"--densities {a.densities!r}: expected comma-separated numbers") from None
    if not all(0.0 < d <= 4.5 for d in dens):
        raise BenchError(f"--densities {a.densities!r}: expected densities in (0, 4.5] per m^2")
    if steps < 1 or a.warmup < 0 or any(s < 2 for s in sizes) or a.million < 0:
        raise BenchError("--sizes needs >= 2 agents, --steps >= 1, --warmup and --million >= 0")
    million = 0 if q else a.million
    py = None if a.no_peers else peers_python(a.peers_python)
    machine = _machine()
    lines = [f"# Avoidance benchmark (`scripts/bench_avoidance.py`)", "",
             f"Machine: {machine}.", "",
             f"Command: `python scripts/bench_avoidance.py {' '.join(sys.argv[1:])}`".rstrip() + "", "",
             f"Parameters (both sides): CollisionFreeSpeedModel a = {MODEL['strength_neighbor_repulsion']:g}, "
             f"D = {MODEL['range_neighbor_repulsion']:g} m, b = {MODEL['strength_geometry_repulsion']:g}, "
             f"D_w = {MODEL['range_geometry_repulsion']:g} m, T = {TIME_GAP:g} s, v0 = {V0:g} m/s, "
             f"r = {RADIUS:g} m, dt = {DT:g} s (JuPedSim's defaults; ours: the `avoidance` effect, model cfsm, "
             "its other keys at their defaults).", ""]
    out = lambda s="": (print(s), lines.append(s))

    # the behaviour runs (bottleneck, corridor) on one numba thread: the effect is bit-identical for any thread
    # count, and on a shared 2-core machine two spinning threads cost more than they give at a few hundred agents
    import numba

    numba.set_num_threads(1)
    # 1. bottleneck
    b = load_bottleneck(a.bottleneck)
    n_bottle = b["positions"].shape[0]
    max_time = 40.0 + 2.0 * n_bottle
    ours = bottleneck_ours(b, max_time)
    fo = door_flow(ours["crossing_times"])
    shown = os.path.relpath(a.bottleneck, ROOT) if os.path.abspath(a.bottleneck).startswith(str(ROOT)) else a.bottleneck
    out(f"## Bottleneck: `{shown}`, {n_bottle} agents, 1.0 m door")
    out()
    out("The scene's geometry, agents (its placement and seed) and parameters on both sides; JuPedSim's walkable area "
        "is the bounding box of agents, walls and waypoints grown by 2 m minus the walls, each goals path's "
        "waypoints its waypoint stages (distance = arrive_radius) and the last one an exit (2 m square); agent i "
        "takes path i mod 5 on both sides. Ours runs the scene's effects but animation through `World.step`.")
    out()
    out(f"Ours against JuPedSim with JuPedSim's default parameters (T = {TIME_GAP:g} s) on both sides; the "
        f"specific flow against the data (1.2 - 2.2 /(m s)) with the empirical parameter set (T = "
        f"{EMPIRICAL_TIME_GAP:g} s, the corridor's). Flow = (N - 1) / (t_N - t_1) over the first crossings of "
        f"x = {LINE_X:g} m; steady flow between the crossings at 10 % and 90 % of N.")
    out()
    out("| | agents out | evacuation time s | mean flow 1/s | steady flow (10-90 %) 1/s | specific flow 1/(m s) | "
        "closest pair m | wall s |")
    out("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    row = lambda name, f, r: out(
        f"| {name} | {f['crossed']} | {_f(f['evacuation_time'])} | {_f(f['mean_flow'], '{:.3f}')} | "
        f"{_f(f['steady_flow'], '{:.3f}')} | {_f(f['mean_flow'] / DOOR_WIDTH if f['mean_flow'] else None, '{:.3f}')} "
        f"| {_f(r['min_distance'], '{:.3f}')} | {r['wall_seconds']:.1f} |")
    row(f"ours (cfsm), T = {TIME_GAP:g} s", fo, ours)
    fj = None
    if py:
        jps = scene_bottleneck_peer(py, b, max_time)
        fj = door_flow(jps["crossing_times"])
        row(f"JuPedSim {jps['jupedsim']}, T = {TIME_GAP:g} s", fj, jps)
    emp = bottleneck_ours(b, max_time, time_gap=EMPIRICAL_TIME_GAP)
    fe = door_flow(emp["crossing_times"])
    row(f"ours (cfsm), T = {EMPIRICAL_TIME_GAP:g} s (empirical set)", fe, emp)
    out()
    verdicts = []
    if fj and fo["evacuation_time"] and fj["evacuation_time"] and fo["mean_flow"] and fj["mean_flow"]:
        dt_ = relative_difference(fo["evacuation_time"], fj["evacuation_time"])
        df_ = relative_difference(fo["mean_flow"], fj["mean_flow"])
        verdicts.append(f"evacuation time ours vs JuPedSim: {100 * dt_:.1f} % (target <= 10 %: "
                        f"{'met' if dt_ <= 0.10 else 'MISSED'})")
        verdicts.append(f"mean flow ours vs JuPedSim: {100 * df_:.1f} % (target <= 10 %: "
                        f"{'met' if df_ <= 0.10 else 'MISSED'})")
    for f, tg in ((fe, EMPIRICAL_TIME_GAP), (fo, TIME_GAP)):
        if f["mean_flow"]:
            js = f["mean_flow"] / DOOR_WIDTH
            verdicts.append(f"specific flow (ours, T = {tg:g} s) {js:.2f} /(m s) (target 1.2 - 2.2: "
                            f"{'met' if 1.2 <= js <= 2.2 else 'MISSED'})"
                            + (" — the empirical parameter set" if tg == EMPIRICAL_TIME_GAP else ""))
    if fj and fj["mean_flow"]:
        verdicts.append(f"specific flow (JuPedSim, its defaults, T = {TIME_GAP:g} s) "
                        f"{fj['mean_flow'] / DOOR_WIDTH:.2f} /(m s)")
    for v in verdicts:
        out(f"- {v}")
    out()

    # 2. corridor
    window = (1.0, 5.0) if q else CORRIDOR_WINDOW
    out(f"## Corridor: speed against density (Weidmann 1993: v0 = {WEIDMANN_V0} m/s, rho_max = {WEIDMANN_RHO_MAX} "
        f"/m², gamma = {WEIDMANN_GAMMA} /m²)")
    out()
    out(f"Measured by PedPy in x in [{CORRIDOR_AREA[0]:g}, {CORRIDOR_AREA[1]:g}] m over t in [{window[0]:g}, "
        f"{window[1]:g}] s; mean of the per-frame classic density and mean individual speed.")
    out()
    out(f"One parameter set for every density: JuPedSim's defaults with the time gap T = {EMPIRICAL_TIME_GAP:g} s "
        f"(the figure's set); the rows at T = {TIME_GAP:g} s (JuPedSim's default) show why: the collision-free "
        "speed model's speed is (spacing - 2r) / T, and T = 1 s is too slow in dense flow.")
    out()
    out("| T s | nominal /m² | agents | measured density /m² | mean speed m/s | Weidmann m/s | speed / Weidmann - 1 "
        "| judged |")
    out("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | :--- |")
    worst = {}
    for tg in (EMPIRICAL_TIME_GAP, TIME_GAP):
        worst[tg] = 0.0
        for rho in dens:
            c = corridor_ours(rho, window=window, time_gap=tg)
            judged = JUDGED[0] <= c["density"] <= JUDGED[1]
            if judged:
                worst[tg] = max(worst[tg], c["error"])
            out(f"| {tg:g} | {rho:g} | {c['agents']} | {c['density']:.2f} | {c['speed']:.3f} | {c['weidmann']:.3f} "
                f"| {100 * (c['speed'] / c['weidmann'] - 1):+.1f} % | {'yes' if judged else 'no (outside 0.5-3)'} |")
    out()
    for tg, w in worst.items():
        out(f"- T = {tg:g} s: largest difference from Weidmann at measured densities 0.5 - 3 /m²: {100 * w:.1f} % "
            f"(target <= 25 %: {'met' if w <= 0.25 else 'MISSED'})" + (" — the figure's parameter set"
                                                                           if tg == EMPIRICAL_TIME_GAP else ""))
    out()

    # 3. speed
    out("## Speed: ms per step (median), same scenario")
    out()
    out(f"Square room, agents 1 m apart on a grid in its west half walking to the middle of the east wall; "
        f"median of {steps} steps after {a.warmup} warm-up steps. Bytes per agent = growth of the resident set from "
        "before the world is built to after two steps (ours: in a fresh interpreter whose kernels are loaded; "
        "JuPedSim: from before its Simulation is made to after the timed steps), / agents; ours' peak in brackets.")
    out()
    nt = numba.config.NUMBA_NUM_THREADS
    out(f"| agents | ours ms/step ({nt} threads) | ours ms/step (1 thread) | JuPedSim ms/step (1 thread) | "
        "JuPedSim / ours | JuPedSim / ours (1 thread each) | ours bytes/agent | JuPedSim bytes/agent |")
    out("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    breakdown = []
    for n in sizes + ([million] if million else []):
        o = timing_ours(n, a.warmup, steps)
        mo = statistics.median(o["ms_per_step"])
        o1 = timing_ours(n, a.warmup, steps, threads=1) if n != million else None
        m1 = statistics.median(o1["ms_per_step"]) if o1 else None
        j = timing_peer(py, n, a.warmup, steps) if (py and n != million) else None
        mj = statistics.median(j["ms_per_step"]) if j else None
        mem = memory_ours(n)
        breakdown.append((n, o["systems_ms"], nt))
        if o1:
            breakdown.append((n, o1["systems_ms"], 1))
        out(f"| {n:,} | {mo:.2f} | {_f(m1)} | {_f(mj)} | {_f(mj / mo if mj else None, '{:.1f}x')} | "
            f"{_f(mj / m1 if (mj and m1) else None, '{:.1f}x')} | {mem['rss_bytes'] / n:,.0f} "
            f"({mem['peak_bytes'] / n:,.0f}) | "
            f"{_f(j['rss_bytes'] / n if j else None, '{:,.0f}')} |")
    out()
    out("Targets: JuPedSim / ours >= 10 at 10 K and 50 K; ours <= 300 ms/step at 1 M.")
    out()
    out("Ours per system (mean ms per step over the timed steps; `World.step` timings):")
    out()
    names = sorted({k for _, o, _ in breakdown for k in o})
    out("| agents | threads | " + " | ".join(names) + " |")
    out("| ---: | ---: | " + " | ".join("---:" for _ in names) + " |")
    for n, o, th in breakdown:
        out(f"| {n:,} | {th} | " + " | ".join(f"{o.get(k, 0.0):.2f}" for k in names) + " |")
    if not q and a.why:
        out()
        out("Why (ours, 1 thread, median ms per step; measured in this run):")
        out()
        rows = [(n, why_ours(n, a.warmup, steps)) for n in sizes + ([million] if million else [])]
        keys = list(rows[0][1])
        out("| agents | " + " | ".join(keys) + " |")
        out("| ---: | " + " | ".join("---:" for _ in keys) + " |")
        for n, w in rows:
            out(f"| {n:,} | " + " | ".join(f"{w[k]:.1f}" for k in keys) + " |")
    if not a.no_write:
        from sim.atomic_io import write_atomic

        write_atomic(a.md, "\n".join(lines) + "\n")
        print(f"wrote {a.md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
