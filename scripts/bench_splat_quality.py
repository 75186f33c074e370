"""What the compute splat's colour rule buys and costs (issue 43): frame 0 of shipped scenes in mode points, each
colour rule's PSNR against the true reference and its draw time.

The rules (``[lod] splat_blend``; render/points/blend.py, points_splat.glsl): ``nearest`` (each anchor takes its
nearest point's colour, the rule before issue 43) and ``blend`` (the weighted mean of the points within a depth
tolerance of an anchor's nearest, at tolerances of 0.5, 1, 2 and 4 splat footprints; weights ``area``, the point's
projected area |n . v|, or ``flat``, every point alike). The reference is :mod:`crowd.reference`'s (full detail,
K x K samples per pixel, box-filtered; cached by content). Draw time: the median of ``--repeats`` draws of the
same selection (each ``Renderer.draw`` ends with ``ctx.finish()``), interleaved over the rules (ratios within one
run; llvmpipe's timer queries are unreliable). Writes a Markdown table to ``--out`` (default
``scripts/bench_splat_quality.md``, atomically).

``--fox N`` adds N copies of ``../shared/assets/Fox.glb`` in ``scripts/bench_peer.py``'s view, with full detail on
the hardware path drawn and timed beside the rules (issue 43's first acceptance figure: points against that).

Run:  .venv/bin/python scripts/bench_splat_quality.py [--scenes stadium grid quickstart] [--repeats 7]
      [--size 1280 720] [--k 4] [--fox 1024]
"""
from __future__ import annotations

import argparse
import datetime
import io
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))  # bench_peer's view of the Foxes (--fox)

#: (name, blend, tolerance in splat footprints, weight)
RULES = (("nearest", False, 0.0, "area"), ("blend 0.5 area", True, 0.5, "area"), ("blend 1 area", True, 1.0, "area"),
         ("blend 2 area", True, 2.0, "area"), ("blend 4 area", True, 4.0, "area"), ("blend 2 flat", True, 2.0, "flat"))
#: LOD options that keep cold hierarchy builds short (as scripts/bench_reference.py)
LOD = {"keyframes": 3, "intervals": 1}
DEFAULT_SCENES = ("stadium", "grid", "quickstart", "exhibition", "horses")


def _draw_seconds(r, dl, bg) -> float:
    """Seconds of one draw of ``dl`` (Renderer.draw ends with ``ctx.finish()``: the GPU's work included)."""
    t0 = time.perf_counter()
    r.draw(dl, bg)
    return time.perf_counter() - t0


def _timed(r, dl, bg, repeats: int) -> tuple:
    """(median seconds of ``repeats`` draws of ``dl``, the last image); one untimed draw first."""
    _draw_seconds(r, dl, bg)
    t = [_draw_seconds(r, dl, bg) for _ in range(repeats)]
    return statistics.median(t), r.read_pixels()


def _frame0(eng, r):
    """The DrawList of frame 0 as ``crowd run`` draws it: one step, then the camera at the world's time."""
    eng.step({})
    camera, _ = eng.terrain_frame(eng.camera_at(eng.world.time), r)
    return eng.select(camera, r.size)


def run_scene(path: Path, size, k: int, repeats: int, full: bool = False) -> dict:
    from crowd.engine import Engine
    from crowd.image_metrics import psnr
    from crowd.images import read_png
    from crowd.reference import reference_scene
    from crowd.reference_cache import reference_task
    from crowd.report.settings import expand_settings

    base = expand_settings(path, [], size=tuple(size), frames=1)[0].scene
    ref = reference_task(reference_scene(base), [0], k)
    if "error" in ref:
        from crowd.errors import CrowdError

        raise CrowdError(ref["error"])
    ref_img = read_png(io.BytesIO(ref["files"]["frames/frame_00000.png"]))
    sweeps = [("lod.mode", ["points"])] + [(f"lod.{key}", [v]) for key, v in LOD.items()]
    sc = expand_settings(path, sweeps, size=tuple(size), frames=1)[0].scene
    out = {"scene": path.stem, "psnr": {}, "ms": {}}
    with Engine(sc, quiet=True) as eng:
        r = eng._open_renderer()
        dl = _frame0(eng, r)
        bg = sc.render.background
        d = r.drawer("points")
        times = {name: [] for name, *_ in RULES}
        for rep in range(repeats + 1):  # round 0: each rule's first draw (compiles; not timed) and its image
            for name, blend, tol, weight in RULES:
                dl.options["splat_blend"] = tol if blend else 0.0  # as [lod] splat_blend names it
                d.blend_weight = weight
                sec = _draw_seconds(r, dl, bg)
                if rep == 0:
                    out["psnr"][name] = psnr(r.read_pixels(), ref_img)
                else:
                    times[name].append(sec)
        out["ms"] = {n: 1e3 * statistics.median(t) for n, t in times.items()}
        out["points"] = int(d.last_counts.get("points", 0))
    if full:  # full detail on the hardware path (the acceptance's baseline), drawn and timed the same way
        import dataclasses

        none = dataclasses.replace(base, render=dataclasses.replace(base.render, raster_threshold=0.0))
        with Engine(none, quiet=True) as eng:
            r = eng._open_renderer()
            sec, img = _timed(r, _frame0(eng, r), none.render.background, repeats)
            out["full"] = (psnr(img, ref_img), 1e3 * sec)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", nargs="*", default=list(DEFAULT_SCENES), help="shipped scenes (none: --fox alone)")
    ap.add_argument("--size", nargs=2, type=int, default=[1280, 720])
    ap.add_argument("--k", type=int, default=4, help="samples per pixel along each axis of the reference")
    ap.add_argument("--repeats", type=int, default=7, help="timed draws per rule (median)")
    ap.add_argument("--fox", type=int, default=0, help="also N copies of ../shared/assets' Fox.glb in "
                    "scripts/bench_peer.py's view (issue 43's first figure), with full detail beside the rules")
    ap.add_argument("--out", default=str(ROOT / "scripts" / "bench_splat_quality.md"))
    args = ap.parse_args(argv)
    if args.repeats < 1 or min(args.size) < 1 or not 2 <= args.k <= 8 or args.fox < 0:
        print("bench_splat_quality: expected --repeats >= 1, a positive --size, --k in 2..8 and --fox >= 0",
              file=sys.stderr)
        return 2
    paths = []
    for s in args.scenes:
        p = ROOT / "scenes" / f"{s}.toml"
        if not p.is_file():
            print(f"bench_splat_quality: --scenes {s}: no such shipped scene (scenes/{s}.toml)", file=sys.stderr)
            return 2
        paths.append(p)
    from crowd.errors import CrowdError

    tmp = None
    if args.fox:
        import tempfile

        from bench_peer import ASSETS, scenario, scene_text
        from sim.gltf.load import load_gltf

        fox = ASSETS / "Fox.glb"
        if not fox.is_file():
            print(f"bench_splat_quality: --fox: {fox} is absent", file=sys.stderr)
            return 2
        ch = load_gltf(fox)
        rest = np.asarray(ch.mesh.positions, np.float64)
        tmp = tempfile.TemporaryDirectory(prefix="bench-splat-")
        p = Path(tmp.name) / f"fox{args.fox}.toml"
        p.write_text(scene_text(fox.resolve(), ch.clip_names()[0], scenario(float(np.ptp(rest, axis=0).max()),
                                                                              args.fox), args.size))
        paths.append(p)
    load0 = os.getloadavg()[0]
    rows = []
    for p in paths:
        try:
            rows.append(run_scene(p, args.size, args.k, args.repeats, full=p.stem.startswith("fox")))
        except CrowdError as e:
            print(f"bench_splat_quality: {p.name}: {str(e).splitlines()[0]}", file=sys.stderr)
            return 2
        r = rows[-1]
        print(f"{r['scene']}: " + ", ".join(f"{n} {r['psnr'][n]:.2f} dB {r['ms'][n]:.1f} ms" for n, *_ in RULES)
              + (f"; full detail {r['full'][0]:.2f} dB {r['full'][1]:.1f} ms" if "full" in r else ""), flush=True)
    names = [n for n, *_ in RULES]
    cmd = " ".join(["scripts/bench_splat_quality.py", *(sys.argv[1:] if argv is None else argv)])
    lines = [f"# The compute splat's colour rule: accuracy and cost ({datetime.date.today().isoformat()})", "",
             f"`.venv/bin/python {cmd}`: "
             f"frame 0 of each scene in mode points at {args.size[0]}x{args.size[1]}, PSNR (dB) against full detail "
             f"with {args.k} x {args.k} samples per pixel (crowd/reference.py), and the median of {args.repeats} "
             "draws of the same selection (ms, interleaved over the rules; each draw ends with ctx.finish()). Rules: "
             "`nearest`, an anchor's nearest point alone (before issue 43); `blend T W`, the weighted mean of the "
             "points within T splat footprints (eye depth) behind an anchor's nearest, weights `area` (projected "
             "area, |n . v|) or `flat`. Load average at the start "
             f"{load0:.2f}, at the end {os.getloadavg()[0]:.2f}.", "",
             "| scene | points | " + " | ".join(f"{n} dB" for n in names) + " | "
             + " | ".join(f"{n} ms" for n in names) + " |",
             "| --- | ---: | " + " | ".join("---:" for _ in names * 2) + " |"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['points']:,} | " + " | ".join(f"{r['psnr'][n]:.2f}" for n in names) + " | "
                     + " | ".join(f"{r['ms'][n]:.1f}" for n in names) + " |")
    for r in rows:
        if "full" in r:
            lines += ["", f"{r['scene']}: full detail (mode none, hardware path) {r['full'][0]:.2f} dB in "
                      f"{r['full'][1]:.1f} ms a draw; the rules' draws at " + ", ".join(
                          f"{n} {r['ms'][n] / r['full'][1]:.2f}x" for n in names) + " of it."]
    from sim.atomic_io import write_atomic

    write_atomic(args.out, "\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
