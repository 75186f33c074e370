"""Benchmark: full-detail (LOD mode "none") frame time, skinned vs static.

At 1280x720, draws 100, 1,000 and 10,000 instances of a 5,000-triangle
procedural humanoid (``sim.procedural.humanoid``) on a grid that fills the
view, and the same instance count of the same mesh unanimated through the
static instancing path, in the same run. Reports the median frame time over
N frames after warm-up (``ctx.finish`` before the clock stops), triangles per
second, and the skinning overhead (skinned / static time; target <= 1.3).

Run:  .venv/bin/python scripts/bench_baseline.py [--counts 100 1000 10000]
      [--frames 3] [--warmup 1] [--out scripts/bench_baseline.md]
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lod.full.mode import NoLodSelector, build_rep  # noqa: E402
from lod.view import Camera  # noqa: E402
from render.context import gl_info  # noqa: E402
from render.renderer import Renderer  # noqa: E402
from sim.procedural import humanoid  # noqa: E402
from sim.state import CrowdState  # noqa: E402

#: grid spacing (metres) between instances
SPACING = 1.2


def grid_state(n: int, rng) -> CrowdState:
    """n agents on a near-square grid centred on the origin, random headings/phases."""
    cols = int(np.ceil(np.sqrt(n)))
    i = np.arange(n)
    st = CrowdState.empty(n)
    st.position[:, 0] = (i % cols - (cols - 1) / 2) * SPACING
    st.position[:, 2] = (i // cols - (cols - 1) / 2) * SPACING
    st.heading[:] = rng.uniform(-np.pi, np.pi, n)
    st.anim_time[:] = rng.uniform(0, 10, n)
    return st


def framing_camera(n: int, aspect: float) -> Camera:
    """Camera looking down at 35 degrees so the grid fills the view."""
    half = 0.5 * np.ceil(np.sqrt(n)) * SPACING + 0.5
    fov = 50.0
    # fit the grid's width to the horizontal field of view (depth is foreshortened)
    dist = 1.25 * half / (np.tan(np.radians(fov / 2)) * aspect) + 1.5
    pitch = np.radians(35)
    eye = np.array([0.0, 1.0 + dist * np.sin(pitch), dist * np.cos(pitch)])
    return Camera.look_at(eye, (0.0, 0.5, 0.0), fov_y=fov, near=0.1, far=dist * 4)


def time_cases(cases, state, cam, size, frames, warmup, advance):
    """Median frame time of each case, the cases drawn round-robin (rotating
    the order every frame) so all see the same machine load.

    cases : list of (name, renderer, selector). Returns {name: median
    seconds}, {name: per-frame seconds}, the median select time of the first
    case, the last DrawList of each case and {name: per-frame CPU seconds}.
    """
    times = {name: [] for name, _, _ in cases}
    cpu = {name: [] for name, _, _ in cases}  # CPU seconds of every thread (the driver's included)
    sel_t, last = [], {}
    for k in range(warmup + frames):
        rot = k % len(cases)
        for name, renderer, sel in cases[rot:] + cases[:rot]:
            t0 = time.perf_counter()
            dl = sel.select(state, cam, size)
            t1, c1 = time.perf_counter(), time.process_time()
            renderer.draw(dl)  # ends with ctx.finish()
            t2, c2 = time.perf_counter(), time.process_time()
            if k >= warmup:
                times[name].append(t2 - t1)
                cpu[name].append(c2 - c1)
                if name == cases[0][0]:
                    sel_t.append(t1 - t0)
            last[name] = dl
        state.anim_time += advance
    med = {name: statistics.median(v) for name, v in times.items()}
    return med, times, statistics.median(sel_t), last, cpu


def paired_ratio(a, b) -> float:
    """Median of per-frame ratios a[i] / b[i]."""
    return statistics.median(x / y for x, y in zip(a, b))


def hardware_line(ctx) -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    info = gl_info(ctx)
    return f"{cpu}, {os.cpu_count()} logical cores; GL: {info['GL_RENDERER']} ({info['GL_VERSION']})"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[100, 1000, 10000])
    ap.add_argument("--triangles", type=int, default=5000)
    ap.add_argument("--frames", type=int, default=3, help="timed frames per case (median)")
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--out", type=Path, default=ROOT / "scripts" / "bench_baseline.md")
    args = ap.parse_args(argv)

    size = tuple(args.size)
    ch = humanoid(args.triangles, seed=0)
    skinned = build_rep(ch, fps=30, key="none:humanoid")
    static = build_rep(ch.mesh, key="static:humanoid")
    renderer = Renderer(size, skinning="palette")
    direct = Renderer(size, ctx=renderer.ctx, skinning="direct")
    for r in (renderer, direct):
        r.upload(skinned)
        r.upload(static)
    hw = hardware_line(renderer.ctx)
    load0 = os.getloadavg()[0]
    rows = []
    print(f"# {hw}")
    print(f"{'instances':>9} {'drawn':>7} {'triangles':>11} {'skinned ms':>11} {'static ms':>10} "
          f"{'ratio':>6} {'best':>5} {'cpu':>5} {'direct ms':>10} {'ratio':>6} {'skinned Mtri/s':>15} {'static Mtri/s':>14} "
          f"{'select ms':>10}")
    for n in args.counts:
        rng = np.random.default_rng(n)  # same grid, headings and phases for every path
        st = grid_state(n, rng)
        cam = framing_camera(n, size[0] / size[1])
        cases = [("skinned", renderer, NoLodSelector([skinned])), ("static", renderer, NoLodSelector([static])),
                 ("direct", direct, NoLodSelector([skinned]))]
        med, per, sel_ms, last, cpu = time_cases(cases, st, cam, size, args.frames, args.warmup, 1 / 30)
        dl, dl_st = last["skinned"], last["static"]
        tri = dl.triangles
        row = dict(n=n, drawn=dl.n_instances, tri=tri, sk=med["skinned"], st=med["static"], di=med["direct"],
                   ratio=paired_ratio(per["skinned"], per["static"]),
                   best=min(per["skinned"]) / min(per["static"]),
                   ratio_di=paired_ratio(per["direct"], per["static"]),
                   ratio_cpu=paired_ratio(cpu["skinned"], cpu["static"]),
                   sk_rate=tri / med["skinned"] / 1e6, st_rate=dl_st.triangles / med["static"] / 1e6, sel=sel_ms)
        rows.append(row)
        print(f"{n:>9} {row['drawn']:>7} {tri:>11,} {row['sk'] * 1e3:>11.1f} {row['st'] * 1e3:>10.1f} "
              f"{row['ratio']:>6.2f} {row['best']:>5.2f} {row['ratio_cpu']:>5.2f} {row['di'] * 1e3:>10.1f} {row['ratio_di']:>6.2f} "
              f"{row['sk_rate']:>15.2f} {row['st_rate']:>14.2f} {sel_ms * 1e3:>10.2f}")
    direct.release()
    renderer.release()
    load1 = os.getloadavg()[0]

    lines = [
        "# NoLOD baseline: skinned vs static instanced draw",
        "",
        f"Hardware: {hw}.",
        "",
        f"`scripts/bench_baseline.py` at {size[0]}x{size[1]}: a {skinned.n_triangles:,}-triangle procedural humanoid "
        f"(`sim.procedural.humanoid({args.triangles})`, {skinned.n_joints} joints, clips baked at 30 fps) on a grid "
        "filling the view; median of "
        f"{args.frames} frames after {args.warmup} warm-up frame(s), `ctx.finish()` before the clock stops. "
        "*static* draws the same mesh, same instances, through the static instancing path. "
        "*skinned* is the default palette path (a transform-feedback pre-pass blends every instance's joint "
        "matrices between its two baked frames once per frame; the vertex shader then reads 3 texels per "
        "influence); *direct* blends both frames in the vertex shader (6 texels per influence). "
        "The three cases are drawn round-robin, rotating the order every frame, so all see the same load on a "
        "shared machine; each *ratio* is the median of per-frame ratios to *static* (the cost of GPU skinning; "
        "target <= 1.3); *best* is the ratio of the fastest frames (min / min), the estimate least disturbed by "
        "other processes; *CPU ratio* is the median per-frame ratio of the CPU time of all the process's threads "
        "(the driver's rasterizer threads included: the work done, which other jobs inflate far less than the wall "
        "time). *select ms* is the CPU time of NoLodSelector.select (culling, instance data, batching).",
        "",
        "| instances | drawn | triangles | skinned ms | static ms | ratio | best | CPU ratio | direct ms | direct ratio "
        "| skinned Mtri/s | static Mtri/s | select ms |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        lines.append(f"| {r['n']:,} | {r['drawn']:,} | {r['tri']:,} | {r['sk'] * 1e3:.1f} | {r['st'] * 1e3:.1f} | "
                     f"{r['ratio']:.2f} | {r['best']:.2f} | {r['ratio_cpu']:.2f} | {r['di'] * 1e3:.1f} | {r['ratio_di']:.2f} | {r['sk_rate']:.2f} | "
                     f"{r['st_rate']:.2f} | {r['sel'] * 1e3:.2f} |")
    lines += [
        "",
        f"1-minute load average {load0:.1f} at the start and {load1:.1f} at the end of the run (2 cores shared with "
        "other jobs): llvmpipe renders on the CPU, so frame times move with the load and the ratios vary by about "
        "+-0.15 from run to run; the per-frame paired ratio and the best-frame ratio are the robust figures. "
        "Skinning adds vertex work only (texel fetches and a weighted sum per influence), so its relative cost "
        "grows as characters shrink on screen and vertex work outweighs rasterisation (10,000 instances).",
        "",
    ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".md.tmp")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
