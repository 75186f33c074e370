"""Benchmark: poses that follow the clip (issue 20) — a long varied clip seen close up in mode points.

One generated humanoid with two clips: its 1.1 s walk and a 30 s varied clip
(``sim.procedural.varied_clip``: its walk and run, time-warped section by
section). Mode points is built for each setting: the default (per clip the
fewest poses within ``pose_error``, ``lod.points.poses``) and the earlier fixed
9 poses per clip (with ``--max-keyframes``: the default with that cap only). One agent is drawn close up (camera 3 m away at chest
height, 640x360) at a dozen times spread over each clip, by mode none (full
detail, the reference) and by mode points; the table gives per setting and
clip the poses baked, the pose error (largest vertex distance between the
interpolated poses and the skinned mesh, sampled at 30 Hz, % of the
character's height), the build time, and the median PSNR of points against
full detail. Issue 20's acceptance: with the default, the 30 s clip's median
PSNR within 2 dB of the 1.1 s clip's.

Run:  .venv/bin/python scripts/bench_poses.py [--triangles 3000] [--duration 30] [--frames 12]
      [--size 640 360] [--pose-error 0.02] [--max-keyframes 256]
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    from crowd.image_metrics import psnr
    from lod.full.mode import NoLodSelector
    from lod.full.reps import build_rep
    from lod.points import mode as pm
    from lod.points.poses import character_extent
    from lod.points.rep import HierarchyCache
    from lod.view import Camera
    from render.context import create_context
    from render.renderer import Renderer
    from sim.procedural import humanoid, varied_clip
    from sim.state import CrowdState

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=3000)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--size", type=int, nargs=2, default=(640, 360))
    ap.add_argument("--pose-error", type=float, default=None, help="default: the mode's (lod.points.config)")
    ap.add_argument("--max-keyframes", type=int, default=None, help="default: the mode's cap per clip")
    a = ap.parse_args(argv)
    if not 500 <= a.triangles <= 200_000:
        ap.error(f"--triangles: expected 500 ..= 200000, got {a.triangles}")
    if not (a.duration > 0.0 and a.frames >= 1 and min(a.size) >= 16):
        ap.error("--duration must be > 0 s, --frames >= 1 and --size at least 16 x 16")
    if a.pose_error is not None and not 1e-4 <= a.pose_error <= 1.0:
        ap.error(f"--pose-error: expected 1e-4 ..= 1 (a fraction of the character's size), got {a.pose_error}")
    if a.max_keyframes is not None and not 2 <= a.max_keyframes <= 4096:
        ap.error(f"--max-keyframes: expected 2 ..= 4096, got {a.max_keyframes}")

    base = humanoid(a.triangles, seed=4)
    ch = dataclasses.replace(base, clips={"walk": base.clip("walk"),
                                          "varied": varied_clip(base, a.duration, seed=7, name="varied")})
    height = character_extent(ch)
    full = build_rep(ch)
    cam = Camera.look_at((0.0, 1.2, 3.0), (0.0, 1.0, 0.0), fov_y=50.0, near=0.05, far=50.0)
    rng = np.random.default_rng(3)
    settings = [("default", {}), ("9 poses", {"keyframes": 9})]
    if a.pose_error is not None:
        settings[0] = (f"pose_error {a.pose_error:g}", {"pose_error": a.pose_error})
    if a.max_keyframes is not None:
        settings[0] = (settings[0][0] + f", cap {a.max_keyframes}", {**settings[0][1], "max_keyframes": a.max_keyframes})
        settings = settings[:1]
    ctx = create_context()
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-poses-") as d:
        for label, params in settings:
            t0 = time.perf_counter()
            reps, sel = pm.build([ch], ["h"], [30], {**params}, cache=HierarchyCache(Path(d) / label),
                                 progress=False)
            build_s = time.perf_counter() - t0
            r = Renderer(tuple(a.size), ctx=ctx)
            try:
                r.upload(full)
                r.upload(reps[0])
                ref_sel = NoLodSelector([full])
                for ci, name in enumerate(ch.clips):
                    dur = float(ch.clip(name).duration)
                    times = np.sort(rng.uniform(0.0, dur, a.frames))
                    vals = []
                    for t in times:
                        st = CrowdState.empty(1)
                        st.clip[:] = ci
                        st.anim_time[:] = t
                        r.draw(ref_sel.select(st, cam, r.size))
                        ref = r.read_pixels()
                        r.draw(sel.select(st, cam, r.size))
                        vals.append(psnr(r.read_pixels(), ref))
                    cp = reps[0].poses[name]
                    rows.append((label, name, dur, len(cp.times), 100 * cp.error / height, build_s,
                                 reps[0].nbytes / 1e6, float(np.median(vals))))
                    print(f"{label:16s} {name:7s} {dur:5.1f} s {len(cp.times):4d} poses  pose error "
                          f"{100 * cp.error / height:5.2f} %  median PSNR {np.median(vals):5.1f} dB", flush=True)
            finally:
                r.release()
    ctx.release()
    print()
    print(f"humanoid {a.triangles} triangles, height {height:.2f} m; close up (3 m), {a.size[0]}x{a.size[1]}, "
          f"{a.frames} times per clip")
    print("| setting | clip | clip s | poses | pose error % height | build s (both clips) | MB | median PSNR dB |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for row in rows:
        print("| {} | {} | {:.1f} | {} | {:.2f} | {:.1f} | {:.1f} | {:.1f} |".format(*row))
    for label in dict.fromkeys(r[0] for r in rows):
        p = {r[1]: r[7] for r in rows if r[0] == label}
        print(f"{label}: varied {p['varied']:.1f} dB vs walk {p['walk']:.1f} dB: difference "
              f"{p['walk'] - p['varied']:.1f} dB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
