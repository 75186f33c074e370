"""Speed and memory of the avoidance effect at 10 K to 1 M agents.

Scenario (as the issue's JuPedSim figure): agents of radius 0.2 m on a jittered square lattice at
``--density`` per m^2 (default 1), all walking towards a point far beyond the square's north edge
(``goals``, 1.34 m/s), no obstacles, dt 0.05 s. After ``--warmup`` steps, ``--steps`` steps are timed; the
figure is the median over steps of the wall time of the avoidance steps (``avoidance.record`` +
``avoidance`` + ``avoidance.resolve``) and of the whole step (with ``goals``), and the CPU time of the
whole step summed over threads (on a machine shared with other jobs the wall time includes waiting for
a core; CPU time / threads is then the better estimate of the wall time on a quiet machine). Bytes per agent: the
CrowdState plus every array the effect keeps (snapshot, grid, buffers) divided by the agent count.

Usage::

    PYTHONPATH=$PWD python scripts/bench_avoidance_scale.py [--model cfsm] [--counts 10000,50000,100000,1000000]
        [--md scripts/bench_avoidance_scale.md]
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time

# numba's OpenMP threads sleep between kernels (as the `crowd` command sets it): spinning threads take the cores
# other jobs on a shared machine need, and then wait for them
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402


def world(n: int, density: float, model: str):
    from sim.params import validate
    from sim.state import CrowdState
    from sim.systems import effect_module
    from sim.world import World

    sp = 1.0 / density ** 0.5
    k = int(np.ceil(n ** 0.5))
    rng = np.random.default_rng(1)
    st = CrowdState.empty(n)
    g = np.arange(n)
    st.position[:, 0] = (g % k) * sp + rng.uniform(-0.1, 0.1, n) * sp
    st.position[:, 2] = (g // k) * sp + rng.uniform(-0.1, 0.1, n) * sp
    w = World(state=st, characters=[], seed=1)
    side = k * sp
    for name, cfg in [("goals", {"paths": [[[side / 2, side + 1000.0]]], "loop": False, "speed": 1.34}),
                      ("avoidance", {"model": model, "radius": 0.2, "v0": 1.34 if model == "cfsm" else 0.0})]:
        w.install(name, validate(effect_module(name).PARAMS, cfg, name))
    return w


def effect_bytes(w) -> int:
    eff = w.resources["avoidance"]
    arrays = [eff.prev, eff.radius, eff.base_rate, eff.scratch, eff.near]
    if eff.model == "orca":
        arrays.append(eff.vstart)
    total = sum(a.nbytes for a in arrays if a is not None)
    if eff.grid is not None:
        total += eff.grid.nbytes()
    n = w.state.n
    total += n * (2 * 16)  # per step: preferred and new velocities (n, 2) float64
    total += n * (24 + 16 + 8)  # resolve: snapshot, pushes, worst overlap
    return total


def measure(n, density, model, warmup, steps):
    w = world(n, density, model)
    for _ in range(warmup):
        w.step(0.05)
    avoid, total, cpu = [], [], []
    for _ in range(steps):
        tim = {}
        c0 = time.process_time()
        t0 = time.perf_counter()
        w.step(0.05, timings=tim)
        total.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        avoid.append(sum(v for k, v in tim.items() if k.startswith("avoidance")))
    return {"n": n, "avoid_ms": 1e3 * float(np.median(avoid)), "step_ms": 1e3 * float(np.median(total)),
            "cpu_ms": 1e3 * float(np.median(cpu)),
            "state_b": w.state.nbytes() / n, "effect_b": effect_bytes(w) / n,
            "speed": float(np.hypot(w.state.velocity[:, 0], w.state.velocity[:, 2]).mean())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="ms per step of the avoidance effect at 10 K - 1 M agents")
    ap.add_argument("--model", default="cfsm", choices=("cfsm", "orca"))
    ap.add_argument("--counts", default="10000,50000,100000,1000000")
    ap.add_argument("--density", type=float, default=1.0)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--steps", type=int, default=5)
    ap.add_argument("--md")
    a = ap.parse_args(argv)
    import numba

    load0 = os.getloadavg()[0]
    rows = [measure(int(c), a.density, a.model, a.warmup, a.steps) for c in a.counts.split(",")]
    load = os.getloadavg()[0]
    lines = [f"model {a.model}, density {a.density:g}/m^2, radius 0.2 m, dt 0.05 s, numba threads "
             f"{numba.get_num_threads()} (OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY')}), load average "
             f"{load0:.1f} at the start, {load:.1f} at the end (`uptime`: the machine is shared)",
             "| agents | avoidance ms/step (median) | whole step ms (with goals) | whole step CPU ms (all threads) "
             "| mean speed m/s | state B/agent | avoidance B/agent |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['n']:,} | {r['avoid_ms']:.1f} | {r['step_ms']:.1f} | {r['cpu_ms']:.1f} | {r['speed']:.2f} | "
              f"{r['state_b']:.0f} | {r['effect_b']:.0f} |" for r in rows]
    text = "\n".join(lines)
    print(text)
    if a.md:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        md = (f"# bench_avoidance_scale: last run\n\nMachine: {platform.machine()}, {os.cpu_count()} CPUs, "
              f"{platform.processor() or platform.platform()}; commit {rev}.\n"
              f"Command: `python scripts/bench_avoidance_scale.py {' '.join(sys.argv[1:] if argv is None else argv)}`\n\n"
              + text + "\n")
        from sim.atomic_io import write_atomic

        write_atomic(a.md, md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
