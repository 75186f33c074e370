"""Benchmark: mode auto's first frames on a small scene against each single mode (issue 50: no costly warm-up).

    python scripts/bench_auto_start.py [--scenes quickstart crossing] [--size 640x360] [--frames 30]
                                       [--modes none triangles clusters points] [--fox N]
                                       [--md scripts/bench_auto_start.md]

The issue's small-scene check: a short report (``--frames`` frames, default 30) of each shipped scene named (or
scene file given),
at ``--size``, in every single mode and in mode auto twice: without a calibration of this machine (the online
fit starts from the defaults, as on a machine where nothing was measured) and with one (``crowd calibrate
--quick`` measured at the start, not stored: what ``crowd build`` stores when the cache holds none). Each run
is one ``crowd.engine.Engine`` in this process (the scene's hierarchies from the cache), the frame's whole time
(simulate, select, draw) from its ``frames.csv``. Printed per scene and run: the median and the mean of frames
5 to the last (the report's window; the mean carries what exploring costs, the median hides it), auto's frames
that drew an explored plan, its switches of plan, its warm-up frames (a draw that made GL objects, left out of the
fit), the plans it held, and each median over the best single mode's. ``--fox N`` adds N Foxes in
``scripts/bench_peer.py``'s view. Runs take turns in the order given; nothing else should be running.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
#: frames before the report's window (shader compiles, first uploads)
SKIP = 5


def _size(text: str) -> tuple:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH, got {text!r}") from None
    if w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive WxH, got {text!r}")
    return w, h


def _fox_scene(n: int, size, folder: Path) -> Path | None:
    """``n`` Foxes as scripts/bench_peer.py places them (its scenario and scene text), or None without the asset."""
    sys.path.insert(0, str(ROOT / "scripts"))
    import numpy as np

    import bench_peer
    from sim.gltf.load import load_gltf

    path = bench_peer.ASSETS / "Fox.glb"
    if not path.is_file():
        print(f"# {path}: absent, the Foxes skipped")
        return None
    ch = load_gltf(path)
    rest = np.asarray(ch.mesh.positions, np.float64)
    sc = bench_peer.scenario(float((rest.max(0) - rest.min(0)).max()), n)
    out = folder / f"fox{n}.toml"
    out.write_text(bench_peer.scene_text(path, ch.clip_names()[0], sc, size))
    return out


def run(scene_path: Path, mode: str, size, frames: int, out: Path, model=None) -> dict:
    """One run of ``scene_path`` in ``mode``; ``model``: auto's prior (a CostModel; None: the defaults)."""
    import csv
    import dataclasses

    from crowd.engine import Engine
    from crowd.scene import load_scene
    from lod.auto import cost_model

    sc = load_scene(scene_path).with_overrides(size=tuple(size), png_every=0)
    sc = dataclasses.replace(sc, lod_mode=mode, lod_params=sc.lod_params if sc.lod_mode == mode else ())
    saved = cost_model.load_any
    cost_model.load_any = lambda *a, **k: model if model is not None else cost_model.CostModel()
    try:
        with Engine(sc, quiet=True) as eng:
            if mode == "auto":
                eng.explain_lod = lambda text: None  # the per-frame records (plan, state, warm-up)
            eng.run(frames=frames, out_dir=out)
    finally:
        cost_model.load_any = saved
    with open(out / "frames.csv") as f:
        rows = list(csv.DictReader(f))
    total = [1e3 * float(r["total"]) for r in rows][SKIP:]
    res = {"median": statistics.median(total), "mean": statistics.fmean(total)}
    if mode == "auto":
        recs = [json.loads(line) for line in (out / "explain_lod.jsonl").read_text().splitlines()]
        res["explored"] = sum(1 for r in recs if r.get("state") == "explore"
                              or (r.get("state") == "return" and r.get("fade_from")))
        inc = [r.get("incumbent") for r in recs]
        res["switches"] = sum(1 for a, b in zip(inc, inc[1:]) if a != b)
        res["warm"] = sum(1 for r in recs if r.get("warm_up"))
        res["plans"] = sorted({r.get("incumbent") for r in recs[SKIP:]})
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["quickstart", "crossing"],
                    help="shipped scene names, or scene files (.toml)")
    ap.add_argument("--size", type=_size, default=(640, 360))
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--modes", nargs="+", default=["none", "triangles", "clusters", "points"],
                    choices=["none", "triangles", "clusters", "points"], help="the single modes auto is set against")
    ap.add_argument("--fox", type=int, default=0, help="also N copies of ../shared/assets/Fox.glb in "
                    "scripts/bench_peer.py's view (the issue's 1,024 Foxes; skipped when the asset is absent)")
    ap.add_argument("--md", type=Path, default=None, help="write the table to this Markdown file")
    args = ap.parse_args(argv)
    if args.frames <= SKIP + 1:
        ap.error(f"--frames: expected more than {SKIP + 1}, got {args.frames}")
    paths = {s: Path(s) if s.endswith(".toml") else ROOT / "scenes" / f"{s}.toml" for s in args.scenes}
    for s, p in paths.items():
        if not p.is_file():
            ap.error(f"--scenes: {s}: no such scene file ({p})")
    if args.fox < 0:
        ap.error(f"--fox: expected a count >= 0, got {args.fox}")
    from crowd.calibrate import calibrate

    t0 = time.time()
    load0 = os.getloadavg()
    model, _ = calibrate(quick=True, save=False)
    cal_s = time.time() - t0
    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        fox = _fox_scene(args.fox, args.size, Path(tmp)) if args.fox else None
        if fox is not None:
            paths[f"{args.fox} Foxes"] = fox
        for s in paths:
            path = paths[s]
            res = {}
            for m in args.modes:
                res[m] = run(path, m, args.size, args.frames, Path(tmp) / f"{Path(s).stem}-{m}")
                print(f"{s} {m}: median {res[m]['median']:.1f} ms, mean {res[m]['mean']:.1f} ms", flush=True)
            for label, prior in (("auto, no calibration", None), ("auto, calibrated", model)):
                r = res[label] = run(path, "auto", args.size, args.frames, Path(tmp) / f"{Path(s).stem}-{label[6:8]}",
                                      prior)
                print(f"{s} {label}: median {r['median']:.1f} ms, mean {r['mean']:.1f} ms, explored {r['explored']} "
                      f"of {args.frames} frames, {r['switches']} switches, warm-up {r['warm']}, holds "
                      f"{', '.join(r['plans'])}", flush=True)
            best = min(args.modes, key=lambda m: res[m]["median"])
            for k, r in res.items():
                auto = k.startswith("auto")
                lines.append(f"| {s} | {k} | {r['median']:.1f} | {r['mean']:.1f} | "
                             + (f"{r['median'] / res[best]['median']:.2f} | {r['explored']} | {r['switches']} | "
                                f"{r['warm']} | {', '.join(r['plans'])} |" if auto else
                                ("**best** |" if k == best else f"{r['median'] / res[best]['median']:.2f} |")
                                + " | | | |"))
    load1 = os.getloadavg()
    text = (f"# Mode auto's first {args.frames} frames against each single mode (issue 50)\n\n"
            f"Command: `scripts/bench_auto_start.py --scenes {' '.join(args.scenes)}"
            + (f" --fox {args.fox}" if args.fox else "") + f" --size {args.size[0]}x"
            f"{args.size[1]} --frames {args.frames} --modes {' '.join(args.modes)}`; run of "
            f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {load0[0]:.2f} at the start, "
            f"{load1[0]:.2f} at the end (2 cores). Calibration: `crowd calibrate --quick` at the start "
            f"({cal_s:.0f} s, not stored). Frame times: simulate + select + draw from `frames.csv`, frames "
            f"{SKIP}-{args.frames - 1} (module docstring). Every mode at its own defaults (auto and triangles "
            "1 px of error, clusters 0.5 px, points splat 2): the times do not compare at equal accuracy "
            "(`scripts/bench_auto.py` measures PSNR beside them); what this table shows is what auto's start "
            "costs: exploring and warm-up frames, and the plan it settles on.\n\n"
            "| scene | run | median ms | mean ms | median / best single mode | explored frames | switches "
            "| warm-up frames | plans held |\n| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n"
            + "\n".join(lines) + "\n")
    print(text)
    if args.md is not None:
        from crowd.output import write_atomic

        write_atomic(str(args.md), text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
