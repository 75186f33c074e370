"""Benchmark: discrete triangle LOD chains (LOD mode "triangles") against full detail (mode "none").

For each scene (default: exhibition) at 1280x720, in ONE run with one renderer:
the frame time (select + draw + ``ctx.finish``) of NoLOD and of the triangle
chains at ``--poe`` pixels of error, drawn in turn on the same simulated frames
along the scene's camera path, the speed-up, the triangles drawn, the
instances per level, and per character the chain (triangles and error of every
level) with its build time (from the cache when present).

Chains are built once and cached (``$CROWD_CACHE_DIR``, default
``~/.cache/crowd``); the first run of a scene includes the build.

Run:  .venv/bin/python scripts/bench_triangles.py [--scenes exhibition] [--frames 2]
      [--warmup 1] [--poe 1.0] [--size 1280 720] [--steps 5] [--levels 7] [--ratio 0.5]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from crowd.engine import Engine  # noqa: E402
from crowd.scene import load_scene  # noqa: E402
from lod.chains import chain as triangles_mode_chain  # noqa: E402
from lod.chains import mode as triangles_mode
from render.renderer import Renderer  # noqa: E402


def bench_scene(path: Path, args) -> dict:
    size = tuple(args.size)
    eng = Engine(load_scene(path), overrides={"size": size}, quiet=True)
    sc = eng.scene
    t0 = time.perf_counter()
    reps, tsel = triangles_mode.build(eng.plan.characters, [c.name for c in sc.characters],
                                      [c.fps for c in sc.characters],
                                      {"poe": args.poe, "levels": args.levels, "ratio": args.ratio},
                                      static_reps=eng.statics)
    t_build = time.perf_counter() - t0
    print(f"  chains built or loaded in {t_build:.1f} s", flush=True)
    for rep in reps:
        if isinstance(rep, triangles_mode_chain.TrianglesRep):
            lv = ", ".join(f"{int(c):,} ({e * 1000:.1f} mm)" for c, e in zip(rep.level_count, rep.level_error))
            print(f"  {rep.key}: {lv}", flush=True)
    r = Renderer(size)
    for rep in [*eng.reps, *eng.statics, *reps]:
        r.upload(rep)
    cases = [("triangles", tsel), ("nolod", eng.selector)]
    for _ in range(args.steps):
        eng.step()
    statics = [(s.key, np.eye(4)) for s in eng.statics]
    times = {n: [] for n, _ in cases}
    tris, levels = {}, []
    for k in range(args.warmup + args.frames):
        cam = eng.camera_at(eng.world.frame * sc.dt)
        for name, sel in cases:
            a = time.perf_counter()
            dl = sel.select(eng.world.state, cam, size, statics=statics)
            r.draw(dl)
            b = time.perf_counter()
            if k >= args.warmup:
                times[name].append(b - a)
                tris[name] = dl.stats["triangles"]
                if name == "triangles":
                    levels = dl.stats["levels"]
            extra = f", levels {dl.stats['levels']}" if name == "triangles" else ""
            print(f"    frame {k} {name}: {b - a:.3f} s, {dl.stats['triangles']:,} triangles, "
                  f"{dl.stats['instances']} instances{extra}", flush=True)
        eng.step()
    r.release()
    eng.close()
    med = {n: statistics.median(v) for n, v in times.items()}
    return {"scene": path.stem, "build_s": t_build, "tri_s": med["triangles"], "nolod_s": med["nolod"],
            "tri_tris": tris["triangles"], "nolod_tris": tris["nolod"], "speedup": med["nolod"] / med["triangles"],
            "levels": levels}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["exhibition"])
    ap.add_argument("--frames", type=int, default=2, help="timed frames per case (median)")
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--steps", type=int, default=5, help="simulation steps before the first frame")
    ap.add_argument("--poe", type=float, default=1.0)
    ap.add_argument("--levels", type=int, default=7)
    ap.add_argument("--ratio", type=float, default=0.5)
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    args = ap.parse_args(argv)
    rows = []
    for s in args.scenes:
        p = Path(s) if s.endswith(".toml") else ROOT / "scenes" / f"{s}.toml"
        print(f"# {p.stem}", flush=True)
        rows.append(bench_scene(p, args))
    print(f"\n{'scene':<11} {'NoLOD s':>8} {'tri s':>7} {'speed-up':>8} {'NoLOD tris':>12} {'tri tris':>11}  "
          f"instances per level")
    for o in rows:
        print(f"{o['scene']:<11} {o['nolod_s']:>8.3f} {o['tri_s']:>7.3f} {o['speedup']:>8.1f} "
              f"{o['nolod_tris']:>12,} {o['tri_tris']:>11,}  {o['levels']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
