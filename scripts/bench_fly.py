"""Benchmark: the fly-through as a person gets it (issue 49): every shipped scene flown with ``crowd fly``'s defaults.

For each scene (default: every ``scenes/*.toml`` but ``million``, which has its own benchmark) a window is opened on
an Xvfb display at ``--size`` and :class:`crowd.fly.FlyApp` runs ``--frames`` frames with the given budget
(default :data:`crowd.fly_budget.DEFAULT_BUDGET_MS`, as ``crowd fly`` has it), the camera where the scene starts
it, the simulation running. Printed per scene: the median frame rate over frames ``--from`` .. ``--frames`` (wall
clock from one frame's start to the next, blit, HUD and swap included: what the person sees), the median and the
slowest frame of that span, the mode drawn at the end (``auto*``: auto in place of the scene's mode, which missed
the budget), auto's error bound, and the PSNR of the last frame against the true reference of the same state and
view (full detail with 4 x 4 samples per pixel, box-filtered: ``crowd.reference``; at the scene's pose rate) and
against aliased full detail (mode ``none``, one sample per pixel).

Run:  .venv/bin/python scripts/bench_fly.py [--scenes exhibition stadium] [--frames 110] [--from 10]
      [--size 1280 720] [--budget MS] [--md scripts/bench_fly.md]
Needs Xvfb (Debian package xvfb). Take the figures with nothing else running.
"""
from __future__ import annotations

import argparse
import gc
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from crowd.fly_budget import DEFAULT_BUDGET_MS, parse_budget  # noqa: E402

#: scenes flown only when named (a million agents: scripts/bench_million.py)
NAMED_ONLY = ("million",)
#: frames per second the issue asks of every shipped scene's fly-through
TARGET_FPS = 10.0
#: the fly-through's stages (crowd.fly.FlyFrame.stages) whose medians are printed, in frame order
STAGES = ("simulate", "select", "upload", "draw", "finish", "observe", "blit", "hud")


def fly_scene(path: Path, frames: int, start: int, size: tuple, budget: float, log: Path | None = None) -> dict:
    """Fly ``path`` for ``frames`` frames; its figures (module docstring). ``log``: a JSON-lines file of every
    frame (its stages in ms, the drawn counts, auto's plan, state and predicted ms), written atomically."""
    from crowd.engine import Engine
    from crowd.fly import FlyApp
    from crowd.image_metrics import psnr
    from crowd.scene import load_scene
    from render.window import Window

    scene = load_scene(path).with_overrides(size=size)
    window = Window(scene.render.size, title=f"bench_fly {scene.name}")
    app = None
    gc_s = [0.0, None]  # the garbage collector's seconds this frame, the start of a collection running

    def collected(phase, info):
        if phase == "start":
            gc_s[1] = time.perf_counter()
        elif gc_s[1] is not None:
            gc_s[0] += time.perf_counter() - gc_s[1]
            gc_s[1] = None

    gc.callbacks.append(collected)
    try:
        engine = Engine(scene, quiet=True)
        app = FlyApp(engine, window, Path("/tmp") / "bench_fly", echo=lambda _: None, budget_ms=budget)
        ratios = []  # frames of mode auto: its predicted rendering time over the measured one
        stages = []  # per measured frame: its stages' seconds (FlyFrame.stages)
        real = app.frame

        def frame(dt):
            gc_s[0] = 0.0
            out = real(dt)
            a = out.drawlist.stats.get("auto")
            render = sum(out.stages.get(k, 0.0) for k in ("upload", "draw", "finish"))
            if app.frames > start and isinstance(a, dict) and a.get("predicted_ms") and render > 0:
                ratios.append(float(a["predicted_ms"]) / (1e3 * render))
            if app.frames > start:
                stages.append(dict(out.stages))
            if log is not None:
                counts = {k: v for k, v in out.drawlist.stats.items() if isinstance(v, (int, float))}
                rows.append({"frame": app.frames - 1, "mode": engine.settings.lod_mode,
                             "stages_ms": {k: round(1e3 * v, 2) for k, v in out.stages.items()}, "counts": counts,
                             "gc_ms": round(1e3 * gc_s[0], 2),
                             "auto": {k: a.get(k) for k in ("plan", "state", "incumbent", "fade_from", "predicted_ms", "plans_ms", "bound",
                                                         "refused_bound", "unmeetable")}
                             if isinstance(a, dict) else None})
            return out

        app.frame = frame
        rows: list = []
        t0 = time.perf_counter()
        app.run(max_frames=frames)
        wall = time.perf_counter() - t0
        if log is not None:
            import json

            from sim.atomic_io import write_atomic

            for row, period in zip(rows, app.periods):
                row["period_ms"] = round(1e3 * period, 2)
            write_atomic(log, "".join(json.dumps(r) + "\n" for r in rows))
        # app.periods[i]: frame i's wall clock, its start to the next frame's start
        periods = np.asarray(app.periods[start:], np.float64)
        sel = app.budget.auto()
        mode = engine.settings.lod_mode + ("*" if app.budget.switched else "")
        bound = float(sel.bound) if sel is not None else float("nan")
        drawn = app.renderer.read_pixels().astype(np.float64) / 255.0
        # full detail of the same state and view: mode none selected and drawn without a step
        camera, _ = engine.terrain_frame(app.controller.camera(), app.renderer)
        engine.set_lod_mode("none")
        dl = engine.select(camera, app.renderer.size)
        from lod.debug_colors import apply_tints

        apply_tints(dl, engine.settings.color_by, statics=engine.static_keys)
        app.renderer.draw(dl, scene.render.background)
        full = app.renderer.read_pixels().astype(np.float64) / 255.0
        from crowd.reference import DEFAULT_K, TileRenderer

        with TileRenderer(app.renderer.size, DEFAULT_K, ctx=app.renderer.ctx,
                          reps=[*engine.reps, *engine.statics, *engine.scenery.reps]) as tiles:
            engine._lit(tiles.renderer).tint_table = engine.tint_table
            big = engine.select(camera, tiles.big)
            apply_tints(big, engine.settings.color_by, statics=engine.static_keys)
            true = tiles.draw(big, scene.render.background).astype(np.float64) / 255.0
        med = float(np.median(periods)) if periods.size else float("nan")
        # the slowest frame (periods[i] is frame start + i's) and its stages
        slow = start + int(np.argmax(periods)) if periods.size else -1
        slow_st = stages[slow - start] if 0 <= slow - start < len(stages) else {}
        return {"scene": path.stem, "scene_mode": app.budget.scene_mode, "fps": 1.0 / med, "median_ms": 1e3 * med,
                "max_ms": 1e3 * float(periods.max()) if periods.size else float("nan"), "mode": mode, "bound": bound,
                "psnr": psnr(drawn, true), "psnr_aliased": psnr(drawn, full), "full_psnr": psnr(full, true),
                "wall_s": wall, "frames": frames, "slowest": (slow, {k: 1e3 * float(v) for k, v in slow_st.items()
                                                                    if k in STAGES}),
                "stages": {k: 1e3 * float(np.median([st.get(k, 0.0) for st in stages])) for k in STAGES} if stages
                else {k: float("nan") for k in STAGES},
                "pred": float(np.median(ratios)) if ratios else float("nan"),
                "pred25": float(np.mean(np.abs(np.asarray(ratios) - 1.0) <= 0.25)) if ratios else float("nan")}
    finally:
        gc.callbacks.remove(collected)
        if app is not None:
            app.close()
        window.close()


def _budget(text: str) -> float:
    try:
        return parse_budget(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="*", default=None, help="scene names (default: every scenes/*.toml but million)")
    ap.add_argument("--frames", type=int, default=110)
    ap.add_argument("--from", dest="start", type=int, default=10, help="first frame of the measured span")
    ap.add_argument("--size", type=int, nargs=2, default=(1280, 720))
    ap.add_argument("--budget", type=_budget, default=DEFAULT_BUDGET_MS, help="ms (crowd fly --budget); 0: off")
    ap.add_argument("--md", default=None, help="also write the table to this markdown file")
    ap.add_argument("--log", default=None, metavar="DIR",
                    help="write every frame of each scene (stages, counts, auto's plan) to DIR/<scene>.jsonl")
    a = ap.parse_args(argv)
    if not 1 <= a.start < a.frames:
        ap.error("--from must be at least 1 and below --frames")
    if a.log is not None:
        try:
            Path(a.log).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            ap.error(f"--log: cannot make folder {a.log}: {e.strerror or e}")
    from crowd.scene import SIZE_RANGE

    if not all(SIZE_RANGE[0] <= v <= SIZE_RANGE[1] for v in a.size):
        ap.error(f"--size: expected two integers in {SIZE_RANGE[0]} ..= {SIZE_RANGE[1]}, got {a.size[0]} {a.size[1]}")
    from crowd.scene import shipped_scenes

    scenes = shipped_scenes(ROOT / "scenes")  # those whose data are here
    if a.scenes:
        unknown = sorted(set(a.scenes) - {s.stem for s in scenes})
        if unknown:
            ap.error(f"--scenes: no scenes/{unknown[0]}.toml")
        scenes = [s for s in scenes if s.stem in a.scenes]
    else:
        scenes = [s for s in scenes if s.stem not in NAMED_ONLY]
    from crowd.errors import user_errors
    from render.window import VirtualDisplay, WindowError

    display = None
    if not os.environ.get("DISPLAY"):
        display = VirtualDisplay().start()
        os.environ["DISPLAY"] = display.display
    head = (f"| scene | scene's mode | fps (median, frames {a.start}-{a.frames}) | median ms | slowest ms | mode drawn "
            f"| bound px | PSNR vs reference dB: drawn / full detail (aliased) | PSNR vs aliased dB "
            f"| auto: predicted / measured (median) | within 25 % |")
    rows = [head, "| --- | --- | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: |"]
    print(head)
    results = []
    try:
        for s in scenes:
            try:
                r = fly_scene(s, a.frames, a.start, tuple(a.size), a.budget,
                              None if a.log is None else Path(a.log) / f"{s.stem}.jsonl")
            except (*user_errors(), WindowError) as e:  # a scene or asset the code cannot handle: one sentence, exit 2
                print(f"bench_fly: {s.name}: {str(e).splitlines()[0]}", file=sys.stderr)
                return 2
            results.append(r)
            row = (f"| {r['scene']} | {r['scene_mode']} | {r['fps']:.1f} | {r['median_ms']:.0f} | {r['max_ms']:.0f} | "
                   f"{r['mode']} | {r['bound']:.3g} | {r['psnr']:.1f} / {r['full_psnr']:.1f} | {r['psnr_aliased']:.1f} | "
                   f"{r['pred']:.2f} | {100 * r['pred25']:.0f} % |")
            rows.append(row)
            f, st = r["slowest"]
            top = ", ".join(f"{k} {v:.0f}" for k, v in sorted(st.items(), key=lambda kv: -kv[1])[:3])
            print(row + f"  ({r['wall_s']:.0f} s; slowest: frame {f}{': ' + top + ' ms' if top else ''})", flush=True)
    finally:
        if display is not None:
            display.stop()
    met = sum(r["fps"] >= TARGET_FPS for r in results)
    over = [r["scene"] for r in results if r["max_ms"] > 2.0 * a.budget + 1e-9] if a.budget > 0 else []
    summary = (f"{met} of {len(results)} scenes at >= {TARGET_FPS:g} fps; slowest frame over 2x the budget "
               f"({2 * a.budget:g} ms) on: {', '.join(over) or 'none'}")
    print(summary)
    stage_rows = ["| scene | " + " | ".join(f"{k} ms" for k in STAGES) + " |",
                  "| --- |" + " ---: |" * len(STAGES)]
    stage_rows += [f"| {r['scene']} | " + " | ".join(f"{r['stages'][k]:.1f}" for k in STAGES) + " |" for r in results]
    print("\n".join(["", f"median of each stage over frames {a.start}-{a.frames}:", *stage_rows]))
    if a.md:
        from sim.atomic_io import write_atomic

        load = os.getloadavg()
        text = (f"# bench_fly: the fly-through with crowd fly's defaults\n\n"
                f"`{' '.join(['scripts/bench_fly.py', *(argv if argv is not None else sys.argv[1:])])}`, "
                f"{time.strftime('%Y-%m-%d')}, {platform.node()} ({os.cpu_count()} cores, Mesa llvmpipe under "
                f"Xvfb), {a.size[0]}x{a.size[1]}, budget {a.budget:g} ms, load before the run "
                f"{load[0]:.1f}.\n\n" + "\n".join(rows) + f"\n\n{summary}\n\n"
                f"Median of each stage over frames {a.start}-{a.frames} (crowd.fly.FlyFrame.stages; upload, draw and "
                "finish are the renderer's):\n\n" + "\n".join(stage_rows) + "\n\n"
                "`auto*`: mode auto drawn in place of the scene's mode, which missed the budget. Frame time is the "
                "wall clock from one frame's start to the next (simulation, selection, rendering, blit, HUD, swap); "
                "the budget covers selection and rendering only. The last two columns: over the measured frames drawn by "
                "mode auto, the median of its predicted rendering time over the measured one, and the share of "
                "frames where the two agree within 25 %.\n")
        write_atomic(Path(a.md), text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
