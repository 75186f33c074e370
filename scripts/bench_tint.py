"""Cost of the per-agent colour variation (render/tint.py, shaders/core/tint.glsl) per frame.

The renderer always uploads the colour words (8 bytes per instance) and every
vertex shader (and the splat's colour pass) calls ``tint_color``; with the
variation off every word is 0 and the HSV conversion is skipped. This script
draws the same selection of one frame of a scene with the variation on (the
scene's, a generated humanoid's default) and off (``Renderer.tint_table =
None``), alternating, and prints the median draw time (``Renderer.draw``:
upload + submission + ``ctx.finish``) of each side per LOD mode and their
ratio. Alternating draws make drift of the machine load hit both sides.

Usage::

    python scripts/bench_tint.py [--scene scenes/quickstart.toml] [--size 1280x720] [--draws 15]
                                 [--modes none,triangles,points,clusters,auto]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _size(text: str) -> tuple:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size: expected WxH, got {text!r}") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise argparse.ArgumentTypeError(f"--size: each side 16 ..= 8192, got {text!r}")
    return (w, h)


def main(argv=None) -> int:
    from crowd.scene import LOD_MODES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(Path(__file__).resolve().parents[1] / "scenes" / "quickstart.toml"))
    ap.add_argument("--size", type=_size, default=(1280, 720), help="WxH (default 1280x720)")
    ap.add_argument("--draws", type=int, default=15, help="draws per side and mode (default 15), >= 3")
    ap.add_argument("--modes", default=",".join(LOD_MODES), help="comma-separated LOD modes")
    a = ap.parse_args(argv)
    modes = [m for m in a.modes.split(",") if m]
    bad = [m for m in modes if m not in LOD_MODES]
    if bad or not modes or a.draws < 3:
        print(f"bench_tint: --modes: expected some of {', '.join(LOD_MODES)}, got {a.modes!r}; --draws >= 3",
              file=sys.stderr)
        return 2
    from crowd.engine import Engine
    from crowd.errors import SceneError
    from crowd.scene import load_scene

    try:
        scene = load_scene(a.scene)
    except (SceneError, OSError) as e:
        print(f"bench_tint: {e}", file=sys.stderr)
        return 2
    print(f"scene {scene.name}, {a.size[0]}x{a.size[1]}, {a.draws} draws per side, frame 0 of the camera path")
    print("| mode | off: draw ms (median) | on: draw ms (median) | on / off |")
    print("| --- | --- | --- | --- |")
    with Engine(scene, overrides={"size": a.size}, quiet=True) as e:
        r = e._open_renderer()
        table = e.tint_table
        cam = e.camera_at(0.0)
        for m in modes:
            e.set_lod_mode(m)
            dl = e.select(cam, a.size)
            times = {"off": [], "on": []}
            for k in range(2 * a.draws + 2):
                side = ("off", "on")[k % 2]
                r.tint_table = table if side == "on" else None
                t0 = time.perf_counter()
                r.draw(dl)
                r.ctx.finish()
                if k >= 2:  # the first pair warms caches and compiles programs
                    times[side].append(time.perf_counter() - t0)
            off, on = (1000.0 * statistics.median(times[s]) for s in ("off", "on"))
            print(f"| {m} | {off:.1f} | {on:.1f} | {on / off:.3f} |")
        r.tint_table = table
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
