"""Benchmark: VDR-AM cluster cuts (LOD mode "clusters") against full detail (mode "none").

For each scene (default: office, exhibition, stampede) at 1280x720 and PoE 0.5
(Claudio, Kim, Kim, Yoon, *VDR-AM*, §6, Table 1), in ONE run with one renderer:
the frame time (select + draw + ``ctx.finish``) of NoLOD, VDR and VDR with
occlusion culling (§5.2), drawn in turn on the same simulated frames, the speed-up, the triangles drawn,
the distinct cuts and indirect commands, the CPU time of the cut per 1,000
instances (§5.1), and per character the hierarchy's build time (from the cache
when present) and bytes per triangle.

Hierarchies are built once and cached (``$CROWD_CACHE_DIR``, default
``~/.cache/crowd``); the first run of a scene includes the build.

Run:  .venv/bin/python scripts/bench_clusters.py [--scenes office exhibition stampede]
      [--frames 2] [--warmup 1] [--poe 0.5] [--size 1280 720] [--strategy indices]
      [--no-nolod] [--no-oc] [--occlusion-every 8] [--steps 5] [--leaf-triangles 100]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from crowd.engine import Engine  # noqa: E402
from crowd.scene import load_scene  # noqa: E402
from lod.clusters import mode as clusters_mode  # noqa: E402
from lod.clusters.dag import bytes_per_triangle  # noqa: E402
from render.renderer import Renderer  # noqa: E402


def bench_scene(path: Path, args) -> dict:
    size = tuple(args.size)
    scene = load_scene(path)
    t0 = time.perf_counter()
    eng = Engine(scene, overrides={"size": size}, quiet=True)
    t_setup = time.perf_counter() - t0
    sc = eng.scene
    t0 = time.perf_counter()
    params = {"poe": args.poe, "leaf_triangles": args.leaf_triangles}
    reps, vsel = clusters_mode.build(eng.plan.characters, [c.name for c in sc.characters],
                                     [c.fps for c in sc.characters], params, static_reps=eng.statics)
    t_build = time.perf_counter() - t0
    for rep in reps:
        if rep.kind == "clusters":
            h = rep.hierarchy
            ch = eng.plan.characters[[r.key for r in reps].index(rep.key)]
            print(f"  {rep.key}: {h.n_triangles:,} triangles, {h.n_clusters} clusters, build {h.build_seconds:.1f} s "
                  f"(when built), {bytes_per_triangle(h, ch.mesh):.1f} bytes/triangle", flush=True)
    r = Renderer(size)
    for rep in [*eng.reps, *eng.statics, *reps]:
        r.upload(rep)
    r.drawer("clusters").strategy = args.strategy
    cases = [("vdr", vsel, r)]
    if not args.no_oc:
        # VDR + occlusion culling (§5.2): the same hierarchies, a renderer of its own (same context)
        r_oc = Renderer(size, ctx=r.ctx)
        for rep in [*eng.statics, *reps]:
            r_oc.upload(replace(rep, occlusion=True, occlusion_every=args.occlusion_every)
                        if rep.kind == "clusters" else rep)
        r_oc.drawer("clusters").strategy = args.strategy
        cases.append(("vdr_oc", vsel, r_oc))
    if not args.no_nolod:
        cases.append(("nolod", eng.selector, r))
    for _ in range(args.steps):
        eng.step()
    statics = [(s.key, np.eye(4)) for s in eng.statics]
    times = {n: [] for n, _, _ in cases}
    tris, last_stats, cut_ms = {}, {}, []
    for k in range(args.warmup + args.frames):
        cam = eng.camera_at(eng.world.frame * sc.dt)
        for name, sel, rr in cases:
            a = time.perf_counter()
            dl = sel.select(eng.world.state, cam, size, statics=statics)
            rr.draw(dl)
            b = time.perf_counter()
            extra = ""
            if name != "nolod":
                ds = rr.drawer("clusters").last_stats
                tri = ds["triangles"] + sum(x.triangles for x in dl.batches if not hasattr(x, "offsets"))
                extra = f" ({ds['groups']} cuts, {ds['commands']} commands, {ds['queries']} queries, " \
                        f"{ds['occluded']} occluded)"
            else:
                tri = dl.stats["triangles"]
            if k >= args.warmup:
                times[name].append(b - a)
                tris[name] = tri
                if name == "vdr":
                    last_stats = dict(rr.drawer("clusters").last_stats)
                    n_inst = max(1, sum(x.n_instances for x in dl.batches if hasattr(x, "offsets")))
                    cut_ms.append(vsel.last_cut_seconds * 1e3 / n_inst * 1000)
            print(f"    frame {k} {name}: {b - a:.3f} s, {tri:,} triangles{extra}", flush=True)
        eng.step()
    for _, _, rr in cases[::-1]:
        rr.release()
    eng.close()
    med = {n: statistics.median(v) for n, v in times.items()}
    out = {"scene": path.stem, "setup_s": t_setup, "build_s": t_build, "vdr_s": med["vdr"],
           "vdr_tris": tris["vdr"], "cut_ms_per_1000": statistics.median(cut_ms), **last_stats}
    if "vdr_oc" in med:
        out.update(oc_s=med["vdr_oc"], oc_tris=tris["vdr_oc"])
    if "nolod" in med:
        out.update(nolod_s=med["nolod"], nolod_tris=tris["nolod"], speedup=med["nolod"] / med["vdr"])
        if "vdr_oc" in med:
            out["speedup_oc"] = med["nolod"] / med["vdr_oc"]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["office", "exhibition", "stampede"])
    ap.add_argument("--frames", type=int, default=2, help="timed frames per case (median)")
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--steps", type=int, default=5, help="simulation steps before the first frame")
    ap.add_argument("--poe", type=float, default=0.5)
    ap.add_argument("--leaf-triangles", type=int, default=clusters_mode.PARAMS["leaf_triangles"].default,
                    help="§4.2 s, the largest leaf cluster ([lod] leaf_triangles; the paper's default 100)")
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--strategy", default="indices", choices=("indices", "ranges"))
    ap.add_argument("--no-nolod", action="store_true", help="skip the (slow) full-detail frames")
    ap.add_argument("--no-oc", action="store_true", help="skip VDR + occlusion culling")
    ap.add_argument("--occlusion-every", type=int, default=8, help="frames between PVS rebuilds (§5.2)")
    args = ap.parse_args(argv)
    rows = []
    for s in args.scenes:
        p = Path(s) if s.endswith(".toml") else ROOT / "scenes" / f"{s}.toml"
        print(f"# {p.stem}", flush=True)
        rows.append(bench_scene(p, args))
    nan = float("nan")
    print(f"\n{'scene':<11} {'NoLOD s':>8} {'VDR s':>7} {'VDR+OC s':>8} {'speed-up':>8} {'+OC':>6} "
          f"{'NoLOD tris':>12} {'VDR tris':>11} {'VDR+OC tris':>11} {'cuts':>6} {'cut ms/1k':>9}")
    for o in rows:
        print(f"{o['scene']:<11} {o.get('nolod_s', nan):>8.3f} {o['vdr_s']:>7.3f} {o.get('oc_s', nan):>8.3f} "
              f"{o.get('speedup', nan):>8.1f} {o.get('speedup_oc', nan):>6.1f} {o.get('nolod_tris', 0):>12,} "
              f"{o['vdr_tris']:>11,} {o.get('oc_tris', 0):>11,} {o.get('groups', 0):>6} "
              f"{o['cut_ms_per_1000']:>9.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
