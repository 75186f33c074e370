"""Benchmark: build time of the point-sample hierarchy per keyframe pair (Wand & Straßer 2002, §3.4.2).

Bakes a procedural humanoid (``sim.procedural.humanoid``, default 30,000
triangles) walking into keyframes and builds the octree of prefiltered points
and triangles (``lod.points.octree.build_segment``) for the first keyframe
pairs. Prints the wall time per pair (after one warm-up build that compiles
the numba kernels), the points and nodes produced, the data structure size,
and the paper's figure for comparison (20-25 s per pair for a 30,000-triangle
walking character with one time interval on a 2 GHz Pentium 4; target here
<= 3 s).

Run:  .venv/bin/python scripts/bench_points_build.py [--triangles 30000]
      [--pairs 1] [--intervals 3] [--fraction 0.125] [--k 2] [--threads N] [--compare-threads]

The build stratifies (one work item per node and time interval) and filters
the octree nodes in parallel threads (``lod.points.stratify.worker_count``:
the usable cores by default; ``--threads N`` sets it). ``--compare-threads``
also times each pair in one thread, in the same run, and checks that both
builds are identical.
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lod.points.config import POINTS_SPACING_FRACTION, POINTS_TIME_INTERVALS, POINTS_TRIANGLE_SAMPLES  # noqa: E402
from lod.points.octree import build_segment  # noqa: E402
from sim.keyframes import bake_skinned  # noqa: E402
from sim.procedural import humanoid  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=30000)
    ap.add_argument("--keyframes", type=int, default=9, help="keyframes baked from the walk clip")
    ap.add_argument("--pairs", type=int, default=1, help="keyframe pairs to build and time")
    ap.add_argument("--intervals", type=int, default=POINTS_TIME_INTERVALS)
    ap.add_argument("--fraction", type=float, default=POINTS_SPACING_FRACTION, help="spacing / node side")
    ap.add_argument("--threads", type=int, default=None, help="worker threads (default: the usable cores)")
    ap.add_argument("--compare-threads", action="store_true",
                    help="also build each pair in one thread (same run) and check the results are identical")
    ap.add_argument("--k", type=int, default=POINTS_TRIANGLE_SAMPLES,
                    help="a triangle with more than k kept samples is stored as a triangle")
    args = ap.parse_args(argv)

    anim = bake_skinned(humanoid(args.triangles, 0), "walk", args.keyframes)
    T = anim.segments[0].indices.shape[0]
    # warm-up: compile the kernels (numba cache) on a small character
    build_segment(bake_skinned(humanoid(1000, 1), "walk", 2), 0, progress=False)
    print(f"machine: {platform.processor() or platform.machine()}, python {platform.python_version()}")
    print(f"character: humanoid, {T} triangles, {anim.n_keyframes} keyframes; "
          f"intervals={args.intervals}, spacing fraction={args.fraction:.4g}, k={args.k}")
    import os

    from lod.points.stratify import worker_count

    workers = worker_count(args.threads)
    print(f"cores: {os.cpu_count()}, threads: {workers}, load average {os.getloadavg()[0]:.1f}")
    kw = dict(intervals=args.intervals, spacing_fraction=args.fraction, triangle_samples=args.k, progress=False)
    times = []
    serial = []
    for k in range(min(args.pairs, len(anim.segments))):
        t0 = time.perf_counter()
        h = build_segment(anim, k, seed=k, threads=workers, **kw)
        dt = time.perf_counter() - t0
        times.append(dt)
        print(f"pair {k}: {dt:6.2f} s  nodes={h.n_nodes}  points={h.n_points} "
              f"(per interval {h.point_count.sum(0).tolist()})  stored triangles at inner nodes="
              f"{int(h.tri_count[h.child_count > 0].sum())}  size={h.nbytes / 1e6:.1f} MB")
        if args.compare_threads:  # the same build in one thread, same run
            t0 = time.perf_counter()
            h1 = build_segment(anim, k, seed=k, threads=1, **kw)
            serial.append(time.perf_counter() - t0)
            same = all(np.array_equal(v, getattr(h1, n)) for n, v in h.__dict__.items() if isinstance(v, np.ndarray))
            print(f"pair {k} in one thread: {serial[-1]:6.2f} s, identical: {same}")
    print(f"load average {os.getloadavg()[0]:.1f}")
    if serial:
        print(f"one thread: median {np.median(serial):.2f} s; {workers} threads / one thread = "
              f"{np.median(times) / np.median(serial):.2f}")
    print(f"build time per keyframe pair ({workers} threads): median {np.median(times):.2f} s "
          f"(paper: 20-25 s, 1 interval, P4 2 GHz; target <= 3 s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
