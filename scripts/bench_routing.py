"""Benchmark of the ``routing`` effect (issue 28) against JuPedSim, exact shortest paths and a million agents.

Our side runs in this interpreter; JuPedSim 1.4 in the peers interpreter (``--peers-python``, env
``CROWD_PEERS_PYTHON``, default ``.venv-peers/bin/python`` from ``make bench-peers``) as subprocesses: the square
room through ``scripts/bench_avoidance_jps.py`` (job ``bottleneck_scene``: JuPedSim's own navigation mesh routes its
agents to the same waypoint and exits), the route figure through ``scripts/bench_routing_jps.py`` (its
``RoutingEngine``). JuPedSim is never imported here.

Figures:

1. square room (``scenes/square_room.toml``, ``--square``): 100 agents leave a 10 m x 10 m room through a 1 m door in
   one wall (no funnel); both sides get the scene's geometry (JuPedSim: the bounding box minus the scene's walls,
   which are the walkable polygon's outline), the same start positions (the scene's placement with seeds
   ``--seeds``), the collision-free speed model with JuPedSim's default parameters and the same waypoint and
   destinations. Evacuation time = the last agent's first crossing of the door's outer face x = 0.4 m; flow =
   (N - 1) / (t_N - t_1). Target: the median over the seeds of ours within 10 % of JuPedSim's, for both.
2. routes (the U-trap of ``scenes/u_trap.toml``): route length from ten starts to the goal, against the exact
   shortest path kept 0.25 m (the clearance) from the walls (a visibility graph over the corners of the area shrunk
   by the clearance, shapely, independent of ``sim.routing``: tests/sim/routing/routing_testutil.py): ours steering
   at the next corner (the shipped default) and down the distance field's gradient alone, at three grid spacings,
   agents walking kinematically and held off the walls; JuPedSim's navigation-mesh route (A* over a constrained
   Delaunay triangulation and the funnel algorithm; it keeps no clearance but shrinks each portal by 0.2 m). Cost of
   one agent's direction per step: our kernel (ns per agent, 1 M agents) against one JuPedSim route query (us, what
   its tactical level computes for every agent every step). This is the measurement that chose the design
   (docs/routing.md).
3. U-trap crowds (``scenes/u_trap.toml``, 40 agents, cfsm and orca): every agent reaches the goal, the closest any
   body came to a wall, and how much longer the routes are than the exact ones with the crowd around (avoidance
   detours; the routing alone is figure 2).
4. scale: ``--agents`` (1,000,000) agents on a 2 km x 2 km floor with 16 buildings, towards 4 goals (agent i to goal
   i mod 4): the routing per step (``Router.directions``, median of ``--steps`` steps with the agents moving, with
   numba's threads and with one), beside a streaming kernel that only reads the positions and writes the
   directions (the floor of any per-agent step), and the whole ``goals`` step routed against straight. Memory per
   goal (field + vias) and per agent (none kept; the caller's buffers per step), field build time (cold, and loaded
   from the disk cache). Target: routing <= 30 ms per step.

Usage::

    python scripts/bench_routing.py                      # everything; writes scripts/bench_routing.md
    python scripts/bench_routing.py --quick --no-write   # smoke run (2 seeds, 100 K agents)
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "tests" / "sim" / "routing"))  # the exact shortest paths of the tests
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # see scripts/bench_avoidance.py

from bench_avoidance import (
    BenchError,
    bottleneck_ours,
    door_flow,
    load_bottleneck,
    peers_python,
    relative_difference,
    scene_bottleneck_peer,
)

JPS_ROUTES = HERE / "bench_routing_jps.py"
SQUARE = ROOT / "scenes" / "square_room.toml"
U_TRAP = ROOT / "scenes" / "u_trap.toml"
SEEDS = (31, 32, 33, 34, 35)
ROUTE_STARTS = [(0.0, 0.0), (-2.0, 2.5), (2.5, -2.5), (-10.0, 0.0), (-10.0, 7.0), (0.0, 8.0), (8.0, 7.0),
                (-3.5, 0.5), (3.0, 3.0), (12.0, -8.0)]
CELLS = (0.25, 0.125, 0.0625)
#: the scale figure's floor: 2 km square, 16 buildings of 60 m x 40 m, goals near the middle of each side
SCALE_HALF = 1000.0
SCALE_BUILDINGS = [{"center": [x, z], "size": [60.0, 40.0]} for x in (-600.0, -200.0, 200.0, 600.0)
                   for z in (-600.0, -200.0, 200.0, 600.0)]
SCALE_GOALS = [(-990.0, 0.0), (990.0, 0.0), (0.0, -990.0), (0.0, 990.0)]


# ---------------------------------------------------------------------------------------------------------------------
# arithmetic (tested in tests/scripts/test_bench_routing.py)
# ---------------------------------------------------------------------------------------------------------------------


def medians(runs: list) -> dict:
    """Median evacuation time and mean flow over runs of ``door_flow`` figures (None where a run has none)."""
    def med(key):
        v = [r[key] for r in runs if r.get(key) is not None]
        return statistics.median(v) if v else None
    return {"evacuation_time": med("evacuation_time"), "mean_flow": med("mean_flow"),
            "crossed": min(r["crossed"] for r in runs) if runs else 0}


def excess(lengths, exact) -> np.ndarray:
    """Relative excess of route lengths over the exact ones."""
    exact = np.asarray(exact, np.float64)
    return (np.asarray(lengths, np.float64) - exact) / exact


def grid_agents(n: int, half: float, seed: int = 0) -> np.ndarray:
    """(n, 2) float64 agents on a jittered square grid over [-half, half]^2, row by row (neighbours near in memory,
    as scenes/million.toml places them)."""
    side = int(math.ceil(math.sqrt(n)))
    step = 2.0 * half / side
    i = np.arange(n)
    rng = np.random.default_rng(seed)
    xz = np.empty((n, 2))
    xz[:, 0] = -half + step * (0.5 + i % side) + rng.uniform(-0.25, 0.25, n) * step
    xz[:, 1] = -half + step * (0.5 + i // side) + rng.uniform(-0.25, 0.25, n) * step
    return xz


# ---------------------------------------------------------------------------------------------------------------------
# 1. square room
# ---------------------------------------------------------------------------------------------------------------------


def square_room(py: str | None, seeds, max_time: float) -> dict:
    """Per seed: ours and JuPedSim's door figures (``door_flow``) on the square room."""
    out = {"ours": [], "jps": [], "seeds": list(seeds), "n": None, "jupedsim": None}
    for s in seeds:
        b = load_bottleneck(SQUARE, seed=s)
        out["n"] = int(b["positions"].shape[0])
        o = bottleneck_ours(b, max_time)
        out["ours"].append({**door_flow(o["crossing_times"]), "closest": o["min_distance"]})
        if py:
            j = scene_bottleneck_peer(py, b, max_time)
            out["jps"].append({**door_flow(j["crossing_times"]), "closest": j["min_distance"]})
            out["jupedsim"] = j["jupedsim"]
    return out


# ---------------------------------------------------------------------------------------------------------------------
# 2. routes
# ---------------------------------------------------------------------------------------------------------------------


def u_trap_geometry():
    from crowd.scene import load_scene
    from sim.routing.effect import walkable_of

    sc = load_scene(U_TRAP)
    eff = {e.name: e.params for e in sc.effects}
    w = walkable_of(eff["routing"], eff["obstacles"])
    goal = tuple(eff["goals"]["paths"][0][0])
    return w, eff, goal


def walk(router, gid, starts, goal, obstacles, clearance, v=1.34, dt=0.05, arrive=0.3, steps=4000) -> tuple:
    """Route lengths of kinematic agents steered by ``router`` and held off the walls as the obstacles effect holds
    them (its numba projection); (lengths, reached)."""
    from sim.obstacles import _project_kernel, polygon_boxes

    starts = np.asarray(starts, np.float64)
    pos = np.zeros((len(starts), 3))
    pos[:, 0], pos[:, 2] = starts[:, 0], starts[:, 1]
    L, done = np.zeros(len(starts)), np.zeros(len(starts), bool)
    out, dist = np.zeros((len(starts), 2)), np.zeros(len(starts))
    pbox = polygon_boxes(obstacles.verts, obstacles.pstart)
    for _ in range(steps):
        router.directions(pos, np.where(done, -1, gid), out, dist)
        d = np.hypot(pos[:, 0] - goal[0], pos[:, 2] - goal[1])
        new = ~done & (d < arrive)
        L[new] += d[new]
        done |= new
        if done.all():
            break
        old = pos.copy()
        pos[:, 0] += out[:, 0] * v * dt
        pos[:, 2] += out[:, 1] * v * dt
        _project_kernel(pos, np.zeros_like(pos), np.ascontiguousarray(old[:, [0, 2]]), True, obstacles.circles,
                        obstacles.verts, obstacles.pstart, obstacles.pbound, clearance, pbox)
        L += np.where(done, 0.0, np.hypot(pos[:, 0] - old[:, 0], pos[:, 2] - old[:, 2]))
    return L, done


def routes(py: str | None) -> dict:
    from routing_testutil import ExactPaths

    from sim.obstacles import ObstacleSet
    from sim.routing.router import Router

    w, eff, goal = u_trap_geometry()
    clearance = eff["routing"]["clearance"]
    obs = ObstacleSet.from_config(eff["obstacles"])
    exact = np.array([ExactPaths(w.area, clearance).length(s, goal) for s in ROUTE_STARTS])
    exact0 = np.array([ExactPaths(w.area, 1e-9).length(s, goal) for s in ROUTE_STARTS])
    rows = []
    for steering in ("corners", "gradient"):
        for cell in CELLS:
            t = time.perf_counter()
            r = Router(w, clearance, cell=cell, steering=steering, use_cache=False)
            gid = r.goal(("point", goal))
            build = time.perf_counter() - t
            L, done = walk(r, gid, ROUTE_STARTS, goal, obs, clearance)
            e = excess(L, exact)
            rows.append({"steering": steering, "cell": cell, "build": build, "reached": int(done.sum()),
                         "max": float(e.max()), "median": float(np.median(e)), "min": float(e.min()),
                         "nodes": r.grid.nodes})
    out = {"exact": exact.tolist(), "exact0": exact0.tolist(), "rows": rows, "jps": None}
    if py:
        import shapely

        job = {"kind": "routes", "area": shapely.to_wkt(w.area), "starts": [list(s) for s in ROUTE_STARTS],
               "goal": list(goal), "repeat": 5}
        j = run_job(py, JPS_ROUTES, job)
        e = excess(j["lengths"], exact)
        out["jps"] = {"max": float(e.max()), "median": float(np.median(e)), "min": float(e.min()),
                      "us_per_query": j["us_per_query"], "jupedsim": j["jupedsim"],
                      "vs_exact0": float(np.max(excess(j["lengths"], exact0)))}
    return out


def run_job(python: str, script: Path, job: dict, timeout: float = 3600) -> dict:
    r = subprocess.run([python, str(script)], input=json.dumps(job), capture_output=True, text=True, timeout=timeout)
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["no output"])[-1]
        raise BenchError(f"JuPedSim job {job['kind']!r} failed in {python}: {last}")
    return json.loads(r.stdout)


# ---------------------------------------------------------------------------------------------------------------------
# 3. U-trap crowds
# ---------------------------------------------------------------------------------------------------------------------


def u_trap_crowds() -> list:
    from routing_testutil import ExactPaths
    from test_scenes import build, run_to_goal

    w, eff, goal = u_trap_geometry()
    ex = ExactPaths(w.area, eff["routing"]["clearance"])
    rows = []
    for model in ("cfsm", "orca"):
        sc, world = build(U_TRAP, model)
        start = world.state.position[:, [0, 2]].copy()
        t = time.perf_counter()
        L, reached, closest = run_to_goal(sc, world)
        exact = np.array([ex.length(s, goal) for s in start])
        openspace = ex.in_open_space(start)
        e = excess(L, exact)[openspace]
        alone = []
        for i in np.nonzero(openspace)[0]:  # each agent alone: the model's route without the crowd's detours
            sc1, w1 = build(U_TRAP, model, only=[int(i)])
            L1, ok1, c1 = run_to_goal(sc1, w1)
            alone.append(float(excess(L1, exact[i:i + 1])[0]) if ok1.all() else math.inf)
            closest = min(closest, c1)
        rows.append({"model": model, "agents": int(start.shape[0]), "reached": int(reached.sum()),
                     "closest": closest, "median": float(np.median(e)), "p90": float(np.quantile(e, 0.9)),
                     "max": float(e.max()), "alone_median": float(np.median(alone)), "alone_max": float(max(alone)),
                     "wall": time.perf_counter() - t})
    return rows


# ---------------------------------------------------------------------------------------------------------------------
# 4. scale
# ---------------------------------------------------------------------------------------------------------------------


def _stream_kernel():
    from numba import njit, prange

    @njit(parallel=True, cache=True)
    def stream(pos, goal, out, dist):
        """The floor of a per-agent step: read a position and a goal id, write a unit direction and a length."""
        for a in prange(pos.shape[0]):
            x, z = pos[a, 0], pos[a, 2]
            ll = math.sqrt(x * x + z * z) + 1e-9 + goal[a]
            out[a, 0] = x / ll
            out[a, 1] = z / ll
            dist[a] = ll

    return stream


def scale(n: int, steps: int) -> dict:
    import numba

    from sim.routing.geometry import Walkable
    from sim.routing.router import Router

    w = Walkable.from_config({"bounds": [-SCALE_HALF, -SCALE_HALF, SCALE_HALF, SCALE_HALF]},
                             {"boxes": SCALE_BUILDINGS})
    with tempfile.TemporaryDirectory(prefix="bench-routing-cache-") as d:
        old = os.environ.get("CROWD_CACHE_DIR")
        os.environ["CROWD_CACHE_DIR"] = d  # a cold cache, then a warm one
        try:
            t = time.perf_counter()
            r = Router(w, 0.25)
            init = time.perf_counter() - t
            cold = []
            for g in SCALE_GOALS:
                t = time.perf_counter()
                r.goal(("point", g))
                cold.append(time.perf_counter() - t)
            r2 = Router(w, 0.25)
            t = time.perf_counter()
            for g in SCALE_GOALS:
                r2.goal(("point", g))
            warm = (time.perf_counter() - t) / len(SCALE_GOALS)
        finally:
            if old is None:
                os.environ.pop("CROWD_CACHE_DIR", None)
            else:
                os.environ["CROWD_CACHE_DIR"] = old
    xz = grid_agents(n, SCALE_HALF - 1.0)
    code = w.where(xz)
    xz[code != 0, 0] += 70.0  # out of the buildings (70 m east of a 60 m wide one is outside it)
    pos = np.zeros((n, 3))
    pos[:, 0], pos[:, 2] = xz[:, 0], xz[:, 1]
    gid = (np.arange(n) % len(SCALE_GOALS)).astype(np.int64)
    out, dist = np.empty((n, 2)), np.empty(n)
    stream = _stream_kernel()
    res = {"n": n, "goals": len(SCALE_GOALS), "init": init, "cold": cold, "warm": warm,
           "bytes_per_goal": r.bytes_per_goal, "nodes": r.grid.nodes, "cell": r.grid.h,
           "corners": int(r.corners.shape[0]), "threads": {}}
    prev = numba.get_num_threads()
    try:
        for th in sorted({numba.config.NUMBA_NUM_THREADS, 1}, reverse=True):
            numba.set_num_threads(th)
            r.directions(pos, gid, out, dist)
            stream(pos, gid, out, dist)
            ms, floor, cpu = [], [], []
            for _ in range(steps):
                pos[:, 0] += out[:, 0] * 0.05  # the agents move a little between steps
                pos[:, 2] += out[:, 1] * 0.05
                t, c = time.perf_counter(), time.process_time()
                r.directions(pos, gid, out, dist)
                ms.append((time.perf_counter() - t) * 1e3)
                cpu.append((time.process_time() - c) * 1e3)
                t = time.perf_counter()
                stream(pos, gid, out, dist)
                floor.append((time.perf_counter() - t) * 1e3)
            res["threads"][th] = {"ms": statistics.median(ms), "floor": statistics.median(floor),
                                  "ratio": statistics.median(np.array(ms) / np.array(floor)),
                                  "cpu": statistics.median(cpu)}
    finally:
        numba.set_num_threads(prev)
    res["goals_step"] = goals_step(r, pos, steps)
    return res


def goals_step(router, pos, steps: int) -> dict:
    """ms per ``goals`` step (kinematic: no boids) of the same agents, routed and straight, interleaved."""
    import sim.goals as goals_mod
    from sim.params import validate
    from sim.state import CrowdState
    from sim.world import World

    n = pos.shape[0]
    paths = [[list(g)] for g in SCALE_GOALS]
    out = {}
    worlds = {}
    for label in ("routed", "straight"):
        st = CrowdState.empty(n)
        st.position[:] = pos
        w = World(state=st, characters=[], seed=0)
        if label == "routed":
            w.resources["routing"] = router
        w.install("goals", validate(goals_mod.PARAMS, {"paths": paths, "loop": False, "speed": 1.34}, "goals"))
        worlds[label] = w
        w.step(0.05)
    times = {k: [] for k in worlds}
    for _ in range(steps):
        for label, w in worlds.items():
            t = time.perf_counter()
            w.step(0.05)
            times[label].append((time.perf_counter() - t) * 1e3)
    for k, v in times.items():
        out[k] = statistics.median(v)
    return out


# ---------------------------------------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------------------------------------


def _f(x, fmt="{:.2f}"):
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def _machine() -> str:
    from bench_avoidance import _machine as m

    return m()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: 2 seeds, 100 K agents, 3 steps")
    ap.add_argument("--peers-python", metavar="PATH", help="interpreter with jupedsim (default $CROWD_PEERS_PYTHON, "
                    "else .venv-peers/bin/python)")
    ap.add_argument("--no-peers", action="store_true", help="skip the JuPedSim side")
    ap.add_argument("--seeds", default=None, help="comma-separated placement seeds of the square room "
                    f"(default {','.join(map(str, SEEDS))})")
    ap.add_argument("--agents", type=int, default=None, help="agents of the scale figure (default 1,000,000)")
    ap.add_argument("--steps", type=int, default=None, help="timed steps of the scale figure (default 10)")
    ap.add_argument("--only", default="square,routes,crowds,scale", help="comma-separated figures to run")
    ap.add_argument("--md", default=str(Path(__file__).with_suffix(".md")), help="markdown output")
    ap.add_argument("--no-write", action="store_true", help="print only")
    a = ap.parse_args(argv)
    try:
        return _main(a)
    except BenchError as e:
        print(f"bench_routing: error: {e}", file=sys.stderr)
        return 2


def _main(a) -> int:
    q = a.quick
    try:
        seeds = [int(s) for s in a.seeds.split(",")] if a.seeds else list(SEEDS[:2] if q else SEEDS)
    except ValueError:
        raise BenchError(f"--seeds {a.seeds!r}: expected comma-separated integers") from None
    n = a.agents if a.agents is not None else (100_000 if q else 1_000_000)
    steps = a.steps if a.steps is not None else (3 if q else 10)
    only = set(a.only.split(","))
    if not only <= {"square", "routes", "crowds", "scale"} or n < 4 or steps < 1 or not seeds:
        raise BenchError("--only takes square, routes, crowds, scale; --agents >= 4, --steps >= 1, one seed at least")
    py = None if a.no_peers else peers_python(a.peers_python)
    import numba

    lines = ["# Routing benchmark (`scripts/bench_routing.py`)", "", f"Machine: {_machine()}.", "",
             f"Command: `python scripts/bench_routing.py {' '.join(sys.argv[1:])}`".rstrip(), ""]
    out = lambda s="": (print(s, flush=True), lines.append(s))

    threads = numba.get_num_threads()
    numba.set_num_threads(1)  # behaviour runs: one thread (bit-identical; cheaper on a shared 2-core machine)
    if "square" in only:
        sq = square_room(py, seeds, 240.0)
        out(f"## 1. Square room: `scenes/square_room.toml`, {sq['n']} agents, 1.0 m door, no funnel")
        out()
        out("Both sides: the scene's geometry (JuPedSim's walkable area is the bounding box of agents, walls and "
            "waypoints grown by 2 m minus the walls), start positions (the scene's placement with each seed), the "
            "collision-free speed model with JuPedSim's defaults (a = 8, D = 0.1 m, b = 5, D_w = 0.02 m, T = 1 s, "
            "v0 = 1.34 m/s, r = 0.2 m, dt = 0.05 s), the waypoint 1.1 m past the door (reached within 0.5 m) and "
            "then one of five destinations across the hall (agent i takes i mod 5). JuPedSim routes with its "
            "navigation mesh, ours with the `routing` effect (clearance 0.2 m, next-corner steering). "
            "Evacuation time: the last first crossing of x = 0.4 m; flow (N - 1) / (t_N - t_1).")
        out()
        out("| seed | ours evacuation s | JuPedSim evacuation s | ours flow 1/s | JuPedSim flow 1/s | ours closest "
            "pair m | JuPedSim closest pair m |")
        out("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        for k, s in enumerate(seeds):
            o = sq["ours"][k]
            j = sq["jps"][k] if sq["jps"] else {}
            out(f"| {s} | {_f(o['evacuation_time'])} | {_f(j.get('evacuation_time'))} | "
                f"{_f(o['mean_flow'], '{:.3f}')} | {_f(j.get('mean_flow'), '{:.3f}')} | {_f(o['closest'], '{:.3f}')}"
                f" | {_f(j.get('closest'), '{:.3f}')} |")
        mo = medians(sq["ours"])
        out(f"| median | {_f(mo['evacuation_time'])} | " + (
            f"{_f(medians(sq['jps'])['evacuation_time'])} | {_f(mo['mean_flow'], '{:.3f}')} | "
            f"{_f(medians(sq['jps'])['mean_flow'], '{:.3f}')} | | |" if sq["jps"] else
            f"– | {_f(mo['mean_flow'], '{:.3f}')} | – | | |"))
        out()
        out(f"- every agent left: ours {mo['crossed']} of {sq['n']} in every run" + (
            f", JuPedSim {medians(sq['jps'])['crossed']}" if sq["jps"] else ""))
        if sq["jps"]:
            mj = medians(sq["jps"])
            for key, name in (("evacuation_time", "evacuation time"), ("mean_flow", "flow")):
                d = relative_difference(mo[key], mj[key])
                out(f"- {name}, median of {len(seeds)} seeds, ours vs JuPedSim {sq['jupedsim']}: {100 * d:.1f} % "
                    f"(target <= 10 %: {'met' if d <= 0.10 else 'MISSED'})")
        out()

    if "routes" in only:
        rt = routes(py)
        out("## 2. Routes round the U-trap: length against the exact shortest path")
        out()
        out(f"Ten starts (inside the U and round it) to the goal (10, 0) of `scenes/u_trap.toml`; exact: "
            f"{', '.join(_f(x) for x in rt['exact'])} m (0.25 m clearance). Ours: kinematic agents at 1.34 m/s, "
            "dt = 0.05 s, held off the walls by the obstacles' projection; excess = route / exact - 1.")
        out()
        out("| steering | cell m | nodes | field build s | reached | excess median | excess max | excess min |")
        out("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        for r in rt["rows"]:
            out(f"| {r['steering']} | {r['cell']:g} | {r['nodes']:,} | {r['build']:.2f} | {r['reached']}/10 | "
                f"{100 * r['median']:.2f} % | {100 * r['max']:.2f} % | {100 * r['min']:.2f} % |")
        if rt["jps"]:
            j = rt["jps"]
            out(f"| JuPedSim {j['jupedsim']} navigation mesh (A* + funnel, portals shrunk 0.2 m) | – | – | – | 10/10 "
                f"| {100 * j['median']:.2f} % | {100 * j['max']:.2f} % | {100 * j['min']:.2f} % |")
        out()
        if rt["jps"]:
            out(f"- JuPedSim's routes are shorter than the 0.25 m-clearance ones (its paths keep no clearance: at most "
                f"{100 * rt['jps']['vs_exact0']:.2f} % over the zero-clearance shortest path); one route query "
                f"costs {rt['jps']['us_per_query']:.1f} us, which its tactical level pays for every agent every "
                f"step: {rt['jps']['us_per_query']:.1f} s per step for a million agents on one core.")
        out()

    if "crowds" in only:
        cr = u_trap_crowds()
        out("## 3. U-trap crowds: `scenes/u_trap.toml`, 40 agents (20 inside the U)")
        out()
        out("| model | reached | closest centre to a wall m (body radius 0.25) | route excess in the crowd: median | "
            "p90 | max | each agent alone: median | max | wall s |")
        out("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        for r in cr:
            out(f"| {r['model']} | {r['reached']}/{r['agents']} | {r['closest']:.4f} | {100 * r['median']:.1f} % | "
                f"{100 * r['p90']:.1f} % | {100 * r['max']:.1f} % | {100 * r['alone_median']:.2f} % | "
                f"{100 * r['alone_max']:.2f} % | {r['wall']:.1f} |")
        out()
        out("Excess over the exact shortest path of the agents starting in open space (all 40 here). In the crowd it is "
            "the crowd's: 40 agents queue round the same arm end and converge on one goal point. Alone, each agent "
            "walks the model's route: cfsm's wall repulsion keeps it a few centimetres off the clearance arcs. The "
            "routing alone (kinematic) is figure 2. Target: 3 % (tests/sim/routing/test_scenes.py).")
        out()

    numba.set_num_threads(threads)
    if "scale" in only:
        sc = scale(n, steps)
        out(f"## 4. Scale: {sc['n']:,} agents towards {sc['goals']} goals on a 2 km x 2 km floor with 16 buildings")
        out()
        out(f"Grid {sc['cell']:g} m ({sc['nodes']:,} nodes; the default spacing grows past 4 M nodes), "
            f"{sc['corners']} corners. Field build per goal: cold {', '.join(f'{x:.1f}' for x in sc['cold'])} s, "
            f"loaded from the disk cache {sc['warm'] * 1e3:.0f} ms; router set-up (raster, corners) "
            f"{sc['init']:.1f} s.")
        out()
        out("| numba threads | routing ms/step (median) | its CPU ms (all threads) | streaming floor ms/step | "
            "routing / floor |")
        out("| ---: | ---: | ---: | ---: | ---: |")
        for th, v in sorted(sc["threads"].items(), reverse=True):
            out(f"| {th} | {v['ms']:.1f} | {v['cpu']:.1f} | {v['floor']:.1f} | {v['ratio']:.1f} |")
        out()
        best = sc["threads"][max(sc["threads"])]["ms"]
        out(f"- routing for {sc['n']:,} agents: {best:.1f} ms per step (target <= 30 ms: "
            f"{'met' if best <= 30 else 'MISSED'}{'' if sc['n'] == 1_000_000 else ', not the 1 M figure'})")
        out(f"- memory per goal: {sc['bytes_per_goal'] / 2**20:.1f} MiB (float32 field + int16 vias, "
            f"{sc['bytes_per_goal'] / sc['nodes']:.0f} bytes per node); per agent: none kept by the router; the "
            "caller's buffers per step: 16 (direction) + 8 (route length) + 8 (goal id) bytes")
        g = sc["goals_step"]
        out(f"- the whole `goals` step (kinematic) for the same agents: routed {g['routed']:.1f} ms, straight "
            f"{g['straight']:.1f} ms")
        out()
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    if not a.no_write:
        from sim.atomic_io import atomic_open

        with atomic_open(a.md, "w") as f:
            f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
