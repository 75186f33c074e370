"""Benchmark: LOD mode "auto" against each single mode on every shipped scene and a million agents (issue 26).

One command (the acceptance of issue 26, item 3)::

    .venv/bin/python scripts/bench_auto.py

For every scene of ``scenes/`` (``million`` included) at 1280x720, on the same simulated frames along the
scene's camera path and with one renderer, it times the single modes (triangle chains and cluster cuts at
``--poe`` pixels, point hierarchies at splat ``--splat``) and mode auto at the same bound (``points_error =
"splat"``: a point hierarchy's error is its splat size, as mode points') once per calibration of
``--calibrations``: ``right`` (a ``crowd calibrate --quick`` of this machine taken at the start, in a file of
the benchmark's own: the shared ``cost_model.json`` is never touched; ``--calibration FILE`` loads one
instead), and that calibration with every per-unit cost scaled by ``x0.3`` and ``x3`` (``skew``: point costs x3
and triangle, cluster and instance costs x0.3, the kind of error a calibration under load made in runs K-M).
Each auto has its own online fit (``lod.auto.online``) and plan chooser (``lod.auto.control``), fed every
frame as ``crowd run`` feeds them (``observe`` with the frame's selection and rendering time and its list).

Frames: the first ``--warmup`` frames (30) draw the autos only (their fits and plan choices settle; their
median is reported separately as "warm-up"), then ``--frames`` frames draw every case in a new random order
each frame (seeded; a case drawn after a heavy one measures slower on llvmpipe). Frame time = select + upload
+ draw + ``ctx.finish``; the table gives medians and "paired" medians of auto / best single mode per frame.
A single mode slower than ``--slow-factor`` x the fastest case after ``--slow-frames`` measured frames is not
drawn again (its median marked ``~``: it is not the best).

Passes (``--passes``): ``quiet``, then ``loaded`` (a second process spinning on one core for the whole pass)
and, optionally, ``half`` (that process starts halfway through the measured frames).

Image error: PSNR against the true reference (:mod:`crowd.reference`: full detail with ``--reference-samples``
K x K samples per pixel, box-filtered; the selection of mode ``none`` at K x the size drawn in tiles) on
``--nolod-samples`` measured frames per scene (evenly spaced), of the mean MSE over those frames as ``crowd
report`` measures it, and beside it against aliased full detail (mode ``none``, one sample per pixel), which
gets its own PSNR against the reference; NoLOD frames predicted slower than ``--nolod-max`` seconds are not drawn
(million: ~10 min a frame) and the scene has no PSNR. Reference images are drawn once (the simulation is
deterministic: the passes see the same states).

The script prints every figure and writes ``scripts/bench_auto.md`` (atomically; the text after its
``<!-- earlier runs -->`` line is kept). Cold builds of the hierarchies take many minutes per big scene: build
them first with ``python -m crowd build scenes/<x>.toml --mode all``. About 60-80 min on the 2-core machine
for everything (both passes), most of it office, stampede, grid and million; ``--scenes`` and ``--frames``
shorten it.

Run:  .venv/bin/python scripts/bench_auto.py [--scenes office million] [--frames 20] [--warmup 30]
      [--calibrations right,x0.3,x3] [--passes quiet,loaded] [--calibration FILE] [--out FILE]
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from crowd.engine import Engine  # noqa: E402
from crowd.image_metrics import mse  # noqa: E402
from crowd.scene import load_scene, shipped_scenes  # noqa: E402
from sim.atomic_io import atomic_open  # noqa: E402
from lod.auto import cost_model  # noqa: E402
from lod.auto import build as auto_mode  # noqa: E402
from lod.chains import mode as triangles_mode  # noqa: E402
from lod.clusters import mode as clusters_mode  # noqa: E402
from lod.full import mode as nolod  # noqa: E402
from lod.points import mode as points_mode  # noqa: E402
from render.renderer import Renderer  # noqa: E402

SINGLES = ("triangles", "clusters", "points")
CALIBRATIONS = ("right", "x0.3", "x3", "skew")
MARKER = "<!-- earlier runs -->"
#: the unit groups the "skew" calibration scales (x0.3 and x3)
SKEW_DOWN = ("triangles", "instances", "clusters", "batches", "cluster_frames")
SKEW_UP = ("points", "point_instances", "splat_pixels", "splat_area")


def scaled(model, how: str):
    """``model`` with its per-unit costs scaled as ``how`` says (every coefficient but the per-frame one)."""
    c = dict(model.coefficients)
    if how == "right":
        return model
    if how == "skew":
        f = {**{k: 0.3 for k in SKEW_DOWN}, **{k: 3.0 for k in SKEW_UP}}
    else:
        f = {k: float(how[1:]) for k in c if k != "frame"}
    return cost_model.CostModel({k: v * f.get(k, 1.0) for k, v in c.items()}, key=f"{model.key or 'defaults'} {how}")


def calibration(args):
    """The "right" model: --calibration FILE, else a quick calibration of this machine now (not stored)."""
    if args.calibration:
        m = cost_model.load_file(args.calibration)
        return m, f"loaded from {args.calibration}"
    from crowd.calibrate import calibrate

    t0 = time.perf_counter()
    m, _ = calibrate(size=tuple(args.size), quick=True, save=False)
    return m, (f"`crowd calibrate --quick` at the start ({time.perf_counter() - t0:.0f} s, fit error "
               f"{100 * (m.median_rel_error or 0):.0f} %, held-out mixed lists "
               f"{100 * (m.validation_rel_error or 0):.0f} %), not stored")


def build_cases(eng, args, models):
    chars, sc = eng.plan.characters, eng.scene
    names, fps, st = [c.name for c in sc.characters], [c.fps for c in sc.characters], eng.statics
    ex = {"instancing": eng.world.resources.get("instancing"), "clips": eng._played_clips()}
    out = {"nolod": nolod.build(chars, names, fps, {}, static_reps=st)}
    out["triangles"] = triangles_mode.build(chars, names, fps, {"poe": args.poe}, static_reps=st, progress=False)
    out["clusters"] = clusters_mode.build(chars, names, fps, {"poe": args.poe}, static_reps=st, progress=False)
    out["points"] = points_mode.build(chars, names, fps, {"splat_size": args.splat}, static_reps=st, progress=False,
                                      **ex)
    for cal, model in models.items():
        out[f"auto {cal}"] = auto_mode.build(chars, names, fps, {"poe": args.poe, "points_error": "splat"},
                                             static_reps=st, progress=False, model=model, **ex)
    return out


class Load:
    """A second process spinning on one core (started and stopped by this script only)."""

    def __init__(self):
        self.p = None

    def start(self):
        if self.p is None:
            self.p = subprocess.Popen([sys.executable, "-c", "while True: pass"])

    def stop(self):
        if self.p is not None:
            self.p.kill()
            self.p.wait()
            self.p = None


def loadavg() -> str:
    try:
        return " ".join(open("/proc/loadavg").read().split()[:3])
    except OSError:
        return "?"


def run_pass(path: Path, args, models, kind: str, refs: dict) -> dict:
    """One pass over one scene: every case on the same frames; ``refs`` (frame -> (true reference, aliased
    NoLOD image)) is filled on the first pass and reused by the next."""
    from crowd.reference import draw_tiles, plan_tiles

    size = tuple(args.size)
    scene = load_scene(path)
    scene = dataclasses.replace(scene, lod_mode="none", lod_params=())  # the cases are built here
    eng = Engine(scene, overrides={"size": size}, quiet=True)
    t0 = time.perf_counter()
    cases = build_cases(eng, args, models)
    t_build = time.perf_counter() - t0
    r = Renderer(size)
    for reps, _ in cases.values():
        for rep in reps:
            if rep.key not in r.reps:
                r.upload(rep)
    for rep in eng.statics:
        r.upload(rep)
    plan = plan_tiles(size, args.reference_samples)
    ref_r = Renderer(plan.tile_pixels, ctx=r.ctx) if args.nolod_samples else None  # the true reference's tiles
    if ref_r is not None:
        for rep in [*cases["nolod"][0], *eng.statics]:
            ref_r.upload(rep)
    big = plan.k * size[0], plan.k * size[1]
    for _ in range(args.steps):
        eng.step()
    statics = [(s.key, np.eye(4)) for s in eng.statics]
    autos = [n for n in cases if n.startswith("auto")]
    n_all = args.warmup + args.frames
    samples = set(np.linspace(args.warmup, n_all - 1, args.nolod_samples).round().astype(int).tolist()) \
        if args.nolod_samples else set()
    rec = {n: {"t": [], "render": [], "warm": [], "pred": [], "plan": [], "mse": [], "mse_aliased": [], "state": []}
           for n in cases}
    dropped, load = set(), Load()
    rng = np.random.default_rng(7)
    half_at = args.warmup + args.frames // 2
    load_avg = [loadavg()]
    try:
        if kind == "loaded":
            load.start()
        for k in range(n_all):
            if kind == "half" and k == half_at:
                load.start()
            measured = k >= args.warmup
            cam = eng.camera_at(eng.world.frame * eng.scene.dt)
            names = list(autos) + ([n for n in SINGLES if n not in dropped] if measured else [])
            names = [names[i] for i in rng.permutation(len(names))]
            ref = refs.get(k)
            if k in samples and ref is None and "nolod" not in dropped:
                names = ["nolod"] + names
            for name in names:
                sel = cases[name][1]
                a = time.perf_counter()
                dl = sel.select(eng.world.state, cam, size, statics=statics)
                s_sel = time.perf_counter() - a
                if name == "nolod" and models["right"].predict(dl) > args.nolod_max:
                    dropped.add("nolod")
                    print(f"    nolod not drawn: predicted {models['right'].predict(dl):.0f} s > --nolod-max",
                          flush=True)
                    continue
                t = r.draw(dl)
                b = time.perf_counter()
                render = sum(float(t.get(s) or 0.0) for s in ("upload", "draw", "finish"))
                x = rec[name]
                if name.startswith("auto"):
                    sel.observe(s_sel + render, select_seconds=s_sel, drawlist=dl)
                    au = dl.stats["auto"]
                    x["plan"].append(au["plan"])
                    x["state"].append(au["state"])
                    x["pred"].append((au["predicted_ms"] * 1e-3, render))
                    if not measured:
                        x["warm"].append(b - a)
                if measured:
                    x["t"].append(b - a)
                    x["render"].append(render)
                if k in samples:
                    img = r.read_pixels()
                    if name == "nolod":
                        true = draw_tiles(ref_r, sel.select(eng.world.state, cam, big, statics=statics), plan,
                                          eng.scene.render.background)
                        refs[k] = ref = (true, img)
                    if ref is not None:
                        x["mse"].append(mse(img, ref[0]))
                        x["mse_aliased"].append(mse(img, ref[1]))
            if measured:  # a single mode far slower than the fastest case is no candidate for the best
                done = k - args.warmup + 1
                if done >= args.slow_frames:
                    fastest = min(statistics.median(rec[n]["t"]) for n in names if rec[n]["t"])
                    for n in SINGLES:
                        if n not in dropped and statistics.median(rec[n]["t"]) > args.slow_factor * fastest:
                            dropped.add(n)
                            print(f"    {n}: {statistics.median(rec[n]['t']):.3f} s > {args.slow_factor} x the "
                                  f"fastest case, not drawn again", flush=True)
            if k % 10 == 0 or k == n_all - 1:
                au = rec["auto right"] if "auto right" in rec else rec[autos[0]]
                print(f"    frame {k}: " + ", ".join(f"{n} {1e3 * (rec[n]['t'] or rec[n]['warm'] or [0])[-1]:.0f}"
                                                     for n in cases if n != "nolod")
                      + f" ms; auto right plan {au['plan'][-1] if au['plan'] else '-'}; load {loadavg()}", flush=True)
                load_avg.append(loadavg())
            eng.step()
    finally:
        load.stop()
        r.release()
        if ref_r is not None:
            ref_r.release()
        eng.close()
    out = {"scene": path.stem, "agents": int(eng.world.state.n), "build_s": t_build, "dropped": sorted(dropped),
           "load": load_avg, "cases": {}}
    def db(m):
        return (math.inf if np.mean(m) == 0 else 10 * math.log10(1 / float(np.mean(m)))) if m else None

    # aliased full detail against the reference: the first pass draws it (its rows); later passes reuse it
    nolod_mse = rec["nolod"]["mse"] or [mse(a, t) for t, a in (refs[k] for k in sorted(samples) if k in refs)]
    out["nolod_psnr"] = db(nolod_mse)
    for n, x in rec.items():
        if n == "nolod":
            continue
        c = {"median": statistics.median(x["t"]) if x["t"] else None, "frames": x["t"],
             "psnr": db(x["mse"]), "psnr_aliased": db(x["mse_aliased"])}
        if n.startswith("auto"):
            sel = cases[n][1]
            c["warmup"] = statistics.median(x["warm"]) if x["warm"] else None
            mp = x["plan"][args.warmup:]
            c["plans"] = {p: mp.count(p) / len(mp) for p in sorted(set(mp))} if mp else {}
            pe = [abs(p - m) / m for p, m in x["pred"][args.warmup:] if m > 0]
            c["pred_err"] = statistics.median(pe) if pe else None
            c["chooser"] = sel.chooser.summary() if sel.chooser is not None else {}
            c["fit"] = {"noise": sel.fit.noise, "load": sel.fit.load} if sel.fit is not None else {}
        out["cases"][n] = c
    return out


def summarize(o: dict) -> dict:
    """Best single mode, ratios (of medians, and paired per frame) and PSNR gaps of one pass over a scene."""
    cs = o["cases"]
    singles = {n: cs[n]["median"] for n in SINGLES if cs[n]["median"] is not None}
    best = min(singles, key=singles.get)
    res = {"best": best, "best_ms": 1e3 * singles[best], "autos": {}}
    for n, c in cs.items():
        if not n.startswith("auto") or c["median"] is None:
            continue
        fb, fa = cs[best]["frames"], c["frames"]
        paired = statistics.median(a / b for a, b in zip(fa, fb)) if len(fa) == len(fb) and fa else None
        beats = all(c["median"] < singles[m] for m in singles) and len(singles) == 3
        gap = (cs[best]["psnr"] - c["psnr"]) if cs[best]["psnr"] is not None and c["psnr"] is not None else None
        res["autos"][n] = {"ratio": c["median"] / singles[best], "paired": paired, "beats_all": beats,
                           "psnr_gap": gap, "ok": c["median"] <= 1.05 * singles[best] and (gap is None or gap <= 1.0)}
    return res


def table(rows: list, kind: str, cals: list) -> list:
    lines = [f"| scene | agents | triangles / clusters / points ms | best | "
             + " | ".join(f"auto {c} ms (x best; paired)" for c in cals)
             + " | auto right warm-up ms | PSNR dB vs reference: full detail (aliased) / best / auto right | "
               "PSNR dB vs aliased: best / auto right | auto right plans | pred. err | switches / explored frames |",
             "| --- | ---: | --- | --- | " + " | ".join("---" for _ in cals) + " | ---: | --- | --- | --- | ---: | --- |"]
    for o in rows:
        s, cs = summarize(o), o["cases"]
        single = " / ".join(("~" if n in o["dropped"] else "") + (f"{1e3 * cs[n]['median']:.0f}" if cs[n]["median"]
                                                                   else "-") for n in SINGLES)
        cells = []
        for c in cals:
            a = s["autos"].get(f"auto {c}")
            if a is None:
                cells.append("-")
                continue
            mark = "**" if a["ok"] else ""
            cells.append(f"{mark}{1e3 * cs[f'auto {c}']['median']:.0f} ({a['ratio']:.2f}; "
                         f"{a['paired']:.2f}){mark}" if a["paired"] is not None else f"{a['ratio']:.2f}")
        ar = cs.get("auto right", {})
        ps = lambda v: "-" if v is None else ("inf" if math.isinf(v) else f"{v:.1f}")
        plans = ", ".join(f"{p} {100 * f:.0f} %" for p, f in (ar.get("plans") or {}).items())
        ch = ar.get("chooser") or {}
        lines.append(f"| {o['scene']} | {o['agents']:,} | {single} | {s['best']} | " + " | ".join(cells)
                     + f" | {1e3 * ar['warmup']:.0f} | {ps(o.get('nolod_psnr'))} / {ps(cs[s['best']]['psnr'])} / "
                     f"{ps(ar.get('psnr'))} | {ps(cs[s['best']].get('psnr_aliased'))} / {ps(ar.get('psnr_aliased'))} | "
                     f"{plans} | "
                     f"{100 * ar['pred_err']:.0f} % | {ch.get('switches', 0)} / {ch.get('explored_frames', 0)} |"
                     if ar.get("warmup") is not None and ar.get("pred_err") is not None else " | - | - | - | - | - | - |")
    return lines


def verdict(rows: list, cals: list) -> list:
    ok, bad, beats = [], [], []
    for o in rows:
        s = summarize(o)
        for c in cals:
            a = s["autos"].get(f"auto {c}")
            if a is None:
                continue
            (ok if a["ok"] else bad).append(f"{o['scene']} ({c}: {a['ratio']:.2f}"
                                            + (f", PSNR {-a['psnr_gap']:+.1f} dB" if a["psnr_gap"] is not None else "")
                                            + ")")
            if c == "right" and a["beats_all"]:
                beats.append(o["scene"])
    return [f"- auto <= 1.05x the best single mode at <= 1 dB less PSNR: {len(ok)} of {len(ok) + len(bad)} "
            f"(scene, calibration) pairs.", f"- not met: {', '.join(bad) or 'none'}.",
            f"- faster than every single mode (calibration right): {', '.join(beats) or 'none'}."]


def write_md(path: Path, header: list, sections: list) -> None:
    old = path.read_text() if path.is_file() else ""
    earlier = old.split(MARKER, 1)[1] if MARKER in old else ("\n" + old if old else "")
    text = "\n".join(header + [""] + sections) + f"\n\n{MARKER}\n" + earlier.lstrip("\n")
    with atomic_open(path, "w") as f:
        f.write(text if text.endswith("\n") else text + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    all_scenes = [p.stem for p in shipped_scenes(ROOT / "scenes")]  # those whose data are here
    ap.add_argument("--scenes", nargs="+", default=all_scenes, help="scene names or .toml files (default: all)")
    ap.add_argument("--frames", type=int, default=20, help="measured frames per case (medians)")
    ap.add_argument("--warmup", type=int, default=30, help="frames before them, autos only (their warm-up)")
    ap.add_argument("--steps", type=int, default=5, help="simulation steps before the first frame")
    ap.add_argument("--poe", type=float, default=2.0, help="pixels of error of triangles, clusters and auto")
    ap.add_argument("--splat", type=int, default=2, help="splat size of mode points")
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--calibrations", default="right,x0.3,x3", help="comma-separated: " + ", ".join(CALIBRATIONS))
    ap.add_argument("--calibration", help="the 'right' calibration from this file (cost_model.json layout) "
                    "instead of a quick calibration now")
    ap.add_argument("--passes", default="quiet,loaded", help="comma-separated: quiet, loaded, half")
    ap.add_argument("--nolod-samples", type=int, default=3, help="measured frames per scene compared with NoLOD")
    ap.add_argument("--nolod-max", type=float, default=120.0, help="seconds; NoLOD predicted slower is not drawn")
    ap.add_argument("--reference-samples", type=int, default=4, help="K of the true reference (2 to 8)")
    ap.add_argument("--slow-factor", type=float, default=4.0)
    ap.add_argument("--slow-frames", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "scripts" / "bench_auto.md"))
    args = ap.parse_args(argv)
    cals = [c.strip() for c in args.calibrations.split(",") if c.strip()]
    passes = [p.strip() for p in args.passes.split(",") if p.strip()]
    if "right" not in cals or any(c not in CALIBRATIONS for c in cals) or \
            any(p not in ("quiet", "loaded", "half") for p in passes) or not passes:
        ap.error("--calibrations must include 'right' (of right, x0.3, x3, skew); --passes of quiet, loaded, half")
    if not 2 <= args.reference_samples <= 8:
        ap.error(f"--reference-samples {args.reference_samples}: expected 2 to 8 samples per pixel along each axis")
    start = datetime.datetime.now(datetime.timezone.utc)
    t_start = time.perf_counter()
    print(f"load at the start: {loadavg()}", flush=True)
    right, how = calibration(args)
    models = {c: scaled(right, c) for c in cals}
    print(f"calibration: {how}", flush=True)
    refs_by_scene, rows = {}, {p: [] for p in passes}
    for kind in passes:
        for s in args.scenes:
            p = Path(s) if s.endswith(".toml") else ROOT / "scenes" / f"{s}.toml"
            print(f"# {kind}: {p.stem} (load {loadavg()})", flush=True)
            o = run_pass(p, args, models, kind, refs_by_scene.setdefault(p.stem, {}))
            rows[kind].append(o)
            s_ = summarize(o)
            print(f"  best {s_['best']} {s_['best_ms']:.0f} ms; " + "; ".join(
                f"{n} x{a['ratio']:.2f} (paired {a['paired'] or float('nan'):.2f})" for n, a in s_["autos"].items()),
                flush=True)
    minutes = (time.perf_counter() - t_start) / 60
    header = ["# LOD mode auto against each single mode on every shipped scene (issue 26)", "",
              f"Run of {start:%Y-%m-%d %H:%M} UTC, {minutes:.0f} min, load average at the start "
              f"{rows[passes[0]][0]['load'][0] if rows[passes[0]] else '?'} (2 cores), "
              f"`scripts/bench_auto.py {' '.join(argv if argv is not None else sys.argv[1:])}`.",
              f"Calibration 'right': {how}; x0.3 / x3: every per-unit cost scaled"
              + ("; skew: point costs x3, triangle/cluster/instance costs x0.3" if "skew" in cals else "") + ".",
              f"{args.size[0]}x{args.size[1]}, poe {args.poe:g} px (triangles, clusters, auto with points_error "
              f"\"splat\"), points at splat {args.splat}; medians of {args.frames} frames after {args.warmup} "
              f"warm-up frames (autos only); PSNR on {args.nolod_samples} sampled frames (of the mean MSE, as "
              f"`crowd report`) against the true reference (full detail, {args.reference_samples} x "
              f"{args.reference_samples} samples per pixel, box filter) and against aliased full detail. Bold: within 1.05x of the best single mode and 1 dB of its "
              "PSNR. `~`: a single mode dropped after a few frames (far slower than the fastest case)."]
    sections = []
    for kind in passes:
        title = {"quiet": "Quiet", "loaded": "One core loaded by a second process for the whole pass",
                 "half": "One core loaded from halfway through the measured frames"}[kind]
        sections += [f"## {title}", ""] + table(rows[kind], kind, cals) + [""] + verdict(rows[kind], cals) + [
            "", "Load average per scene (start, every 10 frames): " + "; ".join(
                f"{o['scene']} {o['load'][0]} .. {o['load'][-1]}" for o in rows[kind]), ""]
    for line in header + [""] + sections:
        print(line)
    write_md(Path(args.out), header, sections)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
