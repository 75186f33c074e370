"""Exhibition: how close visitors come to each other, and how often they visit the stands.

Runs the simulation of a scene (default ``scenes/exhibition.toml``) without rendering and prints, at
5/10/15/20 s (``--at``), the share of visitors whose nearest other visitor's centre is closer than
``--close`` (0.7 m: two body radii of 0.35 m) and closer than half that, and the visits per minute
of the stands over the run. A *visit* is a visitor entering a stand's area, the disc of the stand's
obstacle radius + ``--reach`` (1.5 m) around an attractor's centre, from outside it; "outside" means
beyond that disc by ``--hysteresis`` (1.0 m), so a visitor that jitters on the disc's border is not
counted again and again (visitors that start inside count when they have left and enter again).
``--hysteresis 0`` counts every crossing of the border. Stands are the scene's goals attractors; their radius is
that of the obstacle circle at the same centre (else 0).

Usage (from a checkout; the same script measured main, where exhibition has no avoidance)::

    PYTHONPATH=$PWD python scripts/exhibition_overlap.py [--scene scenes/exhibition.toml] [--md FILE]

Figures go to stdout and, with ``--md``, to a markdown file (written atomically).
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np


def build_world(scene_path):
    """The scene's world with its effects installed (no renderer)."""
    from crowd.plan import plan
    from crowd.scene import load_scene
    from sim.world import World

    sc = load_scene(scene_path)
    p = plan(sc)
    w = World(state=p.state, characters=p.characters, seed=sc.seed)
    w.resources["character_radius"] = [getattr(c, "radius", None) for c in sc.characters]
    for e in sc.effects:
        w.install(e.name, e.params)
    return sc, w


def close_shares(xz: np.ndarray, close: float) -> tuple[float, float]:
    """Share of agents with another agent's centre closer than ``close`` and ``close / 2``."""
    from scipy.spatial import cKDTree

    d, _ = cKDTree(xz).query(xz, k=2)
    nn = d[:, 1]
    return float(np.mean(nn < close)), float(np.mean(nn < close / 2))


def stands(world) -> np.ndarray:
    """(S, 3) stand centre x, z and area radius without reach (obstacle circle at the attractor)."""
    g = world.resources.get("goals")
    att = g.att[:, :2] if g is not None else np.zeros((0, 2))
    obs = world.resources.get("obstacles")
    out = []
    for cx, cz in att:
        r = 0.0
        if obs is not None and obs.circles.size:
            k = np.argmin(np.hypot(obs.circles[:, 0] - cx, obs.circles[:, 1] - cz))
            if np.hypot(obs.circles[k, 0] - cx, obs.circles[k, 1] - cz) < 1e-6:
                r = float(obs.circles[k, 2])
        out.append((cx, cz, r))
    return np.array(out, np.float64).reshape(-1, 3)


def measure(scene_path, at=(5.0, 10.0, 15.0, 20.0), close=0.7, reach=1.5, hysteresis=1.0):
    sc, w = build_world(scene_path)
    st = stands(w)
    area_r = st[:, 2] + reach
    dt = sc.dt
    n_steps = int(round(max(at) / dt))
    marks = {int(round(t / dt)): t for t in at}

    def dist():
        x, z = w.state.position[:, 0], w.state.position[:, 2]
        return np.hypot(x[:, None] - st[None, :, 0], z[:, None] - st[None, :, 1])

    d = dist()
    was = d < area_r[None, :]  # in a stand's area; cleared only beyond area + hysteresis
    visits = np.zeros(st.shape[0], np.int64)
    rows = []
    t0 = time.perf_counter()
    for k in range(1, n_steps + 1):
        w.step(dt)
        d = dist()
        enter = (d < area_r[None, :]) & ~was
        visits += np.sum(enter, axis=0)
        was = (was | enter) & (d < area_r[None, :] + hysteresis)
        if k in marks:
            s1, s2 = close_shares(w.state.position[:, [0, 2]], close)
            rows.append((marks[k], s1, s2))
    wall = time.perf_counter() - t0
    minutes = n_steps * dt / 60.0
    return {"scene": str(scene_path), "agents": w.state.n, "effects": list(w.effects), "rows": rows,
            "visits": visits, "visits_per_min": float(visits.sum() / minutes), "seconds": n_steps * dt,
            "wall_s": wall, "close": close, "reach": reach, "hysteresis": hysteresis}


def report(r) -> str:
    lines = [f"scene {r['scene']}: {r['agents']} agents, effects {', '.join(r['effects'])}",
             f"| t (s) | share closer than {r['close']:g} m | share closer than {r['close'] / 2:g} m |",
             "|---|---|---|"]
    lines += [f"| {t:g} | {100 * a:.2f} % | {100 * b:.2f} % |" for t, a, b in r["rows"]]
    lines.append(f"visits (entering a stand's obstacle radius + {r['reach']:g} m, after having been "
                 f"{r['hysteresis']:g} m beyond it) over {r['seconds']:g} s: "
                 f"{int(r['visits'].sum())} = {r['visits_per_min']:.1f} per minute; per stand "
                 + ", ".join(str(int(v)) for v in r["visits"]))
    lines.append(f"simulation wall time {r['wall_s']:.1f} s")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="scenes/exhibition.toml")
    ap.add_argument("--close", type=float, default=0.7)
    ap.add_argument("--reach", type=float, default=1.5)
    ap.add_argument("--hysteresis", type=float, default=1.0)
    ap.add_argument("--baseline", help="a second scene file measured the same way (e.g. main's exhibition)")
    ap.add_argument("--md", help="write the figures to this markdown file")
    a = ap.parse_args(argv)
    if not Path(a.scene).is_file():
        print(f"{a.scene}: scene file not found", file=sys.stderr)
        return 2
    runs = [measure(a.scene, close=a.close, reach=a.reach, hysteresis=a.hysteresis)]
    if a.baseline:
        runs.insert(0, measure(a.baseline, close=a.close, reach=a.reach, hysteresis=a.hysteresis))
    text = "\n\n".join(report(r) for r in runs)
    if len(runs) == 2:
        ratio = runs[1]["visits_per_min"] / max(runs[0]["visits_per_min"], 1e-9)
        text += f"\n\nvisits per minute, scene / baseline: {ratio:.3f}"
    print(text)
    if a.md:
        try:
            rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        except OSError:
            rev = "?"
        md = ("# exhibition_overlap: last run\n\n"
              f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; commit {rev}.\n"
              f"Command: `python scripts/exhibition_overlap.py {' '.join(argv if argv is not None else sys.argv[1:])}`\n\n"
              + text + "\n")
        from sim.atomic_io import write_atomic

        write_atomic(a.md, md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
