"""Benchmark: what the world around the crowd costs (issue 22): ground + props + blob shadows, and the shadow map.

On one scene (default ``scenes/exhibition.toml``) at 1280x720 in LOD mode ``auto``, in ONE process on the same
simulated frames and cameras, three cases are drawn every measured frame, each by its own engine and renderer
built from the scene with ``[render]`` / ``[[props]]`` overrides:

- ``bare``:  ``[render] shadows = "none"``, ``ground = false`` and no ``[[props]]`` (when the build knows those keys);
- ``world``: ``shadows = "blob"``, ``ground = true``, the scene's props (the default look);
- ``map``:   ``shadows = "map"``, ``ground = true``, the scene's props.

The simulation runs once (the ``world`` engine's, with its props as obstacles) and every case selects and draws
that same state with its own selector and its own world (``engine.scenery.add``: ground, obstacle solids, props,
as ``crowd run`` adds them) (no ``observe`` feedback, so ``auto`` chooses the same representations in
every case); the cases run in a new seeded random order each frame (a case drawn right after a heavy one runs
slower on llvmpipe). Frame time = select + upload + draw + ``ctx.finish``, as ``crowd report`` counts it. The
summary gives world / bare and map / bare as the ratio of the medians and, "paired", as the median over frames of
the per-frame ratio (steadier). Target (issue 22): world / bare <= 1.10.

Keys the scene schema does not have yet (``ground``, ``[[props]]`` before the ``world`` branch is merged) are left
out and named in the output, so the script runs on either side of that merge.

Run:  .venv/bin/python scripts/bench_world.py [--scene scenes/exhibition.toml] [--frames 12] [--warmup 2]
      [--stride 10] [--size 1280 720] [--mode auto] [--md scripts/bench_world.md]
"""
from __future__ import annotations

import argparse
import copy
import os
import platform
import statistics
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from crowd.engine import Engine  # noqa: E402
from crowd.errors import CrowdError  # noqa: E402
from crowd.scene import RENDER_SCHEMA, TOP_LEVEL_KEYS, parse_scene  # noqa: E402

CASES = ("bare", "world", "map")
TARGET = 1.10


def case_doc(doc: dict, case: str, mode: str, size) -> tuple:
    """The scene document of ``case`` and the list of overrides that this build could not apply."""
    d = copy.deepcopy(doc)
    r = d.setdefault("render", {})
    r["size"] = list(size)
    r["shadows"] = {"bare": "none", "world": "blob", "map": "map"}[case]
    d.setdefault("lod", {})["mode"] = mode
    skipped = []
    if "ground" in RENDER_SCHEMA:
        r["ground"] = case != "bare"
    else:
        skipped.append("[render] ground (not in this build)")
    if "props" in TOP_LEVEL_KEYS:
        if case == "bare":
            d.pop("props", None)
    else:
        skipped.append("[[props]] (not in this build)")
    return d, skipped


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "exhibition.toml"))
    ap.add_argument("--frames", type=int, default=12, help="measured frames")
    ap.add_argument("--warmup", type=int, default=2, help="frames drawn first and not counted")
    ap.add_argument("--stride", type=int, default=10, help="simulation steps between measured frames (>= 1)")
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--mode", default="auto", help="LOD mode of every case")
    ap.add_argument("--md", default=str(ROOT / "scripts" / "bench_world.md"), help="markdown of this run ('' = none)")
    args = ap.parse_args(argv)
    if args.frames < 1 or args.warmup < 0 or args.stride < 1:
        print("bench_world: --frames >= 1, --warmup >= 0 and --stride >= 1 expected", file=sys.stderr)
        return 2
    path = Path(args.scene)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as e:
        print(f"bench_world: {path}: cannot read the scene ({e})", file=sys.stderr)
        return 2
    size = tuple(args.size)
    engines, skipped = {}, []
    try:
        for case in CASES:
            d, sk = case_doc(doc, case, args.mode, size)
            skipped = sk
            t0 = time.perf_counter()
            engines[case] = Engine(parse_scene(d, path), quiet=True)
            engines[case]._open_renderer()
            print(f"  {case}: built in {time.perf_counter() - t0:.1f} s", flush=True)
    except CrowdError as e:
        print(f"bench_world: {e}", file=sys.stderr)
        return 2
    sim = engines["world"]
    statics = {c: [(s.key, np.eye(4)) for s in e.statics] for c, e in engines.items()}
    times = {c: [] for c in CASES}
    counts = {c: [] for c in CASES}
    rng = np.random.default_rng(22)
    for k in range(args.warmup + args.frames):
        for _ in range(args.stride):
            sim.step()
        cam = sim.camera_at(sim.world.time)
        for i in rng.permutation(len(CASES)):
            case = CASES[i]
            eng = engines[case]
            a = time.perf_counter()
            dl = eng.selector.select(sim.world.state, cam, size, statics=statics[case])
            if hasattr(eng, "scenery"):  # the world: ground, obstacle solids, props (crowd.world), as a run adds it
                eng.scenery.add(dl, cam, size, eng.settings.poe, eng.settings.lod_mode)
            s = time.perf_counter() - a
            t = eng.renderer.draw(dl, eng.scene.render.background)
            if k >= args.warmup:
                times[case].append(s + sum(float(t.get(x) or 0.0) for x in ("upload", "draw", "finish")))
                counts[case].append((dl.stats.get("triangles", dl.triangles), dl.stats.get("points", dl.points),
                                     dict(eng.renderer.lighting.last_counts), int(dl.stats.get("props", 0)),
                                     int(dl.stats.get("props_instances", 0)),
                                     any(b.rep == "world:ground" for b in dl.batches)))
    from render.context import gl_info

    gl = gl_info(sim.renderer.ctx)
    for e in engines.values():
        e.close()
    med = {c: statistics.median(times[c]) for c in CASES}
    paired = {c: statistics.median(np.asarray(times[c]) / np.asarray(times["bare"])) for c in CASES}
    lines = [f"scene {path.name}, {size[0]}x{size[1]}, lod mode {args.mode}, {args.frames} measured frames "
             f"(+{args.warmup} warm-up), every {args.stride} simulation steps",
             "", "| case | median ms | p90 ms | ratio of medians | paired ratio (median) | triangles | points | ground |"
             " props (instances) | blobs | map casters |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | :---: | ---: | ---: | ---: |"]
    for c in CASES:
        tri, pts, lc, ptri, pinst, ground = counts[c][-1]
        lines.append(f"| {c} | {1e3 * med[c]:.1f} | {1e3 * float(np.percentile(times[c], 90)):.1f} | "
                     f"{med[c] / med['bare']:.3f} | {paired[c]:.3f} | {tri:,} | {pts:,} | {'yes' if ground else 'no'} | "
                     f"{ptri:,} ({pinst}) | {lc['blobs']} | {lc['casters']} |")
    verdict = "meets" if med["world"] / med["bare"] <= TARGET else "misses"
    lines += ["", f"world / bare = {med['world'] / med['bare']:.3f} (paired {paired['world']:.3f}): {verdict} the "
              f"target <= {TARGET:.2f}; map / bare = {med['map'] / med['bare']:.3f} (paired {paired['map']:.3f})"]
    if skipped:
        lines.append("not toggled in this build: " + "; ".join(skipped))
    print("\n".join(lines))
    if args.md:
        from sim.atomic_io import write_atomic

        cmd = "python scripts/bench_world.py " + " ".join(argv if argv is not None else sys.argv[1:])
        head = ["# bench_world: ground + props + shadows against none (issue 22)", "",
                f"Machine: {platform.processor() or platform.machine()}, {gl.get('GL_RENDERER', gl)}; "
                f"command: `{cmd.strip()}`; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.", "",
                "Frame time = select + upload + draw + finish of the same simulated frame and camera for each case "
                "(one process, cases in a seeded random order per frame). Load average at the end of the run: "
                f"{os.getloadavg()[0]:.1f} (other jobs on the same cores move single medians; the paired ratio "
                "is the steadier figure).", ""]
        write_atomic(args.md, "\n".join(head + lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
