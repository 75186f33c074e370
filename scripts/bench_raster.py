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


def alternate(r, dl, variants, setup, frames: int, background=(0.1, 0.1, 0.12)) -> dict:
    """Draw ``dl`` with each variant in turn (``setup(v)`` configures the renderer ``r``; the order rotated every
    round), ``frames`` timed rounds after a warm-up. Returns {"cpu", "wall": variant -> median seconds,
    "images": variant -> the last image, "share": variant -> stats["raster_triangles"], "counts": variant -> the
    rasteriser's last counts}."""
    cpu = {v: [] for v in variants}
    wall = {v: [] for v in variants}
    images, share, counts = {}, {}, {}
    for k in range(frames + 1):
        rot = k % len(variants)
        for v in variants[rot:] + variants[:rot]:
            setup(v)
            t0, c0 = time.perf_counter(), time.process_time()
            r.draw(dl, background)
            t1, c1 = time.perf_counter(), time.process_time()
            if k:
                wall[v].append(t1 - t0)
                cpu[v].append(c1 - c0)
            if k == frames:
                images[v] = r.read_pixels().copy()
            share[v] = int(dl.stats.get("raster_triangles", 0))
            counts[v] = dict(r.raster.last_counts) if r.compute_raster else {}
    return {"cpu": {v: statistics.median(x) for v, x in cpu.items()},
            "wall": {v: statistics.median(x) for v, x in wall.items()}, "images": images, "share": share,
            "counts": counts}


def run_scene(path: Path, mode: str | None, size, steps: int, frames: int, thresholds=(), route_all=False) -> dict:
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
        scene_t = float(r.raster_threshold)
        r.raster.route_all = bool(route_all)  # every eligible copy to compute: the image check of the whole path
        # variants: "scene" = the scene's threshold, "hardware" = hardware only, a number = that threshold
        variants = ["scene", "hardware", *[float(t) for t in thresholds]]

        def setup(v):
            r.compute_raster = on and v != "hardware"
            r.raster_threshold = scene_t if isinstance(v, str) else v

        t = alternate(r, dl, variants, setup, frames, setting.scene.render.background)
        r.raster_threshold = scene_t
        images, share = t["images"], t["share"]
        out = {"mode": eng.scene.lod_mode if mode is None else mode, "psnr": psnr(images["scene"], images["hardware"]),
               "triangles": int(dl.stats.get("triangles", dl.triangles)) + int(dl.stats.get("props", 0)),
               "raster": share["scene"], "share": share, "cpu": t["cpu"], "wall": t["wall"],
               "psnr_t": {v: psnr(images[v], images["hardware"]) for v in variants if not isinstance(v, str)}}
        return out


def peer_case(key: str, n: int, size, frames: int, models_dir: Path) -> dict:
    """The crowd of scripts/bench_peer.py (model ``key`` x ``n``, its grid and camera) drawn in mode none by
    the hardware path and by the compute rasteriser, round-robin: CPU and wall medians, PSNR, compute share."""
    import tempfile

    import bench_peer as bp

    from crowd.engine import Engine
    from crowd.scene import load_scene
    from sim.gltf.load import load_gltf

    path, desc = bp.model_paths(models_dir)[key]
    if path is None:
        return {"desc": desc, "skipped": True}
    ch = load_gltf(path)
    rest = np.asarray(ch.mesh.positions, np.float64)
    sc = bp.scenario(float((rest.max(0) - rest.min(0)).max()), n)
    with tempfile.TemporaryDirectory() as td:
        sp = Path(td) / "s.toml"
        sp.write_text(bp.scene_text(path.resolve(), ch.clip_names()[0], sc, size))
        eng = Engine(load_scene(sp), quiet=True)
    with eng:
        r = eng._open_renderer()
        eng.step()
        dl = eng.select(eng.camera_at(eng.world.time), tuple(size))
        variants = ("hardware", "compute raster, a gathered copy per instance", "compute raster, slots gathered once")

        def setup(v):
            r.compute_raster = v != "hardware"
            r.raster.share_poses = v == variants[2]

        t = alternate(r, dl, variants, setup, frames, eng.scene.render.background)
        images, share, cpu, wall = t["images"], t["share"][variants[1]], t["cpu"], t["wall"]
        r.raster.share_poses = True
        return {"desc": desc, "n": n, "triangles": int(dl.triangles), "compute": share,
                "psnr": psnr(images[variants[0]], images[variants[1]]), "variants": variants,
                "cpu": cpu, "wall": wall}


def size_sweep(sizes, size, frames: int, triangles: int = 3000) -> list:
    """The cost of a triangle on each path as its size on screen grows: a static humanoid of ``triangles``
    triangles (the posed mesh the pose cache hands both paths) on a grid facing the camera at the distance
    where its triangles' 90th-percentile window extent is ``s`` pixels (lod/raster_route.py), as many copies as
    fit the view (at most 400); the hardware path and the compute path (every copy routed to it, threshold 64
    px) drawn alternately. Returns rows (s, copies, triangles, candidates, hardware and compute CPU / wall ms)."""
    import lod.raster_route as rr
    from lod.drawlist import DrawBatch, DrawList
    from lod.full.reps import build_static_rep
    from lod.view import Camera
    from render.renderer import Renderer
    from sim.procedural import humanoid

    rep = build_static_rep(humanoid(triangles, 5).mesh, key="sweep")
    ext, radius, centre = rr.triangle_extent(rep.positions, rep.indices)
    w, h = size
    fov = 50.0
    focal = 0.5 * h / np.tan(np.radians(fov / 2))
    height = float(rep.aabb[1, 1] - rep.aabb[0, 1])
    rows_out = []
    with Renderer(size) as r:
        r.upload(rep)
        cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=fov, near=0.05, far=5000.0)
        view, proj = cam.view_matrix(), cam.projection(w / h)
        for s in sizes:
            d = ext * focal / s + radius  # the nearest point of the sphere at extent/d = s px
            span_y = 2 * d * np.tan(np.radians(fov / 2))
            spacing = 1.1 * height
            ny = max(1, min(20, int(span_y / spacing)))
            nx = max(1, min(20, int(span_y * w / h / spacing)))
            gx, gy = np.meshgrid((np.arange(nx) - (nx - 1) / 2) * spacing, (np.arange(ny) - (ny - 1) / 2) * spacing)
            k = gx.size
            data = np.zeros((k, 16), np.float32)
            data[:, [0, 5, 10]] = 1.0
            data[:, 3] = gx.ravel()
            data[:, 7] = gy.ravel() - centre[1]
            data[:, 11] = -d
            dl = DrawList(np.zeros(3), view, proj, size, [DrawBatch("sweep", 0, np.arange(k, dtype=np.int32), data,
                                                                    triangles=k * rep.n_triangles)])
            def setup(v):
                r.compute_raster = v == "compute"
                r.raster.route_all = True
                r.raster_threshold = rr.MAX_THRESHOLD

            t = alternate(r, dl, ("compute", "hardware"), setup, frames)
            cand = t["counts"]["compute"].get("candidates", 0)
            row = (s, k, k * rep.n_triangles, cand, *(t["cpu"][v] * 1e3 for v in ("hardware", "compute")),
                   *(t["wall"][v] * 1e3 for v in ("hardware", "compute")))
            print(f"  {s:5g} px: {k:4d} copies {row[2]:>10,} triangles  CPU hardware {row[4]:7.1f} compute {row[5]:7.1f} ms "
                  f"({row[4] / row[5]:.2f}x)  wall {row[6]:7.1f} / {row[7]:7.1f} ms ({row[6] / row[7]:.2f}x)", flush=True)
            rows_out.append(row)
    return rows_out


RASTER_BEGIN = "<!-- bench_raster.py --peer-models: begin (rows of the compute rasteriser, issue 29) -->"
RASTER_END = "<!-- bench_raster.py --peer-models: end -->"


def write_full_detail_rows(md: Path, cases: list, command: str, start: str, end: str) -> None:
    """Put the compute rasteriser's rows into scripts/bench_full_detail.md between the RASTER markers (that
    section only: the rest of the file is scripts/bench_full_detail.py's), atomically."""
    from sim.atomic_io import write_atomic

    lines = [RASTER_BEGIN, "", "## Compute rasteriser of small triangles (issue 29; `scripts/bench_raster.py`)", "",
             f"Command: `{command}`. The same crowds (bench_peer's grid and camera), mode none, drawn by the "
             "shipped hardware path and with the compute rasteriser on, alternately; medians. Both compute "
             "variants read the pose cache's posed vertices (render/poses/cache.py: each distinct pose skinned "
             "once); \"a gathered copy per instance\": the rasteriser copies a slot's posed vertices into its own "
             "table once per instance (Raster.share_poses = False); \"slots gathered once\": once per slot "
             "(the shipped default; the bench's copies all play from time 0, so one slot). "
             "PSNR: compute against hardware.", "",
             "| crowd | variant | CPU ms (median) | speed vs hardware, CPU | wall ms (median) | speed vs hardware, wall | "
             "triangles in compute | PSNR vs hardware (dB) |", "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for c in cases:
        if c.get("skipped"):
            lines.append(f"| {c['desc']} | - | | | | | | |")
            continue
        h = "hardware"
        for v in c["variants"]:
            q = "-" if v == h else ("identical" if c["psnr"] == float("inf") else f"{c['psnr']:.1f}")
            lines.append(f"| {c['desc']} x{c['n']:,} | {v} | {c['cpu'][v] * 1e3:.1f} | {c['cpu'][h] / c['cpu'][v]:.2f}x | "
                         f"{c['wall'][v] * 1e3:.1f} | {c['wall'][h] / c['wall'][v]:.2f}x | "
                         f"{(c['compute'] if v != h else 0):,} of {c['triangles']:,} | {q} |")
    lines += ["", f"Machine at the start: {start}; at the end: {end}.", "", RASTER_END]
    text = md.read_text() if md.is_file() else ""
    if RASTER_BEGIN in text and RASTER_END in text:
        a = text.index(RASTER_BEGIN)
        b = text.index(RASTER_END) + len(RASTER_END)
        text = text[:a] + "\n".join(lines) + text[b:]
    else:
        text = text.rstrip("\n") + "\n\n" + "\n".join(lines) + "\n"
    write_atomic(md, text)


def _sweep_text(sweep: list) -> str:
    if not sweep:
        return ""
    return ("\n## The threshold (`--thresholds`): each value timed in the same rounds as the hardware path\n\n"
            "| scene | mode | threshold px | compute | PSNR dB | CPU ms | CPU vs hardware | wall ms | wall vs hardware |\n"
            "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n" + "\n".join(sweep) + "\n")


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
    ap.add_argument("--route-all", action="store_true",
                    help="every eligible copy to the compute path (its triangles beyond 4x the threshold still go "
                         "back): the PSNR of compute-rasterised frames, not of the default split")
    ap.add_argument("--thresholds", type=float, nargs="*", default=[],
                    help="also time these [render] raster_threshold values (pixels): the default's measurement")
    ap.add_argument("--out", type=Path, default=ROOT / "scripts" / "bench_raster.md")
    ap.add_argument("--peer-models", nargs="+", choices=["h4", "h1", "fox", "cesiumman"],
                    help="instead: bench_peer's crowds (h4, h1 x100, fox x1024), hardware vs compute, rows into "
                         "scripts/bench_full_detail.md")
    ap.add_argument("--models-dir", type=Path, default=ROOT / "out" / "bench_peer" / "models")
    ap.add_argument("--assets", type=Path, help="folder of the shared glTF assets (Fox, CesiumMan) when not "
                                                "scripts/bench_peer.py's ../shared/assets")
    ap.add_argument("--sizes", type=float, nargs="*", default=[],
                    help="instead: the triangle-size sweep behind the default threshold (pixels of triangle extent)")
    args = ap.parse_args(argv)
    if args.sizes:
        start = machine_note()
        print(f"# start: {start}")
        rows = size_sweep(args.sizes, tuple(args.size), args.frames)
        end = machine_note()
        print(f"# end: {end}")
        from sim.atomic_io import write_atomic

        cmd = "scripts/bench_raster.py " + " ".join(sys.argv[1:] if argv is None else argv)
        table = "\n".join(f"| {s:g} | {k:,} | {t:,} | {c:,} | {hc:.1f} | {cc:.1f} | {hc / cc:.2f}x | {hw:.1f} | {cw:.1f} | "
                          f"{hw / cw:.2f}x |" for s, k, t, c, hc, cc, hw, cw in rows)
        write_atomic(args.out, f"""# Compute rasteriser: the cost of a triangle by its size on screen (issue 29)

Command: `{cmd}`. A static 3,000-triangle humanoid on a grid facing the camera at the distance where its
triangles' 90th-percentile window extent is the given size; both paths alternately ({args.frames} timed draws each,
medians; the compute path takes every copy, threshold 64 px). "x" > 1: the compute path is faster.

| triangle extent px | copies | triangles | compute candidates | CPU ms hardware | CPU ms compute | CPU | wall ms hardware | wall ms compute | wall |
| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |
{table}

Machine at the start: {start}; at the end: {end}.
""")
        return 0
    if args.peer_models:
        if args.assets is not None:
            import bench_peer

            bench_peer.ASSETS = args.assets
        start = machine_note()
        print(f"# start: {start}")
        cases = []
        for key in args.peer_models:
            n = 1024 if key == "fox" else 100
            c = peer_case(key, n, args.size, args.frames, args.models_dir)
            cases.append(c)
            if not c.get("skipped"):
                print(f"{key} x{n}: " + "; ".join(f"{v} cpu {c['cpu'][v] * 1e3:.1f} wall {c['wall'][v] * 1e3:.1f}"
                                                  for v in c["variants"])
                      + f" ms; PSNR {c['psnr']:.1f}; {c['compute']:,} of {c['triangles']:,} in compute", flush=True)
        end = machine_note()
        print(f"# end: {end}")
        cmd = "scripts/bench_raster.py " + " ".join(sys.argv[1:] if argv is None else argv)
        write_full_detail_rows(ROOT / "scripts" / "bench_full_detail.md", cases, cmd, start, end)
        return 0
    if args.frames < 1 or args.steps < 0:
        print("bench_raster.py: --frames must be >= 1 and --steps >= 0", file=sys.stderr)
        return 2
    from crowd.scene import shipped_scenes

    names = args.scenes or [p.stem for p in shipped_scenes(ROOT / "scenes") if p.stem not in NAMED_ONLY]
    paths = []
    for n in names:
        p = ROOT / "scenes" / f"{n}.toml"
        if not p.is_file():
            print(f"bench_raster.py: --scenes: no scene {p}", file=sys.stderr)
            return 2
        paths.append(p)
    start = machine_note()
    print(f"# start: {start}")
    rows, sweep = [], []
    for p in paths:
        for mode in (args.modes or [None]):
            t0 = time.perf_counter()
            r = run_scene(p, mode, args.size, args.steps, args.frames, args.thresholds, args.route_all)
            for t in args.thresholds:
                sweep.append(f"| {p.stem} | {r['mode']} | {t:g} | {r['share'][t]:,} | {r['psnr_t'][t]:.1f} | "
                             f"{r['cpu'][t] * 1e3:.1f} | {r['cpu']['hardware'] / r['cpu'][t]:.2f}x | "
                             f"{r['wall'][t] * 1e3:.1f} | {r['wall']['hardware'] / r['wall'][t]:.2f}x |")
                print(f"    threshold {t:g}: compute {r['share'][t]:,}  cpu {r['cpu'][t] * 1e3:.1f} ms "
                      f"({r['cpu']['hardware'] / r['cpu'][t]:.2f}x)  wall {r['wall'][t] * 1e3:.1f} ms "
                      f"({r['wall']['hardware'] / r['wall'][t]:.2f}x)", flush=True)
            q = "identical" if r["psnr"] == float("inf") else f"{r['psnr']:.1f}"
            ratio_c = r["cpu"]['hardware'] / r["cpu"]['scene']
            ratio_w = r["wall"]['hardware'] / r["wall"]['scene']
            rows.append(f"| {p.stem} | {r['mode']} | {r['triangles']:,} | {r['raster']:,} | {q} | "
                        f"{r['cpu']['hardware'] * 1e3:.1f} | {r['cpu']['scene'] * 1e3:.1f} | {ratio_c:.2f}x | "
                        f"{r['wall']['hardware'] * 1e3:.1f} | {r['wall']['scene'] * 1e3:.1f} | {ratio_w:.2f}x |")
            rows[-1] = (rows[-1], r["psnr"])
            print(f"{p.stem:12s} {r['mode']:9s} tris {r['triangles']:>11,} compute {r['raster']:>11,}  PSNR {q:>9s}  "
                  f"cpu {r['cpu']['hardware'] * 1e3:7.1f} -> {r['cpu']['scene'] * 1e3:7.1f} ms ({ratio_c:.2f}x)  "
                  f"wall {r['wall']['hardware'] * 1e3:7.1f} -> {r['wall']['scene'] * 1e3:7.1f} ms ({ratio_w:.2f}x)  "
                  f"[{time.perf_counter() - t0:.0f} s]", flush=True)
    end = machine_note()
    print(f"# end: {end}")
    worst = min(q for _, q in rows) if rows else float("inf")
    from sim.atomic_io import write_atomic

    text = f"""# Compute rasteriser of small triangles: images and draw times on the shipped scenes (issue 29)

Command: `scripts/bench_raster.py {' '.join(sys.argv[1:] if argv is None else argv)}`. Each scene in its LOD mode,
{args.size[0]}x{args.size[1]}, the DrawList after {args.steps} steps drawn with the compute rasteriser on and off,
alternately, {args.frames} timed draws each (medians). "compute" = triangles the compute path took
(`stats["raster_triangles"]`; with `--route-all` every eligible copy); PSNR of the two images (acceptance >= 45 dB);
CPU = every thread of the process
(llvmpipe's rasteriser and compute threads); "x" > 1: the compute path is faster. Mesa llvmpipe through EGL.

| scene | mode | triangles | compute | PSNR dB | CPU ms hardware | CPU ms compute | CPU | wall ms hardware | wall ms compute | wall |
| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |
{chr(10).join(r for r, _ in rows)}

Worst PSNR: {'identical' if worst == float('inf') else f'{worst:.1f} dB'}. Machine at the start: {start}; at the end: {end}.
{_sweep_text(sweep)}"""
    write_atomic(args.out, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
