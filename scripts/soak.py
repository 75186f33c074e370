"""Soak test: run a scene headless for a given wall time, watching memory and GL errors.

Every frame is a full engine frame (simulate, select, upload, draw, finish);
after it the resident set size (``/proc/self/statm``, resident pages x page
size) is sampled and ``ctx.error`` is read (any value but ``GL_NO_ERROR``
counts). At the end it prints the frames run, the resident memory at start,
after the warm-up and at the end, the growth after the warm-up (absolute and
in percent), the least-squares trend of the samples after the warm-up (MB
per hour: robust to the driver's allocations going up and down) and the GL
error count. Memory is compared after the warm-up
because the first frames fill caches, the instance buffer and the skinning
palette (they grow by doubling).

Exit code 0 when there was no GL error and the growth after the warm-up is
at most ``--max-growth`` percent, 1 otherwise, 2 for bad input.

The report also gives the C heap in use (glibc ``mallinfo2``: the GL
driver's memory is C heap on llvmpipe) and the renderer's instanced
submissions per frame. ``--max-triangles-in-flight 0`` turns off the
renderer's split of large draws (render.renderer, "Bounded driver memory"),
reproducing the driver's scene-pool growth the split prevents.

Run:  .venv/bin/python scripts/soak.py scenes/horses.toml --seconds 1800 [--warmup 60]
      [--warmup-frames 20] [--size 640x360] [--max-growth 2] [--malloc-trim] [--quiet]
      [--max-triangles-in-flight N]
Issue 10 asks for 30 minutes on ``horses``: growth under 2% after the first minute, no GL error.
Results: scripts/soak.md.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: bytes per page for /proc/self/statm
PAGE_BYTES = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def resident_bytes() -> int:
    """Resident set size of this process in bytes (0 where /proc is missing)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * PAGE_BYTES
    except (OSError, ValueError, IndexError):
        return 0


def heap_in_use() -> int:
    """Bytes of C heap in use (glibc ``mallinfo2``: ``uordblks + hblkhd``), 0
    where it is unavailable."""
    try:
        import ctypes

        class _MallInfo2(ctypes.Structure):
            _fields_ = [(n, ctypes.c_size_t) for n in
                        ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
                         "fordblks", "keepcost")]

        fn = ctypes.CDLL("libc.so.6").mallinfo2
        fn.restype = _MallInfo2
        m = fn()
        return int(m.uordblks + m.hblkhd)
    except (OSError, AttributeError):
        return 0


def malloc_trim():
    """``malloc_trim(0)`` of glibc (returns freed heap pages to the system); a no-op
    function elsewhere. Returns the callable."""
    try:
        import ctypes

        fn = ctypes.CDLL("libc.so.6").malloc_trim
        return lambda: fn(0)
    except (OSError, AttributeError):
        return lambda: None


def soak(scene_path: str, seconds: float, warmup: float, size=None, quiet: bool = False,
         report_every: float = 60.0, trim: bool = False, warmup_frames: int = 0,
         max_triangles_in_flight: int | None = -1) -> dict:
    """Run ``scene_path`` for ``seconds`` of wall time; returns the figures (dict).

    ``trim``: call glibc's ``malloc_trim(0)`` after every frame, so freed heap
    memory the allocator keeps (the GL driver frees and reallocates large
    vertex/binning buffers) does not count as growth.
    ``max_triangles_in_flight``: the renderer's split of large draws (-1: its
    default; None or 0: no split).
    """
    do_trim = malloc_trim() if trim else (lambda: None)
    from crowd.engine import Engine
    from crowd.scene import load_scene

    scene = load_scene(scene_path)
    if size is not None:
        scene = scene.with_overrides(size=size)
    t_build = time.perf_counter()
    with Engine(scene, quiet=True) as engine:
        renderer = engine.open_renderer()
        ctx = renderer.ctx
        if max_triangles_in_flight is None or max_triangles_in_flight >= 0:
            renderer.max_triangles_in_flight = max_triangles_in_flight or None
        limit = renderer.max_triangles_in_flight
        submissions = 0
        size = scene.render.size
        bg = scene.render.background
        build_s = time.perf_counter() - t_build
        errors: dict = {}
        rss_start = resident_bytes()
        heap_start = heap_in_use()
        heap_warm = None
        rss_warm = None
        rss_max = rss_start
        samples = []  # (seconds, resident bytes) after the warm-up
        frames = 0
        t0 = time.perf_counter()
        last_report = t0
        while True:
            now = time.perf_counter()
            if now - t0 >= seconds:
                break
            engine.step()
            cam = engine.camera_at(engine.world.time)
            renderer.draw(engine.select(cam, size), bg)
            err = ctx.error
            if err != "GL_NO_ERROR":
                errors[err] = errors.get(err, 0) + 1
            frames += 1
            submissions += renderer.last_submissions
            do_trim()
            rss = resident_bytes()
            rss_max = max(rss_max, rss)
            el = time.perf_counter() - t0
            if rss_warm is None and el >= warmup and frames >= warmup_frames:
                rss_warm = rss
                heap_warm = heap_in_use()
            if rss_warm is not None:
                samples.append((el, rss))
            if not quiet and now - last_report >= report_every:
                last_report = now
                print(f"  {now - t0:7.0f} s  frame {frames:7d}  resident {rss / 1e6:9.1f} MB  "
                      f"heap in use {heap_in_use() / 1e6:8.1f} MB  GL errors {sum(errors.values())}", flush=True)
        rss_end = resident_bytes()
        heap_end = heap_in_use()
    wall = time.perf_counter() - t0
    if rss_warm is None:  # shorter than the warm-up: compare with the start
        rss_warm, heap_warm = rss_start, heap_start
    growth = rss_end - rss_warm
    slope = 0.0  # least-squares trend of the resident memory after the warm-up, bytes per hour
    if len(samples) >= 3:
        import numpy as np

        t, m = np.array(samples, np.float64).T
        if np.ptp(t) > 0:
            slope = float(np.polyfit(t, m, 1)[0]) * 3600.0
    return {"scene": str(scene_path), "frames": frames, "seconds": wall, "build_seconds": build_s,
            "fps": frames / wall if wall > 0 else 0.0, "rss_start": rss_start, "rss_after_warmup": rss_warm,
            "rss_end": rss_end, "rss_max": rss_max, "growth_bytes": growth,
            "growth_percent": 100.0 * growth / rss_warm if rss_warm else 0.0, "trend_bytes_per_hour": slope,
            "gl_errors": sum(errors.values()), "gl_error_kinds": errors, "warmup": warmup, "trim": trim,
            "warmup_frames": warmup_frames, "heap_start": heap_start, "heap_after_warmup": heap_warm,
            "heap_end": heap_end, "submissions_per_frame": submissions / frames if frames else 0.0,
            "max_triangles_in_flight": limit}


def format_report(r: dict) -> str:
    mb = lambda b: f"{b / 1e6:.1f} MB"  # noqa: E731
    kinds = ", ".join(f"{k} x{v}" for k, v in r["gl_error_kinds"].items()) or "none"
    return "\n".join([
        f"soak {r['scene']}: {r['frames']} frames in {r['seconds']:.1f} s ({r['fps']:.2f} frames/s; "
        f"build {r['build_seconds']:.1f} s){'; malloc_trim after every frame' if r['trim'] else ''}",
        f"  resident memory: start {mb(r['rss_start'])}, after the warm-up ({r['warmup']:g} s, "
        f"{r['warmup_frames']} frames) "
        f"{mb(r['rss_after_warmup'])}, end {mb(r['rss_end'])}, max {mb(r['rss_max'])}",
        f"  memory growth after warm-up: {r['growth_bytes'] / 1e6:+.2f} MB ({r['growth_percent']:+.2f}%); "
        f"trend {r['trend_bytes_per_hour'] / 1e6:+.1f} MB/hour",
        f"  C heap in use: start {mb(r['heap_start'])}, after the warm-up {mb(r['heap_after_warmup'])}, "
        f"end {mb(r['heap_end'])}",
        f"  draw submissions per frame: {r['submissions_per_frame']:.1f} (max triangles in flight: "
        f"{r['max_triangles_in_flight'] if r['max_triangles_in_flight'] else 'no limit'})",
        f"  GL errors: {r['gl_errors']} ({kinds})",
    ])


def main(argv=None) -> int:
    from crowd.cli import _size
    from crowd.errors import user_errors

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", help="scene file (.toml)")
    ap.add_argument("--seconds", type=float, default=60.0, help="wall time to run (default 60)")
    ap.add_argument("--warmup", type=float, default=None,
                    help="seconds before the memory baseline (default: min(60, seconds / 4))")
    ap.add_argument("--warmup-frames", type=int, default=0,
                    help="frames the warm-up lasts at least (slow scenes: the driver's buffers settle after a few "
                         "frames, not seconds)")
    ap.add_argument("--size", type=_size, help="image size WxH (overrides [render] size)")
    ap.add_argument("--max-growth", type=float, default=2.0, help="percent allowed after warm-up (default 2)")
    ap.add_argument("--quiet", action="store_true", help="only the final report")
    ap.add_argument("--malloc-trim", action="store_true",
                    help="call glibc malloc_trim(0) after every frame (separates retained free heap from leaks)")
    ap.add_argument("--max-triangles-in-flight", type=int, default=-1,
                    help="the renderer's split of large draws in triangles (default: the renderer's; 0: no split)")
    a = ap.parse_args(argv)
    if not a.seconds > 0:
        ap.error(f"--seconds: expected > 0, got {a.seconds}")
    warmup = min(60.0, a.seconds / 4) if a.warmup is None else a.warmup
    try:
        r = soak(a.scene, a.seconds, warmup, size=a.size, quiet=a.quiet, trim=a.malloc_trim,
                 warmup_frames=a.warmup_frames, max_triangles_in_flight=a.max_triangles_in_flight)
    except user_errors() as e:
        print(f"soak: error: {str(e).splitlines()[0]}", file=sys.stderr)
        return 2
    print(format_report(r))
    ok = r["gl_errors"] == 0 and r["growth_percent"] <= a.max_growth
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
