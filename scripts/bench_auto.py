"""Benchmark: LOD mode "auto" against full detail and each single representation (issue 7).

For each scene at 1280x720, in ONE run with one renderer, on the same simulated
frames along the scene's camera path: the frame time (select + upload + draw +
``ctx.finish``) of NoLOD (``lod.full.mode``), of each single representation
(triangle chains at ``--poe``, cluster cuts at ``--poe``, point hierarchies at
splat size ``--splat``) and of auto at the fixed bound ``--poe`` twice: "auto"
(a point hierarchy's error = splat size + projected keyframe deviation, the
default) and "auto-splat" (``points_error = "splat"``: the splat size alone,
issue 7's definition), with the image
error of each against NoLOD (PSNR, dB) and, for auto, the cost model's
predicted render time against the measured one. NoLOD frames whose predicted
render time exceeds ``--nolod-max`` seconds are not drawn (their time is the
prediction, marked ``~``; the image error then has no reference).

The summary gives auto / best single as the ratio of the medians and, "paired",
as the median over the frames of auto-splat's time over the best single
representation's on the same frame (steadier: one list drawn on llvmpipe
varies by up to 2x from frame to frame).

``--budget SCENE`` then runs auto in budget mode on that scene with a budget
of 3x the best fixed-bound frame time measured there, for ``--budget-frames``
frames (the engine's observe loop), and prints the p95 frame time against the
budget.

The cases after NoLOD run in a new random order every frame (seeded; a case drawn right
after a heavy frame measures slower on llvmpipe, so no case keeps one position or one
predecessor).

Point hierarchies of both points and auto use ``--keyframes`` (default 3) and
``--intervals`` (default 1): cold builds at the modes' defaults (9, 3) take
minutes per segment of a 100k-triangle character on the shared machine.

Run:  .venv/bin/python scripts/bench_auto.py [--scenes grid office] [--frames 1] [--warmup 1]
      [--poe 1.0] [--splat 2] [--keyframes 3] [--intervals 1] [--size 1280 720] [--nolod-max 20]
      [--budget stampede] [--budget-frames 16] [--pricing-frames 15 [--pricing-only]]

``--pricing-frames N`` first times auto's selection alone on N frames with its frame plans priced in one pass
over all groups (``lod.auto.plans.price_plans``, the default) and with the per-group loop it replaced,
alternating, and checks that both draw the same lists.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from crowd.engine import Engine  # noqa: E402
from crowd.image_metrics import psnr  # noqa: E402
from crowd.scene import load_scene  # noqa: E402
from lod.chains import mode as triangles_mode  # noqa: E402
from lod.auto import mode as auto_mode
from lod.clusters import mode as clusters_mode
from lod.auto import cost_model
from lod.full import mode as nolod
from lod.points import mode as points_mode
from render.context import gl_info  # noqa: E402
from render.renderer import Renderer  # noqa: E402

SCENES = ("poser4", "horses", "stadium", "grid", "office", "exhibition", "stampede")
CASES = ("nolod", "triangles", "clusters", "points", "auto", "auto-splat")


def build_cases(eng, args, model):
    sc = eng.scene
    chars, names, fps = eng.plan.characters, [c.name for c in sc.characters], [c.fps for c in sc.characters]
    st = eng.statics
    q = False
    out = {}
    t0 = time.perf_counter()
    reps, sel = nolod.build(chars, names, fps, {}, static_reps=st)
    out["nolod"] = (reps, sel)
    out["triangles"] = triangles_mode.build(chars, names, fps, {"poe": args.poe}, static_reps=st, progress=q)
    out["clusters"] = clusters_mode.build(chars, names, fps, {"poe": args.poe}, static_reps=st, progress=q)
    pp = {"keyframes": args.keyframes, "intervals": args.intervals}
    # as crowd.engine builds them: the simulation's instancing groups (super-hierarchies, §3.6) and the clips
    # the scene can play
    ex = {"instancing": eng.world.resources.get("instancing"), "clips": eng._played_clips()}
    out["points"] = points_mode.build(chars, names, fps, {"splat_size": args.splat, **pp}, static_reps=st, progress=q,
                                      **ex)
    out["auto"] = auto_mode.build(chars, names, fps, {"poe": args.poe, "keyframes": args.keyframes}, static_reps=st,
                                  progress=q, model=model, points_params={"intervals": args.intervals}, **ex)
    out["auto-splat"] = auto_mode.build(chars, names, fps, {"poe": args.poe, "keyframes": args.keyframes,
                                                            "points_error": "splat"}, static_reps=st, progress=q,
                                        model=model, points_params={"intervals": args.intervals}, **ex)
    print(f"  representations built or loaded in {time.perf_counter() - t0:.1f} s", flush=True)
    return out


def pricing_section(eng, cases, args) -> dict:
    """Selection time of auto with the frame plans priced in one pass over all groups
    (``lod.auto.plans.price_plans``) and with the per-group loop it replaced (``price_plans_loop``),
    alternating on the same simulated frames (no drawing); also checks both draw the same lists."""
    size = tuple(args.size)
    statics = [(s.key, np.eye(4)) for s in eng.statics]
    out = {}
    for name in ("auto", "auto-splat"):
        sel = cases[name][1]
        frames0 = sel._frames  # these selections are not observed: the timed run still explores from its start
        t = {True: [], False: []}
        groups = []
        for k in range(args.pricing_frames):
            cam = eng.camera_at(eng.world.frame * eng.scene.dt)
            lists = {}
            for one in ((True, False) if k % 2 == 0 else (False, True)):
                sel._plans = (lambda f, g, b, fx=(0.0, frozenset()), one=one:
                              type(sel)._plans(sel, f, g, b, fx, one_pass=one))
                a = time.perf_counter()
                dl = sel.select(eng.world.state, cam, size, statics=statics)
                t[one].append(time.perf_counter() - a)
                lists[one] = [(x.rep, x.part, x.level, tuple(np.asarray(x.instance_ids).tolist())) for x in dl.batches]
            del sel._plans
            sel._frames = frames0
            if lists[True] != lists[False]:
                raise SystemExit(f"bench_auto: {name}: one-pass and per-group pricing drew different lists")
            groups.append(sum(1 for x in dl.batches))
            eng.step()
        out[name] = (statistics.median(t[True]), statistics.median(t[False]), statistics.median(groups))
        print(f"  {name} selection: one pass {1e3 * out[name][0]:.2f} ms, per-group loop {1e3 * out[name][1]:.2f} ms "
              f"(median of {args.pricing_frames} alternating frames; {out[name][2]:.0f} batches drawn; same lists)",
              flush=True)
    return out


def bench_scene(path: Path, args, model) -> dict:
    size = tuple(args.size)
    eng = Engine(load_scene(path), overrides={"size": size}, quiet=True)
    sc = eng.scene
    cases = build_cases(eng, args, model)
    if args.pricing_frames:
        for _ in range(args.steps):
            eng.step()
        pricing = pricing_section(eng, cases, args)
        if args.pricing_only:
            eng.close()
            return {"scene": path.stem, "pricing": pricing}
    r = Renderer(size)
    for reps, _ in cases.values():
        for rep in reps:
            if rep.key not in r.reps:
                r.upload(rep)
    for rep in eng.statics:
        r.upload(rep)
    for _ in range(args.steps):
        eng.step()
    statics = [(s.key, np.eye(4)) for s in eng.statics]
    times = {n: [] for n in CASES}
    est = {n: False for n in CASES}
    err = {n: [] for n in CASES}
    sels = {n: [] for n in CASES}
    plans = {n: [] for n in CASES}
    pred, meas = [], []
    info = {}
    order_rng = np.random.default_rng(7)
    for k in range(args.warmup + args.frames):
        cam = eng.camera_at(eng.world.frame * sc.dt)
        ref = None
        # NoLOD first (the reference image), the others in a new random order every frame (seeded): a case
        # drawn right after a heavy one (e.g. a 0.8 s triangle frame) runs slower on llvmpipe, so no case
        # keeps one position or one predecessor
        for name in ["nolod"] + [CASES[1 + i] for i in order_rng.permutation(len(CASES) - 1)]:
            sel = cases[name][1]
            a = time.perf_counter()
            dl = sel.select(eng.world.state, cam, size, statics=statics)
            if name == "nolod" and model.predict(dl) > args.nolod_max:
                times[name].append(time.perf_counter() - a + model.predict(dl))
                est[name] = True
                print(f"    frame {k} nolod: not drawn, predicted {model.predict(dl):.1f} s "
                      f"({dl.stats['triangles']:,} triangles)", flush=True)
                continue
            s_sel = time.perf_counter() - a
            t = r.draw(dl)
            b = time.perf_counter()
            img = r.read_pixels()
            if name == "nolod":
                ref = img
            elif ref is not None and k >= args.warmup:
                err[name].append(psnr(img, ref))
            measured = sum(float(t.get(s) or 0.0) for s in ("upload", "draw", "finish"))
            if name.startswith("auto"):
                # as crowd.engine does: selection + rendering; the selector refits its model with the rendering
                # share (lod.auto.mode.AutoSelector.observe) and budget mode adapts to the whole
                sel.observe(s_sel + measured)
            if k >= args.warmup:
                times[name].append(b - a)
                sels[name].append(s_sel)
                if name.startswith("auto"):
                    pred.append(dl.stats["auto"]["predicted_ms"] * 1e-3)
                    meas.append(measured)
                    info[name] = dl.stats["auto"]["representations"]
                    plans[name].append(dl.stats["auto"]["plan"])
            extra = (f", plan {dl.stats['auto']['plan']}, predicted {dl.stats['auto']['predicted_ms']:.1f} ms vs "
                     f"measured {1e3 * measured:.1f} ms, {dl.stats['auto']['options']}, plans (ms) "
                     f"{ {n: round(v, 1) for n, v in dl.stats['auto']['plans_ms'].items()} }"
                     if name.startswith("auto") else "")
            print(f"    frame {k} {name}: {b - a:.3f} s (select {s_sel:.3f}, render {measured:.3f}), "
                  f"{dl.stats['triangles']:,} tris, "
                  f"{dl.stats.get('points', 0):,} points, {dl.stats['instances']} inst{extra}", flush=True)
        eng.step()
    out = {"scene": path.stem, "agents": int(eng.world.state.n),
           "t": {n: statistics.median(v) for n, v in times.items() if v}, "est": est, "frames": times,
           "psnr": {n: (statistics.median(v) if v else None) for n, v in err.items()},
           "pred_err": [abs(p - m) / m for p, m in zip(pred, meas) if m > 0], "reps": info,
           "sel": {n: statistics.median(v) for n, v in sels.items() if v}, "plans": plans}
    if args.budget and path.stem == args.budget:
        best = min(out["t"][n] for n in ("triangles", "clusters", "points", "auto", "auto-splat"))
        budget = 3.0 * best
        chars = eng.plan.characters
        _, bsel = auto_mode.build(chars, [c.name for c in sc.characters], [c.fps for c in sc.characters],
                                  {"poe": args.poe, "budget_ms": 1e3 * budget, "keyframes": args.keyframes},
                                  static_reps=eng.statics, progress=False, model=model,
                                  points_params={"intervals": args.intervals})
        ft, bounds = [], []
        for k in range(args.budget_frames):
            cam = eng.camera_at(eng.world.frame * sc.dt)
            a = time.perf_counter()
            dl = bsel.select(eng.world.state, cam, size, statics=statics)
            t = r.draw(dl)
            ft.append(time.perf_counter() - a)
            bsel.observe(ft[-1])  # the budget is on the whole frame: selection + rendering
            bounds.append(dl.stats["auto"]["bound"])
            print(f"    budget frame {k}: {ft[-1]:.3f} s (budget {budget:.3f}), bound {bounds[-1]:.2f}", flush=True)
            eng.step()
        out["budget"] = {"budget": budget, "p95": float(np.percentile(ft[len(ft) // 2:], 95)), "bounds": bounds}
    r.release()
    eng.close()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--frames", type=int, default=1, help="timed frames per case (median)")
    ap.add_argument("--warmup", type=int, default=3, help="untimed frames first (auto measures and corrects "
                    "its frame plans over them)")
    ap.add_argument("--steps", type=int, default=5, help="simulation steps before the first frame")
    ap.add_argument("--poe", type=float, default=1.0, help="pixels of error of triangles, clusters and auto")
    ap.add_argument("--splat", type=int, default=2, help="splat size of mode points")
    ap.add_argument("--keyframes", type=int, default=3, help="poses baked per clip for the point hierarchies "
                    "(points and auto; few: cold builds of 100k-triangle characters take minutes per segment)")
    ap.add_argument("--intervals", type=int, default=1, help="stratification time intervals of the point "
                    "hierarchies (points and auto)")
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--nolod-max", type=float, default=20.0, help="seconds; NoLOD frames predicted slower are "
                    "not drawn")
    ap.add_argument("--budget", default="", help="scene to run budget mode on (e.g. stampede)")
    ap.add_argument("--budget-frames", type=int, default=16)
    ap.add_argument("--pricing-frames", type=int, default=0, help="frames of auto's selection timed with the "
                    "one-pass plan pricing against the per-group loop it replaced (0: skip)")
    ap.add_argument("--pricing-only", action="store_true", help="only that selection timing (no drawing)")
    args = ap.parse_args(argv)
    with Renderer((64, 64)) as probe:
        model = cost_model.load(gl_info(probe.ctx).get("GL_RENDERER") or "")
    print(f"cost model: {model.key or 'defaults'}", flush=True)
    rows = []
    for s in args.scenes:
        p = Path(s) if s.endswith(".toml") else ROOT / "scenes" / f"{s}.toml"
        print(f"# {p.stem}", flush=True)
        rows.append(bench_scene(p, args, model))
    print(f"\n{'scene':<11} " + " ".join(f"{n + ' s':>12}" for n in CASES) + "  auto/best  splat/best"
          "  paired  PSNR dB (tri clu pts auto auto-splat)  pred err  auto reps")
    for o in rows:
        if "t" not in o:
            continue
        t = o["t"]
        best_name = min(("triangles", "clusters", "points"), key=lambda n: t[n])
        best = t[best_name]
        # the same ratio frame by frame (every case draws each simulated frame; frames of one list vary by up
        # to 2x on llvmpipe, so the median of the per-frame ratios is the steadier figure)
        fa, fb = o["frames"]["auto-splat"], o["frames"][best_name]
        paired = statistics.median(x / y for x, y in zip(fa, fb)) if fa and len(fa) == len(fb) else float("nan")
        # against the fastest single mode of each frame (the strictest pairing), for both autos
        fmin = [min(v) for v in zip(*(o["frames"][n] for n in ("triangles", "clusters", "points")))]
        strict = {n: statistics.median(x / y for x, y in zip(o["frames"][n], fmin)) for n in ("auto", "auto-splat")
                  if len(o["frames"][n]) == len(fmin) and fmin}
        cells = " ".join(f"{('~' if o['est'][n] else '') + format(t[n], '.3f'):>12}" for n in CASES)
        ps = " ".join(f"{o['psnr'][n]:.1f}" if o["psnr"][n] is not None else "-" for n in CASES[1:])
        pe = f"{100 * statistics.median(o['pred_err']):.0f} %" if o["pred_err"] else "-"
        print(f"{o['scene']:<11} {cells}  {t['auto'] / best:9.2f}  {t['auto-splat'] / best:10.2f}  {paired:6.2f}"
              f"  {ps:>37}  {pe:>8}  {o['reps']}")
        print(f"  paired per frame: auto / {best_name} {statistics.median(x / y for x, y in zip(o['frames']['auto'], fb)):.3f}, "
              f"auto-splat / {best_name} {paired:.3f}; against each frame's fastest single mode: "
              + ", ".join(f"{n} {v:.3f}" for n, v in strict.items()))
        print("  selection s (median): " + " ".join(f"{n} {v:.3f}" for n, v in o["sel"].items())
              + f"; auto plans {o['plans'].get('auto')}, auto-splat plans {o['plans'].get('auto-splat')}")
        if "budget" in o:
            b = o["budget"]
            print(f"  budget mode: budget {b['budget']:.3f} s, p95 {b['p95']:.3f} s "
                  f"({100 * (b['p95'] / b['budget'] - 1):+.0f} %), final bound {b['bounds'][-1]:.2f}")
    allp = [e for o in rows for e in o.get("pred_err", ())]
    if allp:
        print(f"median |predicted - measured| / measured over all auto frames: {100 * statistics.median(allp):.0f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
