"""Regenerate the README's pictures of the world: a frame of exhibition and one of office (docs/*.png).

    python scripts/world_pictures.py [--size 640x360] [--frames 60] [--lod none] [--out docs]

Each scene is simulated for ``--frames`` frames (no drawing), then one frame is drawn headless from the
scene's camera at that time, with its props, obstacle solids and ground, and written atomically as
``<out>/<scene>.png``. LOD mode ``none`` (default) draws every triangle (83 M for exhibition: about a
minute on llvmpipe); ``--lod triangles`` is faster once its chains are cached.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SCENES = ("exhibition", "office")


def picture(name: str, size, frames: int, lod: str, out: Path) -> Path:
    import dataclasses

    from crowd.engine import Engine
    from crowd.scene import load_scene
    from crowd.images import write_png

    scene = load_scene(ROOT / "scenes" / f"{name}.toml").with_overrides(size=size)
    if lod != scene.lod_mode:
        scene = dataclasses.replace(scene, lod_mode=lod, lod_params=())
    with Engine(scene, quiet=True) as e:
        for _ in range(frames):
            e.step()
        r = e.open_renderer()
        cam = e.camera_at(e.world.time)
        dl = e.select(cam, size)
        r.draw(dl, scene.render.background)
        return write_png(out / f"{name}.png", r.read_pixels())


def main(argv=None) -> int:
    from crowd.scene import parse_size

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=60, help="frames simulated before the picture")
    ap.add_argument("--lod", default="none", help="LOD mode of the pictures")
    ap.add_argument("--out", default=str(ROOT / "docs"))
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    if size is None:
        ap.error(f"--size: expected WxH, got {args.size!r}")
    from crowd.scene import LOD_MODES

    if args.frames < 0:
        ap.error(f"--frames: expected >= 0, got {args.frames}")
    if args.lod not in LOD_MODES:
        ap.error(f"--lod: expected one of {', '.join(LOD_MODES)}, got {args.lod!r}")
    missing = [n for n in args.scenes if not (ROOT / "scenes" / f"{n}.toml").is_file()]
    if missing:
        ap.error(f"no scene {missing[0]!r} in {ROOT / 'scenes'}")
    from crowd.errors import user_errors

    for name in args.scenes:
        t = time.perf_counter()
        try:
            p = picture(name, size, max(0, args.frames), args.lod, Path(args.out))
        except user_errors() as e:  # a scene the code refuses (a replay without its data): one sentence, exit 2
            print(f"world_pictures.py: {str(e).splitlines()[0]}", file=sys.stderr)
            return 2
        print(f"{p}: {size[0]}x{size[1]}, {time.perf_counter() - t:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
