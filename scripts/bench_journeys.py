"""Journeys and a changing agent count (effect ``journeys``, ``sim/population.py``): what they cost, and whether
the counts follow the configured rates.

1. **A scene that never changes its count pays nothing**: ``scenes/quickstart.toml`` (its world only, no
   renderer) stepped by the engine's ``Engine.step`` (which now asks ``world.agents_changed`` after every step)
   against the same step without that test, interleaved in blocks; and the per-frame telemetry added
   (``crowd.population.frame_counts``) timed alone. Ratio of medians and microseconds per frame.
2. **Compaction**: ``sim.population.apply`` with 1 % of the agents leaving and 1 % entering, at 10 K - 1 M
   agents (ms per change; it runs only on steps whose count changes); bytes per agent the effect keeps.
3. **The journeys' own steps**: ``journeys.leave`` + ``journeys.steer`` + ``journeys.update`` per step for
   crowds of 1 K - 100 K agents walking to a waypoint and out through a door while a source adds 1 % of the crowd
   per second (no avoidance: the journeys alone).
4. **Rates** on ``scenes/concourse.toml`` (simulation only, ``--seconds`` simulated, ``--seeds`` seeds): per source
   the agents entered against the rate (uniform: exact; Poisson: per seed and the mean over seeds, whose deviation
   shrinks as 1 / sqrt(count)), the choices against their weights, the exits, the alive count's identity
   agents = start + entered - left.

Usage::

    PYTHONPATH=$PWD python scripts/bench_journeys.py [--quick] [--md scripts/bench_journeys.md]
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def _world(scene):
    from crowd.plan import plan
    from sim.world import World

    p = plan(scene)
    w = World(state=p.state, characters=p.characters, seed=scene.seed)
    w.resources["character_radius"] = [c.radius for c in scene.characters]
    for e in scene.effects:
        w.install(e.name, e.params)
    return w


# ------------------------------------------------------------------------------------------ 1. constant scene
def constant_cost(frames: int, blocks: int) -> dict:
    from crowd.engine import Engine
    from crowd.population import frame_counts
    from crowd.scene import load_scene

    sc = load_scene(REPO / "scenes" / "quickstart.toml")
    w = _world(sc)
    hooked = SimpleNamespace(scene=sc, world=w)

    def bare():  # Engine.step before this change: the step, then the finiteness check
        w.step(sc.dt, sc.substeps)
        w.state.check_finite()

    for _ in range(20):
        Engine.step(hooked)
        bare()
    ta, tb = [], []
    for b in range(blocks):
        for which, out in ((lambda: Engine.step(hooked), ta), (bare, tb)) if b % 2 == 0 else \
                ((bare, tb), (lambda: Engine.step(hooked), ta)):
            for _ in range(frames):
                t0 = time.perf_counter()
                which()
                out.append(time.perf_counter() - t0)
    k = 20000
    t0 = time.perf_counter()
    for _ in range(k):
        if w.agents_changed is not None:
            pass
        frame_counts(w)
    hook_us = (time.perf_counter() - t0) / k * 1e6
    return {"agents": w.state.n, "hooked_ms": 1e3 * float(np.median(ta)), "bare_ms": 1e3 * float(np.median(tb)),
            "ratio": float(np.median(ta) / np.median(tb)), "hook_us": hook_us, "steps": len(ta)}


# ---------------------------------------------------------------------------------------------- 2. compaction
def compaction_cost(counts: list, repeats: int) -> list:
    from sim.population import apply
    from sim.state import CrowdState
    from sim.world import World

    rows = []
    for n in counts:
        st = CrowdState.empty(n)
        st.position[:] = np.random.default_rng(0).normal(size=(n, 3))
        w = World(state=st, characters=[], seed=1)
        k = max(1, n // 100)
        times = []
        for r in range(repeats):
            keep = np.sort(np.random.default_rng(r).choice(w.state.n, w.state.n - k, replace=False))
            new = CrowdState.empty(k)
            t0 = time.perf_counter()
            apply(w, keep, new)
            times.append(time.perf_counter() - t0)
        rows.append({"n": n, "ms": 1e3 * float(np.median(times)), "bytes": st.nbytes() / n,
                     "ids_bytes": st.ids.nbytes / n})
    return rows


# ------------------------------------------------------------------------------------ 3. the journeys' steps
STEPS_SCENE = """\
name = "journeys_steps"
seed = 5
dt = 0.1
frames = 10
effects = ["journeys"]

[[characters]]
name = "p"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "random"
character = "p"
count = {n}
center = [0.0, 0.0, 0.0]
size = [{side}, {side}]

[[stages]]
name = "mid"
kind = "waypoint"
point = [0.0, {far}]
radius = 2.0

[[stages]]
name = "door"
kind = "exit"
line = [[-{half}, {far2}], [{half}, {far2}]]

[[journeys]]
name = "j"
placements = [0]
stages = ["mid", "door"]

[[sources]]
name = "s"
character = "p"
journey = "j"
rate = {rate}
polygon = [[-{half}, -{half}], [{half}, -{half}], [{half}, {half}], [-{half}, {half}]]
"""


def steps_cost(counts: list, steps: int) -> list:
    from crowd.scene import parse_scene

    import tomllib

    rows = []
    for n in counts:
        side = float(np.sqrt(n) * 1.2)
        text = STEPS_SCENE.format(n=n, side=side, half=side / 2, far=side, far2=side * 0.6, rate=max(1.0, n / 100))
        sc = parse_scene(tomllib.loads(text), Path("journeys_steps.toml"))
        w = _world(sc)
        for _ in range(3):
            w.step(sc.dt)
        per = []
        for _ in range(steps):
            tm = {}
            w.step(sc.dt, timings=tm)
            per.append(sum(v for k, v in tm.items() if k.startswith("journeys")))
        j = w.resources["journeys"]
        own = sum(getattr(j, k).nbytes for k in ("journey", "step", "stage", "phase", "slot", "ticket", "release",
                                                  "transitions", "tshape", "stop_at", "speed", "source",
                                                  "leave_frame")) / max(1, w.state.n)
        rows.append({"n": w.state.n, "ms": 1e3 * float(np.median(per)), "bytes": own})
    return rows


# --------------------------------------------------------------------------------------------------- 4. rates
def rates(seconds: float, seeds: list) -> dict:
    import tomllib

    from crowd.scene import parse_scene

    path = REPO / "scenes" / "concourse.toml"
    base = tomllib.loads(path.read_text())
    out = {"runs": []}
    for seed in seeds:
        doc = dict(base, seed=seed, frames=int(round(seconds / base["dt"])))
        sc = parse_scene(doc, path)
        w = _world(sc)
        j = w.resources["journeys"]
        n0 = w.state.n
        entered = left = 0
        ok = True
        chosen = {}
        for _ in range(sc.frames):
            w.step(sc.dt)
            c = j.take_frame_counts()
            entered += c["entered"]
            left += c["left"]
            ok &= w.state.n == n0 + entered - left
            for i in np.flatnonzero(j.transitions == 1):  # first choice of every agent, by journey
                key = (int(w.state.ids[i]), int(j.journey[i]))
                chosen.setdefault(key, j.stages[int(j.stage[i])].name)
        t = w.time
        srcs = {s.name: {"entered": s.entered, "expected": s.expected(t), "rate": s.rate,
                         "process": "poisson" if s.poisson else "uniform", "waiting": s.waiting} for s in j.sources}
        exits = {s.name: int(j.exited_by_stage[i]) for i, s in enumerate(j.stages) if s.kind == 1}
        out["runs"].append({"seed": seed, "time": t, "sources": srcs, "exits": exits, "identity": bool(ok),
                            "alive_end": w.state.n, "choices": chosen, "journeys": [jr.name for jr in j.journeys],
                            "weights": [[(j.stages[int(k)].name, float(c)) for k, c in
                                         zip(jr.entries[0][0], np.diff(np.r_[0.0, jr.entries[0][1]]))]
                                        for jr in j.journeys]})
    return out


def _rates_lines(r: dict) -> list:
    lines = ["| seed | source | process | rate 1/s | entered | expected | deviation |", "|---|---|---|---|---|---|---|"]
    per = {}
    for run in r["runs"]:
        for name, s in run["sources"].items():
            dev = s["entered"] / s["expected"] - 1.0
            per.setdefault(name, []).append((s["entered"], s["expected"], s["process"]))
            lines.append(f"| {run['seed']} | {name} | {s['process']} | {s['rate']:g} | {s['entered']} | "
                         f"{s['expected']:.1f} | {100 * dev:+.2f} % |")
    lines += ["", "| source | seeds | entered (sum) | expected (sum) | deviation of the sum | 1/sqrt(expected) |",
              "|---|---|---|---|---|---|"]
    for name, v in per.items():
        e, x = sum(a for a, _, _ in v), sum(b for _, b, _ in v)
        lines.append(f"| {name} ({v[0][2]}) | {len(v)} | {e} | {x:.1f} | {100 * (e / x - 1):+.2f} % | "
                     f"{100 / np.sqrt(x):.2f} % |")
    # choices of the first entry against the weights, over every run
    lines += ["", "| journey | stage | chosen | share | weight share |", "|---|---|---|---|---|"]
    run0 = r["runs"][0]
    for ji, name in enumerate(run0["journeys"]):
        counts = {}
        for run in r["runs"]:
            for (aid, jj), st in run["choices"].items():
                if jj == ji:
                    counts[st] = counts.get(st, 0) + 1
        total = sum(counts.values())
        wsum = sum(wt for _, wt in run0["weights"][ji])
        for st, wt in run0["weights"][ji]:
            c = counts.get(st, 0)
            lines.append(f"| {name} | {st} | {c} | {c / max(total, 1):.3f} | {wt / wsum:.3f} |")
    lines += ["", "| seed | simulated s | exits (agents out) | alive at the end | agents = start + entered - left "
                  "every frame |", "|---|---|---|---|---|"]
    for run in r["runs"]:
        lines.append(f"| {run['seed']} | {run['time']:.0f} | "
                     + ", ".join(f"{k} {v}" for k, v in run["exits"].items())
                     + f" | {run['alive_end']} | {'yes' if run['identity'] else 'NO'} |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="journeys and a changing agent count: cost and rates")
    ap.add_argument("--quick", action="store_true", help="small sizes, short runs (a smoke test)")
    ap.add_argument("--seconds", type=float, default=600.0, help="simulated seconds of each concourse run")
    ap.add_argument("--seeds", type=int, default=8, help="concourse runs (seeds 28, 29, ...)")
    ap.add_argument("--md")
    a = ap.parse_args(argv)
    import numba

    q = a.quick
    load0 = os.getloadavg()[0]
    t_start = time.perf_counter()
    c = constant_cost(frames=20 if q else 100, blocks=4 if q else 12)
    comp = compaction_cost([10_000, 100_000] if q else [10_000, 100_000, 1_000_000], repeats=3 if q else 9)
    steps = steps_cost([1_000, 10_000] if q else [1_000, 10_000, 100_000], steps=3 if q else 15)
    r = rates(60.0 if q else a.seconds, list(range(28, 28 + (2 if q else a.seeds))))
    load = os.getloadavg()[0]
    lines = [f"numba threads {numba.get_num_threads()}, load average {load0:.1f} at the start, {load:.1f} at the end "
             f"(`uptime`; the machine is shared), {time.perf_counter() - t_start:.0f} s in all",
             "", "## 1. A scene that never changes its count",
             f"quickstart ({c['agents']} agents, world only): Engine.step with the agent-count test "
             f"{c['hooked_ms']:.3f} ms, without {c['bare_ms']:.3f} ms (medians of {c['steps']} steps each, interleaved "
             f"blocks): ratio **{c['ratio']:.3f}**; the per-frame test + telemetry counts alone: "
             f"{c['hook_us']:.2f} us per frame.",
             "", "## 2. Compaction (1 % leave and 1 % enter, one change)",
             "| agents | ms per change (median) | CrowdState B/agent | ids B/agent |", "|---|---|---|---|"]
    lines += [f"| {x['n']:,} | {x['ms']:.2f} | {x['bytes']:.0f} | {x['ids_bytes']:.0f} |" for x in comp]
    lines += ["", "## 3. The journeys' steps (leave + steer + update, no avoidance; a source adds 1 %/s)",
              "| agents | ms per step (median) | journeys B/agent |", "|---|---|---|"]
    lines += [f"| {x['n']:,} | {x['ms']:.2f} | {x['bytes']:.0f} |" for x in steps]
    lines += ["", f"## 4. Rates on scenes/concourse.toml ({r['runs'][0]['time']:.0f} simulated s per run)"]
    lines += _rates_lines(r)
    text = "\n".join(lines)
    print(text)
    if a.md:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                             cwd=REPO).stdout.strip()
        md = (f"# bench_journeys: last run\n\nMachine: {platform.machine()}, {os.cpu_count()} CPUs, "
              f"{platform.processor() or platform.platform()}; commit {rev}.\n"
              f"Command: `python scripts/bench_journeys.py {' '.join(sys.argv[1:] if argv is None else argv)}`\n\n"
              + text + "\n")
        from sim.atomic_io import write_atomic

        write_atomic(a.md, md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
