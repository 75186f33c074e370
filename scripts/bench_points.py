"""Benchmark of the point-hierarchy LOD mode (Wand & Straßer 2002; lod/points_mode.py, render/points.py).

Prints:

1. splat throughput: a grid of instances of a 6,396-triangle procedural
   humanoid (baked to keyframes) far enough that the octree traversal selects
   mostly points; the same DrawList is drawn with the compute-shader splat and
   with the GL_POINTS reference in the same run, frames interleaved (median
   over N frames, ``ctx.finish`` inside the clock). Points/s of both and their ratio
   (target >= 5x).
2. build time per keyframe pair (one segment octree, no cache) of a
   30,000-triangle humanoid with 3 time intervals and with 1 (paper: 20-25 s
   on a 2 GHz Pentium 4; target <= 3 s).
3. optionally (``--grid``) the ``grid`` scene (90,000 instances) at 640x480,
   mode "points" against mode "none", a few frames through ``crowd run``.

Run:  .venv/bin/python scripts/bench_points.py [--size 1280x720] [--frames 3] [--instances 400] [--grid]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lod import points_mode as pm  # noqa: E402
from lod.points_octree import build_hierarchy  # noqa: E402
from lod.view import Camera  # noqa: E402
from render.renderer import Renderer  # noqa: E402
from sim.procedural import humanoid  # noqa: E402
from sim.state import CrowdState  # noqa: E402


def splat_throughput(size, frames, instances, splat, cache):
    ch = humanoid(6396, seed=41)
    reps, sel = pm.build([ch], ["poser"], [30], {"splat_size": splat, "keyframes": 9}, cache=cache,
                         progress=lambda it, d: it)
    side = int(np.ceil(np.sqrt(instances)))
    st = CrowdState.empty(instances)
    rng = np.random.default_rng(1)
    g = np.arange(instances)
    st.position[:, 0] = (g % side - side / 2) * 1.5
    st.position[:, 2] = -(g // side) * 1.5
    st.heading[:] = rng.uniform(0, 2 * np.pi, instances)
    st.anim_time[:] = rng.uniform(0, 2, instances)
    cam = Camera.look_at((0.0, 0.4 * side, 0.9 * side + 10.0), (0.0, 0.0, -0.5 * side * 1.5), fov_y=50.0)
    r = Renderer(size)
    r.upload(reps[0])
    dl = sel.select(st, cam, size)
    out = {"points": dl.stats["points"], "triangles": dl.stats["triangles"]}
    # the triangles' share, drawn the same way in both paths, is measured alone
    tri_only = [type(b)(**{**b.__dict__, "point_jobs": np.zeros((0, 3), np.int64)}) for b in dl.batches]
    dl2 = type(dl)(dl.origin, dl.view, dl.proj, dl.size, tri_only, dl.stats)
    runs = {"compute": (dl, "compute"), "gl_points": (dl, "gl_points"), "triangles_only": (dl2, "compute")}
    times = {k: [] for k in runs}
    for it in range(frames + 1):  # interleaved, so all three see the same machine load; first is warm-up
        for k, (d, path) in runs.items():
            r.drawer("points").path = path
            t0 = time.perf_counter()
            r.draw(d)  # ends with ctx.finish
            if it:
                times[k].append(time.perf_counter() - t0)
    out.update({k: statistics.median(v) for k, v in times.items()})
    r.release()
    return out


def build_time(triangles, intervals):
    from sim.keyframes import bake_skinned

    ch = humanoid(triangles, seed=3)
    anim = bake_skinned(ch, "walk", 9)
    kf = pm.build_keyframed_rep(pm.keyframed_character(ch, 9))
    arrays = pm.segment_arrays(kf, 0)
    t0 = time.perf_counter()
    h = build_hierarchy(*arrays, intervals=intervals, progress=False)
    dt = time.perf_counter() - t0
    del anim
    return dt, int(arrays[2].shape[0]), h.n_points, h.n_nodes, h.nbytes


def grid_frames(mode, size, frames):
    scene = (ROOT / "scenes" / "grid.toml").read_text().replace('mode = "none"', f'mode = "{mode}"')
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "grid.toml"
        p.write_text(scene)
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        t0 = time.perf_counter()
        res = subprocess.run([sys.executable, "-m", "crowd", "run", str(p), "--frames", str(frames), "--size", size,
                              "--out", str(Path(d) / "out"), "--quiet", "--png-every", "0"], cwd=ROOT, env=env,
                             capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if res.returncode:
            return {"error": res.stderr[-800:]}
        import csv

        rows = list(csv.DictReader(open(next((Path(d) / "out").rglob("frames.csv")))))
    return {"wall_s": wall, "rows": rows}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--instances", type=int, default=400)
    ap.add_argument("--splat", type=int, default=2)
    ap.add_argument("--build-triangles", type=int, default=30000)
    ap.add_argument("--grid", action="store_true", help="also run the grid scene (slow)")
    a = ap.parse_args(argv)
    size = tuple(int(v) for v in a.size.lower().split("x"))
    cache = pm.HierarchyCache()
    s = splat_throughput(size, a.frames, a.instances, a.splat, cache)
    pts = s["points"]
    tc, tg, tt = s["compute"], s["gl_points"], s["triangles_only"]
    print(f"splat throughput at {size[0]}x{size[1]}, splat {a.splat}, {a.instances} instances: "
          f"{pts} points + {s['triangles']} triangles per frame")
    print(f"  frame: compute {tc * 1e3:.1f} ms, GL_POINTS {tg * 1e3:.1f} ms, triangles only {tt * 1e3:.1f} ms")
    pc, pg = tc - tt, tg - tt
    print(f"  points/s (frame minus the triangles-only frame): compute {pts / max(pc, 1e-9) / 1e6:.1f} M, "
          f"GL_POINTS {pts / max(pg, 1e-9) / 1e6:.1f} M, ratio {pg / max(pc, 1e-9):.1f}x (target >= 5x)")
    for iv in (3, 1):
        dt, T, P, N, nb = build_time(a.build_triangles, iv)
        print(f"build of one keyframe pair, {T} triangles, {iv} interval(s): {dt:.2f} s "
              f"({P} points, {N} nodes, {nb / 1e6:.1f} MB)")
    if a.grid:
        for mode in ("points", "none"):
            g = grid_frames(mode, "640x480", 2)
            if "error" in g:
                print(f"grid {mode}: failed: {g['error']}")
                continue
            print(f"grid {mode}: crowd run of 2 frames at 640x480 took {g['wall_s']:.1f} s (with build)")
            for row in g["rows"][1:]:  # frame 0 includes JIT compilation
                print(f"    frame {row['frame']}: total {float(row['total']):.3f} s, select {float(row['select']):.3f} s, "
                      f"draw {float(row['draw']):.3f} s, {row['instances']} instances, {row['points']} points, "
                      f"{row['triangles']} triangles")


if __name__ == "__main__":
    main()
