"""HUD cost per frame of ``crowd fly`` (target: at most 1 ms).

Runs the fly-through's own frame (``crowd.fly.FlyApp.frame``: simulate,
select, draw, blit) in a glfw window and, on alternate frames, draws the HUD
on top. Both kinds of frame are measured the same way, from a ``ctx.finish()``
after the blit to a ``ctx.finish()`` after the (possibly absent) HUD, so the
GPU work of the HUD is inside the clock; the HUD cost is the difference of the
two medians (means printed too). Frames alternate, so drift of the machine load
hits both sides. Two modes are measured: as ``crowd fly`` draws it (the text
is rebuilt every ``HUD_REFRESH`` seconds of the frame clock or after input, the
quad is drawn every frame) and the worst case of text rebuilt every frame.

Without a display, an Xvfb server is started for the run (Debian package
``xvfb``). Usage::

    python scripts/bench_hud.py [--scene FILE] [--size WxH] [--frames N] [--help-text]

Defaults: a small built-in scene (16 humanoids), 1280x720, 120 frames.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SCENE = """\
name = "bench_hud"
seed = 1
dt = 0.0333333
frames = 10
effects = ["animation"]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 2000

[[placement]]
kind = "grid"
character = "walker"
rows = 4
cols = 4
spacing = [1.5, 1.5]

[camera]
position = [2.0, 2.5, 9.0]
target = [2.0, 0.8, 2.0]
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", help="scene file (default: a built-in 16-agent scene)")
    ap.add_argument("--size", default="1280x720", help="window size WxH (default 1280x720)")
    ap.add_argument("--frames", type=int, default=120, help="frames measured, half with HUD (default 120)")
    ap.add_argument("--help-text", action="store_true", help="show the help block too (a longer HUD)")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))

    from render.window import VirtualDisplay, display_available

    vd = None
    if not display_available():
        vd = VirtualDisplay(screen=f"{max(w, 640)}x{max(h, 480)}x24").start()
        os.environ["DISPLAY"] = vd.display
    try:
        return _run(args, (w, h), vd is not None)
    finally:
        if vd is not None:
            vd.stop()


def _run(args, size, xvfb: bool) -> int:
    from crowd.engine import Engine
    from crowd.fly import HUD_REFRESH, FlyApp
    from crowd.scene import load_scene
    from render.window import Window

    with tempfile.TemporaryDirectory() as tmp:
        scene_path = Path(args.scene) if args.scene else Path(tmp) / "bench_hud.toml"
        if not args.scene:
            scene_path.write_text(SCENE)
        scene = load_scene(scene_path).with_overrides(size=size)
        window = Window(size, title="bench_hud")
        app = None
        try:
            engine = Engine(scene, quiet=True)
            app = FlyApp(engine, window, Path(tmp) / "out", echo=lambda s: None)
            c = app.controller
            c.help_visible = bool(args.help_text)
            ctx = window.ctx
            modes = {"app": ([], [], [], []), "every": ([], [], [], [])}
            extent = (0, 0)
            for mode, (on, off, frame_on, frame_off) in modes.items():
                for i in range(args.frames + 4):
                    with_hud = i % 2 == 0
                    c.hud_visible = False  # the HUD is drawn below, inside the clock
                    t0 = time.perf_counter()
                    app.frame(1 / 30)
                    ctx.finish()
                    t1 = time.perf_counter()
                    if with_hud:
                        extent = app.draw_hud(app.size, refresh=mode == "every")
                    ctx.finish()
                    t2 = time.perf_counter()
                    window.swap()
                    window.poll()
                    if i < 4:  # warm-up: shader compilation, first uploads
                        continue
                    (on if with_hud else off).append(t2 - t1)
                    (frame_on if with_hud else frame_off).append(t2 - t0)
        finally:
            if app is not None:
                app.close()
            window.close()

    med, mean = statistics.median, statistics.fmean
    print(f"bench_hud: {scene.name}, {size[0]}x{size[1]}, {args.frames} frames per mode, half with HUD "
          f"({'Xvfb' if xvfb else os.environ.get('DISPLAY')}), HUD of {extent[0]}x{extent[1]} pixels"
          f"{' incl. help' if args.help_text else ''}")
    for mode, title in (("app", f"as in crowd fly (text rebuilt every {HUD_REFRESH:g} s or on input)"),
                        ("every", "text rebuilt every frame (worst case)")):
        on, off, frame_on, frame_off = modes[mode]
        cost = med(on) - med(off)
        print(f"  {title}:")
        print(f"    HUD stage median: with {med(on) * 1e3:.3f} ms, without {med(off) * 1e3:.3f} ms -> HUD cost "
              f"{cost * 1e3:.3f} ms per frame (mean {(mean(on) - mean(off)) * 1e3:.3f} ms; target <= 1 ms: "
              f"{'met' if cost <= 1e-3 else 'MISSED'})")
        print(f"    whole frame median: with HUD {med(frame_on) * 1e3:.2f} ms, without {med(frame_off) * 1e3:.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
