"""Benchmark: occlusion culling of point-hierarchy nodes (render/points/occlusion.py) on the grid seen from inside.

``scenes/grid.toml`` (90,000 instances, §3.6 hierarchical instantiation, mode "points", splat 2) with its
camera replaced by a walk at eye height through the grid (:data:`INSIDE_CAMERA`; the scene's own camera
ends 3 m up looking down over the heads, where little is hidden: ``--scene-camera`` measures that one).
Per frame of the walk (consecutive frames at the scene's dt, so the previous frame's visible set is what
a running engine would have): one simulation step, one selection, then the same DrawList drawn with
occlusion culling off and on, in alternating order, in one process and one renderer. Prints per pair
the frame times (select + draw + read-back), their ratio, the jobs / points / triangles occlusion left
out and the PSNR of the culled image against the unculled one; then the medians. Besides wall time, the CPU
time of the draw (``time.process_time``: every thread of the process, llvmpipe's rasterizer threads included)
is paired too: on a shared machine it measures the work done rather than the share of the cores obtained.

Run:  .venv/bin/python scripts/bench_occlusion.py [--frames 12] [--warmup 2] [--size 1280x720]
      [--start 0.0] [--scene-camera]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from bench_points import make_engine  # noqa: E402

#: the scene's camera keys (replaced below) and a walk at eye height (1.6 m) between the grid's rows,
#: looking along a shallow diagonal of the grid
SCENE_KEYS = """keys = [
  { time = 0.0, position = [0.0, 250.0, 420.0], target = [0.0, 0.0, 0.0] },
  { time = 4.0, position = [200.0, 60.0, 200.0], target = [0.0, 0.0, 0.0] },
  { time = 8.0, position = [10.0, 3.0, 20.0], target = [0.0, 1.0, 0.0] },
]"""
INSIDE_CAMERA = """keys = [
  { time = 0.0, position = [0.0, 1.6, 0.0], target = [100.0, 1.2, -60.0] },
  { time = 4.0, position = [8.0, 1.6, -4.0], target = [108.0, 1.2, -64.0] },
  { time = 8.0, position = [16.0, 1.6, -8.0], target = [116.0, 1.2, -68.0] },
]"""


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(((a.astype(np.float64) - b.astype(np.float64)) ** 2).mean())
    return float("inf") if mse == 0.0 else 10.0 * np.log10(255.0 ** 2 / mse)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=12, help="measured frames (pairs)")
    ap.add_argument("--warmup", type=int, default=2, help="frames drawn first, not counted")
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--start", type=float, default=0.0, help="camera time of the first frame (s)")
    ap.add_argument("--scene-camera", action="store_true", help="the scene's own camera path (from --start)")
    a = ap.parse_args(argv)
    try:
        size = tuple(int(v) for v in a.size.lower().split("x"))
        if len(size) != 2 or min(size) < 16 or a.frames < 1 or a.warmup < 0:
            raise ValueError
    except ValueError:
        print(f"bench_occlusion: --size {a.size!r} / --frames {a.frames} / --warmup {a.warmup}: expected WxH "
              f"(>= 16 each), frames >= 1, warmup >= 0", file=sys.stderr)
        return 2
    edits = () if a.scene_camera else ((SCENE_KEYS, INSIDE_CAMERA),)
    t0 = time.perf_counter()
    eng = make_engine("grid", "points", size, 2, edits)
    print(f"grid, mode points, splat 2, {size[0]}x{size[1]}, camera {'of the scene' if a.scene_camera else 'inside'}"
          f" from t = {a.start:g} s; engine set up in {time.perf_counter() - t0:.0f} s; load average "
          f"{' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    with eng:
        r = eng._open_renderer()
        d = r.uploaded_drawer("points")
        dt = float(eng.scene.dt)
        rows = []
        for f in range(a.warmup + a.frames):
            eng.step()
            cam = eng.camera_at(a.start + f * dt)
            t0 = time.perf_counter()
            dl = eng.select(cam, size)
            sel = time.perf_counter() - t0
            res = {}
            for on in ((False, True) if f % 2 == 0 else (True, False)):
                d.occlusion = on
                t0, c0 = time.perf_counter(), time.process_time()
                r.draw(dl)
                img = r.read_pixels()
                res[on] = (sel + time.perf_counter() - t0, img, dict(d.last_counts), time.process_time() - c0)
            if f < a.warmup:
                continue
            c = res[True][2]
            row = {"off": res[False][0], "on": res[True][0], "ratio": res[False][0] / res[True][0],
                   "cpu_off": res[False][3], "cpu_on": res[True][3], "cpu_ratio": res[False][3] / res[True][3],
                   "psnr": psnr(res[True][1], res[False][1]), "select": sel,
                   "points": dl.stats["points"], "triangles": dl.stats["triangles"], **c}
            rows.append(row)
            print(f"  frame {f - a.warmup}: off {row['off'] * 1e3:.1f} ms, on {row['on'] * 1e3:.1f} ms, "
                  f"{row['ratio']:.2f}x (draw CPU time of all threads {row['cpu_off'] * 1e3:.0f} / "
                  f"{row['cpu_on'] * 1e3:.0f} ms, {row['cpu_ratio']:.2f}x); culled {c['occluded_point_jobs']:,} point jobs "
                  f"({c['occluded_points']:,} of {row['points']:,} points), {c['occluded_tri_jobs']:,} triangle "
                  f"jobs ({c['occluded_triangles']:,} of {row['triangles']:,} triangles); "
                  f"PSNR {row['psnr']:.1f} dB", flush=True)
    med = lambda k: statistics.median(x[k] for x in rows)  # noqa: E731
    print(f"median: off {med('off') * 1e3:.1f} ms, on {med('on') * 1e3:.1f} ms (select {med('select') * 1e3:.1f}); "
          f"paired ratio {med('ratio'):.2f}x (target >= 1.8x); draw CPU time (all threads: the work, less "
          f"sensitive to other jobs) off {med('cpu_off') * 1e3:.0f} ms, on {med('cpu_on') * 1e3:.0f} ms, paired "
          f"{med('cpu_ratio'):.2f}x; points culled "
          f"{med('occluded_points') / max(med('points'), 1):.0%}, triangles culled "
          f"{med('occluded_triangles') / max(med('triangles'), 1):.0%}; PSNR min "
          f"{min(x['psnr'] for x in rows):.1f} dB (target >= 40); load average "
          f"{' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
