"""Benchmark and image check of the compute rasteriser of small triangles (issue 29, render/raster/).

For every shipped scene (``scenes/*.toml``; ``million`` only when named) in its own LOD mode (``--modes`` adds
others): the engine steps ``--steps`` frames, one DrawList is selected, and it is drawn alternately with the
compute rasteriser on (``[render] raster_threshold``) and off (every triangle through the hardware path), round-
robin, ``--frames`` timed draws each after a warm-up. Reported: the PSNR of the two images (acceptance: >= 45 dB
on every scene, the worst stated), the triangles the compute path took (``stats["raster_triangles"]``) of the
frame's total, and the median CPU time (every thread of the process: llvmpipe's) and wall time of a draw with
each path, with their ratio (> 1: the compute path is faster). The machine's load is printed at the start and
the end (the figures an acceptance rests on are taken on a quiet machine).

Run:  .venv/bin/python scripts/bench_raster.py [--scenes grid office ...] [--modes none triangles ...]
      [--size 1280 720] [--steps 3] [--frames 3] [--out scripts/bench_raster.md]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "scripts"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

#: scenes drawn only when --scenes names them
NAMED_ONLY = ("million",)
#: LOD options that keep cold hierarchy builds short (as scripts/frame_digests.py)
LOD = {"points": {"keyframes": 3, "intervals": 1}, "auto": {"keyframes": 3, "adapt": False}}


def psnr(a, b) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def run_scene(path: Path, mode: str | None, size, steps: int, frames: int) -> dict:
    from crowd.engine import Engine
    from crowd.report.settings import expand_settings

    sweeps = [] if mode is None else [("lod.mode", [mode])] + [(f"lod.{k}", [v]) for k, v in LOD.get(mode, {}).items()]
    setting = expand_settings(path, sweeps, size=tuple(size), frames=steps + 1)[0]
    with Engine(setting.scene, quiet=True) as eng:
        r = eng._open_renderer()
        for _ in range(steps):
            eng.step()
        cam = eng.camera_at(eng.world.time)
        dl = eng.select(cam, tuple(size))
        on = bool(r.compute_raster)
        images, wall, cpu, share = {}, {True: [], False: []}, {True: [], False: []}, 0
        for k in range(frames + 1):
            for c in ((True, False) if k % 2 == 0 else (False, True)):
                r.compute_raster = c and on
                t0, c0 = time.perf_counter(), time.process_time()
                r.draw(dl, setting.scene.render.background)
                t1, c1 = time.perf_counter(), time.process_time()
                if k:
                    wall[c].append(t1 - t0)
                    cpu[c].append(c1 - c0)
                if k == frames:
                    images[c] = r.read_pixels().copy()
                if c:
                    share = int(dl.stats.get("raster_triangles", 0))
        return {"mode": eng.scene.lod_mode if mode is None else mode, "psnr": psnr(images[True], images[False]),
                "triangles": int(dl.stats.get("triangles", dl.triangles)), "raster": share,
                "cpu": {c: statistics.median(v) for c, v in cpu.items()},
                "wall": {c: statistics.median(v) for c, v in wall.items()}}


def machine_note() -> str:
    import os

    return "load average " + " / ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", help="scene names (default: every shipped scene but million)")
    ap.add_argument("--modes", nargs="+", help="LOD modes (default: each scene's own)")
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--steps", type=int, default=3)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "scripts" / "bench_raster.md")
    args = ap.parse_args(argv)
    if args.frames < 1 or args.steps < 0:
        print("bench_raster.py: --frames must be >= 1 and --steps >= 0", file=sys.stderr)
        return 2
    names = args.scenes or sorted(p.stem for p in (ROOT / "scenes").glob("*.toml") if p.stem not in NAMED_ONLY)
    paths = []
    for n in names:
        p = ROOT / "scenes" / f"{n}.toml"
        if not p.is_file():
            print(f"bench_raster.py: --scenes: no scene {p}", file=sys.stderr)
            return 2
        paths.append(p)
    start = machine_note()
    print(f"# start: {start}")
    rows = []
    for p in paths:
        for mode in (args.modes or [None]):
            t0 = time.perf_counter()
            r = run_scene(p, mode, args.size, args.steps, args.frames)
            q = "identical" if r["psnr"] == float("inf") else f"{r['psnr']:.1f}"
            ratio_c = r["cpu"][False] / r["cpu"][True]
            ratio_w = r["wall"][False] / r["wall"][True]
            rows.append(f"| {p.stem} | {r['mode']} | {r['triangles']:,} | {r['raster']:,} | {q} | "
                        f"{r['cpu'][False] * 1e3:.1f} | {r['cpu'][True] * 1e3:.1f} | {ratio_c:.2f}x | "
                        f"{r['wall'][False] * 1e3:.1f} | {r['wall'][True] * 1e3:.1f} | {ratio_w:.2f}x |")
            rows[-1] = (rows[-1], r["psnr"])
            print(f"{p.stem:12s} {r['mode']:9s} tris {r['triangles']:>11,} compute {r['raster']:>11,}  PSNR {q:>9s}  "
                  f"cpu {r['cpu'][False] * 1e3:7.1f} -> {r['cpu'][True] * 1e3:7.1f} ms ({ratio_c:.2f}x)  "
                  f"wall {r['wall'][False] * 1e3:7.1f} -> {r['wall'][True] * 1e3:7.1f} ms ({ratio_w:.2f}x)  "
                  f"[{time.perf_counter() - t0:.0f} s]", flush=True)
    end = machine_note()
    print(f"# end: {end}")
    worst = min(q for _, q in rows) if rows else float("inf")
    from lod.atomic_io import write_atomic

    text = f"""# Compute rasteriser of small triangles: images and draw times on the shipped scenes (issue 29)

Command: `scripts/bench_raster.py {' '.join(sys.argv[1:] if argv is None else argv)}`. Each scene in its LOD mode,
{args.size[0]}x{args.size[1]}, the DrawList after {args.steps} steps drawn with the compute rasteriser on and off,
alternately, {args.frames} timed draws each (medians). "compute" = triangles the compute path took
(`stats["raster_triangles"]`); PSNR of the two images (acceptance >= 45 dB); CPU = every thread of the process
(llvmpipe's rasteriser and compute threads); "x" > 1: the compute path is faster. Mesa llvmpipe through EGL.

| scene | mode | triangles | compute | PSNR dB | CPU ms hardware | CPU ms compute | CPU | wall ms hardware | wall ms compute | wall |
| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |
{chr(10).join(r for r, _ in rows)}

Worst PSNR: {'identical' if worst == float('inf') else f'{worst:.1f} dB'}. Machine at the start: {start}; at the end: {end}.
"""
    write_atomic(args.out, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
