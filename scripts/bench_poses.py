"""Benchmark: poses that follow the clip (issues 20 and 27) — a long clip seen close up in mode points.

One generated humanoid with two clips: its 1.1 s walk and a long clip (``--clip varied``: 30 s of
``sim.procedural.varied_clip``, its walk and run time-warped section by section; ``--clip dance``: a
``sim.dance.dance_clip``). Mode points is built for each setting (``--settings``):

- ``follow`` (the default path since issue 27): one hierarchy of rest-pose samples placed with the animation
  (``lod.points.follow``): no baked poses, memory independent of the clip's length;
- ``baked``: per clip the fewest poses within ``pose_error`` (``lod.points.poses``), one octree per keyframe pair
  (with ``--max-keyframes``: that cap);
- ``9 poses``: the earlier fixed 9 poses per clip.

One agent is drawn close up (camera ``--distance`` m away at chest height, ``--size``) at ``--frames`` times
spread over each clip, by full detail with 4 x 4 samples per pixel, box-filtered (the true reference,
``crowd.reference``) and by mode points; the table gives per setting
and clip the poses baked, the pose error (largest vertex distance between the interpolated poses and the skinned
mesh, sampled at 30 Hz, % of the character's height; 0 for follow), the build time, the MB of the hierarchies,
and the median PSNR of points against the reference. Acceptance: the long clip's median PSNR within 2 dB of the
walk's (issue 20 with baked poses; issue 27: a 62 K-triangle character with a 35 s clip, one copy 4.5 m away,
320x320: ``--triangles 62000 --clip dance --duration 35 --distance 4.5 --size 320 320 --settings follow``).

Run:  .venv/bin/python scripts/bench_poses.py [--triangles 3000] [--clip varied|dance] [--duration 30]
      [--frames 12] [--size 640 360] [--distance 3] [--settings follow baked 9poses] [--pose-error 0.02]
      [--max-keyframes 256] [--out scripts/bench_poses_last.md]
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
    from crowd.reference import DEFAULT_K, TileRenderer
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
    ap.add_argument("--clip", choices=("varied", "dance"), default="varied")
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--size", type=int, nargs=2, default=(640, 360))
    ap.add_argument("--distance", type=float, default=3.0, help="camera distance, metres")
    ap.add_argument("--settings", nargs="+", default=["follow", "baked", "9poses"],
                    choices=["follow", "baked", "9poses"])
    ap.add_argument("--out", type=Path, default=None, help="also write the table here (atomically)")
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

    from sim.dance import dance_clip

    base = humanoid(a.triangles, seed=4)
    long_name = a.clip
    long = (varied_clip(base, a.duration, seed=7, name="varied") if a.clip == "varied" else
            dance_clip(base, a.duration, seed=7, name="dance"))
    height = character_extent(base)
    cam = Camera.look_at((0.0, 1.2, a.distance), (0.0, 1.0, 0.0), fov_y=50.0, near=0.05, far=50.0)
    rng = np.random.default_rng(3)
    baked = {"animation": "baked"}
    if a.pose_error is not None:
        baked["pose_error"] = a.pose_error
    if a.max_keyframes is not None:
        baked["max_keyframes"] = a.max_keyframes
    label = "baked" + (f" pose_error {a.pose_error:g}" if a.pose_error is not None else "") + \
        (f", cap {a.max_keyframes}" if a.max_keyframes is not None else "")
    table = {"follow": ("follow", {"animation": "follow"}), "baked": (label, baked),
             "9poses": ("9 poses", {"animation": "baked", "keyframes": 9})}
    settings = [table[k] for k in a.settings]
    # the follow path builds one hierarchy per character: the walk and the long clip each get a character of
    # their own (the same mesh), so each clip's build time and memory are its own
    chars = [("walk", dataclasses.replace(base, clips={"walk": base.clip("walk")})),
             (long_name, dataclasses.replace(base, clips={long_name: long}))]
    import os

    ctx = create_context()
    rows = []
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench-poses-") as d:
        for label, params in settings:
            for name, ch in chars:
                full = build_rep(ch)
                t0 = time.perf_counter()
                reps, sel = pm.build([ch], ["h"], [30], {**params}, cache=HierarchyCache(Path(d) / label),
                                     progress=False)
                build_s = time.perf_counter() - t0
                r = Renderer(tuple(a.size), ctx=ctx)
                tiles = TileRenderer(tuple(a.size), DEFAULT_K, ctx=ctx, reps=[full])  # the true reference
                try:
                    r.upload(full)
                    r.upload(reps[0])
                    ref_sel = NoLodSelector([full])
                    dur = float(ch.clip(name).duration)
                    # times on the baked rows (30 per second): mode none draws the exact time, points the shared
                    # pose of the nearest row (pose sharing, lod.points.follow_select); on a row both are exact
                    times = np.sort(np.round(rng.uniform(0.0, dur, a.frames) * 30.0) / 30.0)
                    vals = []
                    for t in times:
                        st = CrowdState.empty(1)
                        st.anim_time[:] = t
                        ref = tiles.draw(ref_sel.select(st, cam, tiles.big))
                        r.draw(sel.select(st, cam, r.size))
                        vals.append(psnr(r.read_pixels(), ref))
                    cp = reps[0].poses.get(name)
                    n_poses = len(cp.times) if cp is not None else 0
                    err = 100 * cp.error / height if cp is not None else 0.0
                    rows.append((label, name, dur, n_poses, err, build_s, reps[0].nbytes / 1e6,
                                 float(np.median(vals))))
                    print(f"{label:16s} {name:7s} {dur:5.1f} s {n_poses:4d} poses  pose error {err:5.2f} %  "
                          f"build {build_s:6.1f} s  {reps[0].nbytes / 1e6:7.1f} MB  median PSNR "
                          f"{np.median(vals):5.1f} dB", flush=True)
                finally:
                    tiles.release()
                    r.release()
    ctx.release()
    head = (f"humanoid {a.triangles} triangles, height {height:.2f} m; close up ({a.distance:g} m), "
            f"{a.size[0]}x{a.size[1]}, {a.frames} times per clip; load average {load0:.1f} -> "
            f"{os.getloadavg()[0]:.1f}")
    lines = [head, "", "| setting | clip | clip s | poses | pose error % height | build s | MB | "
             "median PSNR dB vs reference |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    lines += ["| {} | {} | {:.1f} | {} | {:.2f} | {:.1f} | {:.1f} | {:.1f} |".format(*row) for row in rows]
    lines.append("")
    for label in dict.fromkeys(r[0] for r in rows):
        p = {r[1]: r[7] for r in rows if r[0] == label}
        lines.append(f"{label}: {long_name} {p[long_name]:.1f} dB vs walk {p['walk']:.1f} dB: difference "
                     f"{p['walk'] - p[long_name]:.1f} dB (acceptance: within 2 dB)")
    print()
    print("\n".join(lines))
    if a.out is not None:
        from sim.atomic_io import write_atomic

        cmd = "scripts/bench_poses.py " + " ".join(argv if argv is not None else sys.argv[1:])
        write_atomic(a.out, f"# bench_poses\n\nCommand: `{cmd}`\n\n" + "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
