"""Benchmark: a million independently moving agents (issues 21 and 26, ``scenes/million.toml``).

The scene is the bar of issue 26: a million boids humanoids (5,000 triangles) over 2 x 2 km, the camera
above the middle of one edge at half the field's width up and 0.6 of it back (the view of
``scripts/bench_peer.py``), 1280 x 720; mode auto at 2 pixels. Acceptance: mode auto >= 4 frames per
second end to end, selection <= 60 ms, on this 2-core machine.

Runs the scene end to end (``crowd.engine.Engine``, as ``crowd run`` does) once per LOD mode, each in
a subprocess of its own (so its peak memory is its own); ``points-root`` is mode points with
``coarse = false`` (every far agent drawn from its whole hierarchy root, as before
``lod/points/coarse.py``). Prints per mode:

- scene load: seconds from the scene file to the first frame with the LOD cache warm;
- per-stage medians per frame from the telemetry (``frames.csv``: simulate, select, upload, draw,
  finish, total) over the frames after ``--warmup``; frames per second from the median total;
- ``cpu ms``: the process's CPU time per measured frame (all threads: numba's and llvmpipe's), the work
  a frame costs whatever else runs on the machine;
- points per agent drawn, triangles;
- memory: the peak resident size of the process (``ru_maxrss``) and the memory guard's estimate
  (``crowd.memory.estimate_scene``);

then the growth table: the first mode on the scene at 10 K, 100 K, 300 K and 1 M agents at the same density
with the view scaled with sqrt(N) (``--growth``, each in its own process); the image error of a window of one
frame against full detail drawn with 4 x 4 samples per pixel and box-filtered, for every mode and the aliased
full-detail frame (``--no-image`` skips it: the reference draws ~0.5 M agents at full detail, minutes); then,
in one process, mode auto's selection of the same frame by the flat path (``lod/auto/flat.py``)
and by the per-group path it replaced (``AutoSelector.flat = False``), interleaved (a ratio measured in
one run survives the load); and the serial/parallel comparison of two per-agent kernels. The load
average before and after, and the busiest other processes at the start, are printed: the machine is
shared, absolute figures compare only within a run.

Run:  .venv/bin/python scripts/bench_million.py [--scene scenes/million.toml] [--modes points auto]
      [--frames 10] [--warmup 3] [--md scripts/bench_million.md] [--no-kernels] [--no-selection] [--no-image]
      [--growth 10000 100000 300000 1000000]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

STAGES = ("simulate", "select", "upload", "draw", "finish", "total")


def _fail(msg: str) -> None:
    print(f"bench_million.py: {msg}", file=sys.stderr)
    raise SystemExit(2)


#: mode variants: ``<mode>-<variant>`` runs the mode with these ``[lod]`` keys over the scene's own
VARIANTS = {"root": {"coarse": False},  # points drawn from whole roots at least (no coarser prefixes)
            "far": {"far_pixels": 2.0},  # the far tier on (lod.far)
            "nofar": {"far_pixels": 0.0}}  # the far tier off: the before of issue 45


def _scene(scene_path: str, mode: str):
    from crowd.scene import load_scene

    scene = load_scene(scene_path)
    base, _, variant = mode.partition("-")
    params = dict(scene.lod_params) if scene.lod_mode == base else {}
    params.update(VARIANTS.get(variant, {}))
    return replace(scene, lod_mode=base, lod_params=tuple(params.items()))


def scaled_scene(scene, n: int):
    """The million scene at ``n`` agents and the same density: the grid's rows and columns, its origin, the
    boids' bounds and the camera's position and target (and far plane) scaled by sqrt(n / its agents), so the
    view frames the crowd as it does at a million (issue 45's growth table)."""
    import math

    p0 = scene.placements[0]
    rows, cols = int(p0.params["rows"]), int(p0.params["cols"])
    f = math.sqrt(float(n) / float(rows * cols))
    side = max(1, int(round(math.sqrt(n))))
    q = dict(p0.params, rows=side, cols=side, origin=[v * f for v in p0.params["origin"]])
    effects = tuple(replace(e, params=dict(e.params, bounds=[v * f for v in e.params["bounds"]]))
                    if "bounds" in e.params else e for e in scene.effects)
    cam = replace(scene.camera, position=tuple(v * f for v in scene.camera.position),
                  target=tuple(v * f for v in scene.camera.target), far=max(scene.camera.far * f, 100.0))
    return replace(scene, placements=(replace(p0, params=q),) + tuple(scene.placements[1:]), effects=effects,
                   camera=cam)


def _mode_ok(mode: str, modes) -> bool:
    base, _, variant = mode.partition("-")
    return base in modes and (not variant or variant in VARIANTS)


def image_error(scene_path: str, modes, frame: int = 8, crop=(448, 288, 384, 216), k: int = 4) -> dict:
    """PSNR (dB) of each mode's frame ``frame`` against full detail drawn with K x K samples per pixel and
    box-filtered (``crowd/reference.py``), over the pixel window ``crop`` (x, y from the top left, width,
    height): a million agents at full detail are 5 G triangles, so the reference draws only the agents whose
    position projects within 16 pixels of the window (at K x the pixels, through ``tile_projection``). Also the
    aliased full-detail frame (one sample per pixel) of the same window, and each image's mean colour there."""
    import numpy as np

    from crowd.engine import Engine
    from crowd.reference import box_filter, reference_scene, tile_projection

    x0, y0, cw, ch = (int(v) for v in crop)
    out = {}

    def window(img):
        return img[y0:y0 + ch, x0:x0 + cw]

    full = reference_scene(_scene(scene_path, "none"))
    with Engine(full, quiet=True) as eng:
        for _ in range(frame + 1):
            eng.step()
        cam = eng.camera_at(eng.world.time)
        W, H = full.render.size
        bg = full.render.background
        for kk in (k, 1):
            dl = eng.select(cam, (kk * W, kk * H))
            vp = np.asarray(dl.proj, np.float64) @ np.asarray(dl.view, np.float64)
            keep = []
            for b in dl.batches:
                d = np.asarray(b.instance_data, np.float64)
                if not b.rep.startswith("none:") or int(np.asarray(b.instance_ids)[0]) < 0:
                    keep.append(b)  # the ground, scenery, statics: whole
                    continue
                c = d[:, [3, 7, 11]] @ vp[:3, :3].T + vp[:3, 3]
                wc = d[:, [3, 7, 11]] @ vp[3, :3] + vp[3, 3]
                px = (c[:, 0] / wc * 0.5 + 0.5) * W
                py = (1.0 - (c[:, 1] / wc * 0.5 + 0.5)) * H
                m = (wc > 0) & (px > x0 - 16) & (px < x0 + cw + 16) & (py > y0 - 16) & (py < y0 + ch + 16)
                if m.any():
                    keep.append(replace(b, instance_ids=b.instance_ids[m], instance_data=b.instance_data[m],
                                        triangles=int(b.triangles * m.sum() / max(1, m.size))))
            r = eng.open_renderer(size=(kk * cw, kk * ch))
            r.pose_sharing = False
            tile = replace(dl, batches=keep, poses=None, size=(kk * cw, kk * ch),
                           proj=tile_projection(dl.proj, (W, H), (x0, y0), (cw, ch)).astype(np.float32))
            r.draw(tile, bg)
            img = box_filter(r.read_pixels(), kk)
            if kk == k:
                ref = img
                out["agents in the window"] = int(sum(b.n_instances for b in keep if b.n_instances
                                                      and int(np.asarray(b.instance_ids)[0]) >= 0))
            else:
                out["none (aliased)"] = img
    for m in modes:
        with Engine(_scene(scene_path, m), quiet=True) as eng:
            r = eng._open_renderer()
            for _ in range(frame + 1):
                eng.step()
            dl = eng.select(eng.camera_at(eng.world.time), full.render.size)
            r.draw(dl, full.render.background)
            out[m] = window(r.read_pixels())

    def psnr(a):
        e = np.mean((a.astype(np.float64) - ref.astype(np.float64)) ** 2)
        return float("inf") if e == 0 else float(10.0 * np.log10(255.0 ** 2 / e))

    n = out.pop("agents in the window")
    return {"crop": [x0, y0, cw, ch], "k": k, "frame": frame, "agents": n,
            "reference_mean": ref.reshape(-1, 3).mean(axis=0).tolist(),
            "rows": [(name, psnr(img), img.reshape(-1, 3).mean(axis=0).tolist()) for name, img in out.items()]}


def run_one(scene_path: str, mode: str, frames: int, warmup: int, agents: int = 0) -> dict:
    """One mode in this process (``agents`` > 0: the scene scaled to that many, :func:`scaled_scene`): load,
    run, read the telemetry back."""
    import csv

    from crowd.engine import Engine
    from crowd.memory import estimate_scene

    scene = _scene(scene_path, mode)
    if agents > 0:
        scene = scaled_scene(scene, agents)
    est = estimate_scene(scene)
    t0 = time.perf_counter()
    with Engine(scene, quiet=True) as eng:
        eng._open_renderer()
        load = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as tmp:
            if warmup:
                eng.run(frames=warmup, out_dir=Path(tmp) / "warm")
            c0 = time.process_time()
            eng.run(frames=frames, out_dir=Path(tmp) / "run")
            cpu = (time.process_time() - c0) / frames
            with open(Path(tmp) / "run" / "frames.csv") as f:
                rows = list(csv.DictReader(f))
    med = {s: statistics.median(float(r[s]) for r in rows) for s in STAGES}
    agents = int(scene_agents(scene))
    pts = statistics.median(float(r["points"]) for r in rows)
    return {"mode": mode, "load_s": load, "frames": len(rows), "median_s": med, "cpu_s": cpu,
            "points": pts, "points_per_agent": pts / max(1, agents),
            "triangles": statistics.median(float(r["triangles"]) for r in rows), "agents": agents,
            "peak_rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, "estimate": est.total}


def selection(scene_path: str, repeats: int = 3) -> dict:
    """Mode auto's selection of one frame of the scene, flat and per-group, interleaved: median wall
    and CPU seconds of each (numba threads as configured), and whether both drew the same."""
    import numpy as np

    from crowd.engine import Engine

    scene = _scene(scene_path, "auto-nofar")  # the far tier off: both paths select every agent
    with Engine(scene, quiet=True) as eng:
        eng.step()
        sel = eng.selector
        cam = eng.camera_at(eng.world.time)
        size = scene.render.size
        times = {True: [], False: []}
        lists = {}
        for f in (True, False):  # compile / warm
            sel.flat = f
            sel.select(eng.world.state, cam, size)
        for _ in range(repeats):
            for f in (True, False):
                sel.flat = f
                t, c = time.perf_counter(), time.process_time()
                lists[f] = sel.select(eng.world.state, cam, size)
                times[f].append((time.perf_counter() - t, time.process_time() - c))
        a, b = lists[True], lists[False]
        same = [(x.rep, x.part, x.level) for x in a.batches] == [(x.rep, x.part, x.level) for x in b.batches] and \
            all(np.array_equal(x.instance_ids, y.instance_ids) for x, y in zip(a.batches, b.batches))
    med = {f: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for f, v in times.items()}
    return {"flat": med[True], "per_group": med[False], "same": bool(same),
            "instances": int(a.stats["instances"]), "plan": a.stats["auto"]["plan"]}


def kernels(n: int = 1_000_000, repeats: int = 3) -> list:
    """Serial against parallel for the per-agent kernels this scene runs, on ``n`` agents of the
    scene's density and a far view: (name, serial median s, parallel median s)."""
    import numba
    import numpy as np

    from lod.full import pack
    from lod.full.reps import build_keyframed_rep
    from lod.points import coarse
    from lod.points import jobs
    from lod.points import mode as pm
    from lod.points.octree import build_hierarchy
    from lod.view import Camera
    from sim.procedural import humanoid

    def med(fn):
        fn()  # compile / warm
        ts = []
        for _ in range(repeats):
            t = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t)
        return statistics.median(ts)

    rng = np.random.default_rng(0)
    out = []
    kf = build_keyframed_rep(pm.keyframed_character(humanoid(5000, 21), 3), key="w")
    h = build_hierarchy(*pm.segment_arrays(kf, 0), seed=0, progress=False)
    coarse.add_coarse(h)
    data = np.zeros((n, 16), np.float32)
    yaw = rng.uniform(-3, 3, n)
    data[:, 0], data[:, 2], data[:, 5], data[:, 8], data[:, 10] = np.cos(yaw), np.sin(yaw), 1, -np.sin(yaw), np.cos(yaw)
    data[:, 3], data[:, 7], data[:, 11] = rng.uniform(-1000, 1000, n), -1000.0, -rng.uniform(1200, 3200, n)
    data[:, 12] = rng.uniform(0, 1, n)
    cam = Camera.look_at((0.0, 0.0, 0.0), (0.0, -1000.0, -2200.0), fov_y=50.0, near=1.0, far=1e4)
    planes = cam.frustum_planes(16 / 9)
    vs = 720 / (2 * np.tan(np.radians(25.0)))
    times = []
    for lim in (10 ** 12, jobs.TRAVERSE_PARALLEL_MIN):
        jobs.TRAVERSE_PARALLEL_MIN = lim
        times.append(med(lambda: jobs.traverse_instances(h, data, planes, vs, 2.0)))
    out.append(("points traversal (lod/points/jobs.py)", *times))
    pos = np.c_[rng.uniform(-1000, 1000, n), np.zeros(n), rng.uniform(-1000, 1000, n)]
    G = 15
    args = (pos, np.array([0.0, 1000.0, 2200.0]), rng.uniform(-3, 3, n), np.ones(n), rng.integers(0, G, n),
            rng.uniform(0, 2, n), rng.uniform(0, 1, n), np.c_[np.zeros((G, 3)), np.ones(G)], np.zeros(G, bool),
            np.zeros(G), np.full(G, 30.0), np.ones(G), np.ones(G, bool), np.full(G, 30.0), planes, True)
    times = []
    for lim in (10 ** 12, pack.PACK_PARALLEL_MIN):
        pack.PACK_PARALLEL_MIN = lim
        times.append(med(lambda: pack.instance_batches(*args)))
    out.append(("instance packing (lod/full/pack.py)", *times))
    out.append(("numba threads", numba.get_num_threads(), numba.get_num_threads()))
    return out


def scene_agents(scene) -> int:
    from crowd.memory import placement_agents

    return sum(placement_agents(p.kind, p.params) for p in scene.placements)


def busiest(n: int = 6) -> list[str]:
    """The n processes using the most CPU (``ps``), as "command (cpu %)"."""
    try:
        out = subprocess.run(["ps", "-eo", "pcpu,comm", "--sort=-pcpu", "--no-headers"], capture_output=True,
                             text=True, timeout=10).stdout.splitlines()
    except (OSError, subprocess.SubprocessError):
        return []
    return [f"{c.split(None, 1)[1]} ({c.split(None, 1)[0]} %)" for c in out[:n] if len(c.split(None, 1)) == 2]


def _child(a, what: str) -> dict:
    cmd = [sys.executable, __file__, "--scene", a.scene, "--frames", str(a.frames), "--warmup", str(a.warmup),
           "--one", what, "--modes", *a.modes]
    p = subprocess.run(cmd, capture_output=True, text=True, env=os.environ | {"PYTHONPATH": str(ROOT)})
    if p.returncode:
        last = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else f"exit code {p.returncode}"
        _fail(f"{what}: the run failed: {last}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "million.toml"))
    ap.add_argument("--modes", nargs="+", default=["points", "auto"])
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--md", default=str(ROOT / "scripts" / "bench_million.md"))
    ap.add_argument("--one", help=argparse.SUPPRESS)  # internal: run one mode (or "selection"), print JSON
    ap.add_argument("--no-kernels", action="store_true", help="skip the serial/parallel kernel comparison")
    ap.add_argument("--no-selection", action="store_true", help="skip the flat/per-group selection comparison")
    ap.add_argument("--no-image", action="store_true", help="skip the image error against the 4 x 4 reference")
    ap.add_argument("--growth", type=int, nargs="*", default=[10_000, 100_000, 300_000, 1_000_000],
                    help="agent counts of the growth table (the scene at the same density, the view scaled with "
                         "sqrt(N)), in the first of --modes; none: skip it")
    a = ap.parse_args(argv)
    if any(n < 1 for n in a.growth):
        _fail(f"--growth: expected agent counts >= 1, got {' '.join(map(str, a.growth))}")
    if a.frames < 1 or a.warmup < 0:
        _fail(f"--frames: expected >= 1 and --warmup >= 0, got {a.frames} and {a.warmup}")
    if not Path(a.scene).is_file():
        _fail(f"--scene: {a.scene}: no such file")
    from lod.modes import MODES

    bad = [m for m in a.modes if not _mode_ok(m, MODES)]
    if bad:
        _fail(f"--modes: unknown mode {bad[0]!r}; accepted: {', '.join(sorted(MODES))}, each optionally with "
              f"-{', -'.join(VARIANTS)}")
    import crowd  # noqa: F401  (the app's OpenMP wait policy, as crowd run has it, for the kernels here too)

    if a.one:
        if a.one == "selection":
            res = selection(a.scene)
        elif a.one == "image":
            res = image_error(a.scene, a.modes)
        elif a.one.startswith("growth:"):
            res = run_one(a.scene, a.modes[0], a.frames, a.warmup, agents=int(a.one.split(":", 1)[1]))
        else:
            res = run_one(a.scene, a.one, a.frames, a.warmup)
        print(json.dumps(res))
        return 0
    load0, others = os.getloadavg(), busiest()
    results = [_child(a, m) for m in a.modes]
    sel = None if a.no_selection else _child(a, "selection")
    img = None if a.no_image else _child(a, "image")
    growth = [_child(a, f"growth:{n}") for n in a.growth]
    kern = [] if a.no_kernels else kernels()
    load1 = os.getloadavg()
    lines = [f"| mode | load s | {' | '.join(s + ' ms' for s in STAGES)} | fps | cpu ms | points/agent | triangles | "
             "peak RSS GB | guard estimate GB |",
             "| --- | ---: | " + " | ".join("---:" for _ in STAGES) + " | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in results:
        med = r["median_s"]
        lines.append(f"| {r['mode']} | {r['load_s']:.1f} | " + " | ".join(f"{1e3 * med[s]:.0f}" for s in STAGES)
                     + f" | {1.0 / med['total']:.2f} | {1e3 * r['cpu_s']:.0f} | {r['points_per_agent']:.2f} | "
                     f"{r['triangles']:,.0f} | {r['peak_rss'] / 1e9:.2f} | {r['estimate'] / 1e9:.2f} |")
    head = (f"Scene {Path(a.scene).name}: {results[0]['agents']:,} agents; medians of {a.frames} frames after "
            f"{a.warmup} warm-up frames; load average {load0[0]:.1f} before, {load1[0]:.1f} after.")
    slines = []
    if sel is not None:
        (fw, fc), (pw, pc) = sel["flat"], sel["per_group"]
        slines = ["| mode auto's selection of one frame | wall ms | cpu ms |", "| --- | ---: | ---: |",
                  f"| flat arrays (lod/auto/flat.py) | {1e3 * fw:.0f} | {1e3 * fc:.0f} |",
                  f"| per group (the reference) | {1e3 * pw:.0f} | {1e3 * pc:.0f} |",
                  f"| per group / flat | {pw / fw:.2f} | {pc / fc:.2f} |", "",
                  f"Same draw list from both: {'yes' if sel['same'] else 'NO'} ({sel['instances']:,} instances, "
                  f"plan {sel['plan']})."]
    klines = ["| kernel (1,000,000 agents, far view) | serial ms | parallel ms | serial / parallel |",
              "| --- | ---: | ---: | ---: |"]
    for name, s, p in kern:
        if name == "numba threads":
            klines.append(f"| numba threads | {s} | {p} | |")
        else:
            klines.append(f"| {name} | {1e3 * s:.0f} | {1e3 * p:.0f} | {s / p:.2f} |")
    ilines = []
    if img is not None:
        x0, y0, cw, ch = img["crop"]
        ilines = [f"Image error of frame {img['frame']} in the window x {x0}..{x0 + cw}, y {y0}..{y0 + ch} (from the "
                  f"top left; {img['agents']:,} agents drawn there at full detail) against full detail with "
                  f"{img['k']} x {img['k']} samples per pixel, box-filtered (crowd/reference.py), whose mean colour "
                  "there is " + ", ".join(f"{v:.1f}" for v in img["reference_mean"]) + ":", "",
                  "| image | PSNR dB | mean colour (R, G, B) |", "| --- | ---: | --- |"]
        for name, db, mean in img["rows"]:
            ilines.append(f"| {name} | {db:.2f} | " + ", ".join(f"{v:.1f}" for v in mean) + " |")
    glines = []
    if growth:
        t0 = growth[0]["median_s"]["total"]
        glines = [f"Growth at constant density (mode {a.modes[0]}, the view scaled with sqrt(N); medians of "
                  f"{a.frames} frames after {a.warmup}):", "",
                  f"| agents | {' | '.join(s + ' ms' for s in STAGES)} | x {growth[0]['agents']:,} |",
                  "| ---: | " + " | ".join("---:" for _ in STAGES) + " | ---: |"]
        for r in growth:
            med = r["median_s"]
            glines.append(f"| {r['agents']:,} | " + " | ".join(f"{1e3 * med[s]:.0f}" for s in STAGES)
                          + f" | {med['total'] / t0:.2f} |")
    print(head)
    print("\n".join(lines))
    if glines:
        print("\n".join(glines))
    if ilines:
        print("\n".join(ilines))
    if slines:
        print("\n".join(slines))
    if kern:
        print("\n".join(klines))
    import platform

    from render.context import create_context, gl_info

    ctx = create_context()
    gl = gl_info(ctx).get("GL_RENDERER", "")
    ctx.release()
    md = ["# A million moving agents (`scripts/bench_million.py`)", "",
          f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} logical CPUs, Python "
          f"{platform.python_version()}, {gl}.", "",
          f"Command: `{' '.join(['.venv/bin/python', 'scripts/bench_million.py'] + (argv or sys.argv[1:]))}`", "",
          head, "", *lines, "", *((glines + [""]) if glines else []), *((ilines + [""]) if ilines else []), *((slines + [""]) if slines else []), *((klines + [""]) if kern else []),
          "Busiest processes at the start (the machine is shared): " + ", ".join(others) + ".", "",
          "Stages are the engine's telemetry (`frames.csv`) per frame: simulate (boids + animation), select (LOD "
          "selection: culling, packing, traversal, auto's pricing), upload + draw + finish (the renderer). "
          "`cpu ms` is the process's CPU time per measured frame, every thread counted. "
          "`load s` is the time from the scene file to the first frame with the LOD cache warm. "
          "Peak RSS is the benchmark process's own (one process per mode)."]
    from sim.atomic_io import atomic_open

    with atomic_open(a.md, "w") as f:
        f.write("\n".join(md) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
