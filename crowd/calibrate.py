"""``crowd calibrate``: measure this machine's frame-cost coefficients.

A short headless run renders synthetic draw lists and times every frame
(instance upload + submission + ``ctx.finish``, the stages ``crowd run``
times and mode "auto" observes), fits the linear model of
:mod:`lod.auto.cost_model` by non-negative least squares and stores it under this
machine and GL renderer string. The draw lists exercise every feature of the
model, so that predictions of the mixed draw lists of mode "auto" hold:

- full-detail triangles (:mod:`lod.full.mode`) of two procedural humanoids of
  different triangle counts, varying the number of instances and splitting
  batches into several draw calls (per triangle, per instance, per batch);
- VDR-AM cluster cuts (:mod:`lod.clusters.mode`) at several pixels of error
  (per cluster);
- Wand & Straßer point hierarchies (:mod:`lod.points.mode`) at splat sizes 1
  to 3 (per splat).

Then, held out of the fit, mixed draw lists of mode "auto" (all three
representations in one frame) are rendered and the model's median relative
error on them is stored as ``validation_rel_error``: the figure issue 7's
"predicted within 25 % of measured" is checked against.
"""
from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np

from lod.auto import cost_model
from lod.drawlist import DrawBatch
from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from sim.procedural import humanoid

#: humanoid of the cluster, point and mixed calibration draw lists (triangles)
HIER_TRIANGLES = 1500
#: poses baked per clip for the point hierarchies of the calibration (few: a short build)
HIER_KEYFRAMES = 3
#: per level: (selector, attribute, values, instance counts, farthest agent in metres, held out) of the draw
#: lists of the calibration humanoid: small crowds (to 120 m) and large far crowds (to 400 m, the regime of the
#: benchmark scenes' tens of thousands of small instances); "auto" lists are held out of the fit (validation)
HIER_PLANS = {
    "quick": (("clusters", "poe", (1.0, 4.0), (64, 320), 120.0, False),
              ("points", "splat_size", (1, 3), (64, 320), 120.0, False),
              ("triangles", "poe", (1.0,), (2000,), 400.0, False),
              ("clusters", "poe", (1.0,), (2000,), 400.0, False),
              ("points", "splat_size", (2,), (2000,), 400.0, False),
              ("auto", "poe", (1.0, 3.0), (200,), 120.0, True),
              ("auto", "poe", (2.0,), (2000,), 400.0, True)),
    "full": (("clusters", "poe", (0.5, 2.0, 8.0), (32, 160, 640), 120.0, False),
             ("points", "splat_size", (1, 2, 3), (32, 160, 640), 120.0, False),
             ("triangles", "poe", (1.0, 4.0), (2000, 8000), 400.0, False),
             ("clusters", "poe", (1.0, 4.0), (2000, 8000), 400.0, False),
             ("points", "splat_size", (1, 2, 3), (2000, 8000), 400.0, False),
             ("auto", "poe", (0.5, 1.0, 3.0), (150, 600), 120.0, True),
             ("auto", "poe", (1.0, 2.0, 4.0), (2000, 8000), 400.0, True)),
}
#: (humanoid triangles, instance counts, batch splits) per calibration level
PLANS = {
    "quick": ((600, (8, 96, 480), (1, 16)), (5000, (4, 48, 160), (1, 8))),
    "full": ((600, (8, 64, 256, 800), (1, 8, 48)), (5000, (4, 32, 96, 240), (1, 4, 24))),
}


def _state(n: int, rng, far: float = 120.0) -> SimpleNamespace:
    """``n`` agents scattered like a crowd seen from its edge: in a 50-degree
    wedge in front of the camera, 8 to ``far`` m away (most draws far and
    small, as in the benchmark scenes, so pixel fill does not dominate)."""
    d = 8.0 + (float(far) - 8.0) * np.sqrt(rng.uniform(0.0, 1.0, n))
    a = rng.uniform(-0.4, 0.4, n)
    pos = np.stack([d * np.sin(a), np.zeros(n), -d * np.cos(a)], axis=1)
    return SimpleNamespace(n=n, character=np.zeros(n, np.int64), clip=rng.integers(0, 2, n),
                           anim_time=rng.uniform(0.0, 1.0, n), position=pos, scale=np.ones(n),
                           heading=rng.uniform(-np.pi, np.pi, n))


def _split(dl, parts: int):
    out = []
    for b in dl.batches:
        k = b.n_instances
        edges = np.linspace(0, k, min(parts, k) + 1).astype(int)
        per = b.triangles // max(k, 1)
        for a, e in zip(edges[:-1], edges[1:]):
            if e > a:
                out.append(DrawBatch(b.rep, b.part, b.instance_ids[a:e], b.instance_data[a:e], triangles=per * (e - a)))
    dl.batches = out
    dl.stats["batches"] = len(out)
    dl.stats["triangles"] = int(sum(b.triangles for b in out))
    return dl


def measure(renderer, quick: bool = False, repeats: int | None = None, seed: int = 0, plans=None):
    """Render the calibration draw lists with ``renderer``.

    Returns
    -------
    X : (n, 9) float64 feature counts (:func:`lod.auto.cost_model.features`)
    y : (n,) float64 seconds, the median over ``repeats`` timed frames (after one warm-up)
    """
    rng = np.random.default_rng(seed)
    plans = plans or PLANS["quick" if quick else "full"]
    repeats = int(repeats or (2 if quick else 3))
    X, y = [], []
    for tri, counts, splits in plans:
        rep = build_rep(humanoid(tri, 0), key=f"calibrate:{tri}")
        renderer.upload(rep)
        sel = NoLodSelector([rep])
        cam = Camera.look_at((0.0, 2.0, 0.0), (0.0, 1.0, -20.0))
        for n in counts:
            st = _state(n, rng)
            for parts in splits:
                dl = _split(sel.select(st, cam, renderer.size), parts)
                times = []
                for r in range(repeats + 1):
                    t0 = time.perf_counter()
                    renderer.draw(dl)
                    dt = time.perf_counter() - t0
                    if r:
                        times.append(dt)
                X.append(cost_model.features(dl))
                y.append(float(np.median(times)))
    return np.asarray(X, np.float64), np.asarray(y, np.float64)


def _timed(renderer, dl, repeats: int) -> float:
    times = []
    for r in range(repeats + 1):
        t0 = time.perf_counter()
        renderer.draw(dl)
        if r:
            times.append(time.perf_counter() - t0)
    return float(np.median(times))


def hierarchy_selectors(quiet: bool = True):
    """The calibration character's reps and selectors of modes "triangles",
    "clusters", "points" and "auto" (chains and hierarchies from the cache,
    else built: a few seconds).

    Returns
    -------
    dict with "reps" (every rep to upload) and a selector per mode name
    ("auto": all candidates, the default cost model)
    """
    from lod.auto import cost_model as cm
    from lod.auto import build as auto_mode
    from lod.chains import mode as triangles_mode
    from lod.clusters import mode as clusters_mode
    from lod.points import mode as points_mode

    ch = humanoid(HIER_TRIANGLES, 1)
    prog = False if quiet else None
    treps, tsel = triangles_mode.build([ch], ["calibrate"], [30], {}, progress=prog)
    creps, csel = clusters_mode.build([ch], ["calibrate"], [30], {}, progress=prog)
    preps, psel = points_mode.build([ch], ["calibrate"], [30], {"keyframes": HIER_KEYFRAMES}, progress=prog)
    areps, asel = auto_mode.build([ch], ["calibrate-auto"], [30], {"keyframes": HIER_KEYFRAMES}, progress=prog,
                                  model=cm.CostModel())
    return {"reps": [*treps, *creps, *preps, *areps], "triangles": tsel, "clusters": csel, "points": psel,
            "auto": asel}


def measure_hierarchies(renderer, quick: bool = False, repeats: int | None = None, seed: int = 1, sels=None,
                        model=None, which: str = "all"):
    """Render the :data:`HIER_PLANS` draw lists: triangle chains, cluster
    cuts and point splats (fitted), and mixed lists of mode "auto" (held out).

    Parameters
    ----------
    model : the cost model the "auto" lists are selected with (default: the
        defaults); pass the model fitted so far for lists like those it will choose
    which : "all", "fit" (only the fitted lists) or "held" (only the held-out lists)

    Returns
    -------
    X : (n, 9) float64 feature counts, y : (n,) float64 seconds of the fitted
    lists; Xv, yv : the same of the held-out mixed lists (validation)
    """
    rng = np.random.default_rng(seed)
    repeats = int(repeats or (2 if quick else 3))
    sels = sels or hierarchy_selectors()
    if model is not None:  # mode auto chooses with its prior (the stored calibration), reports with model
        sels["auto"].model = sels["auto"].prior = model
    for rep in sels["reps"]:
        if rep.key not in renderer.reps:
            renderer.upload(rep)
    cam = Camera.look_at((0.0, 2.0, 0.0), (0.0, 1.0, -20.0))
    X, y, Xv, yv = [], [], [], []
    for name, attr, values, counts, far, held in HIER_PLANS["quick" if quick else "full"]:
        if (which == "fit" and held) or (which == "held" and not held):
            continue
        sel = sels[name]
        for n in counts:
            st = _state(n, rng, far)
            for v in values:
                setattr(sel, attr, v)
                dl = sel.select(st, cam, renderer.size)
                (Xv if held else X).append(cost_model.features(dl))
                (yv if held else y).append(_timed(renderer, dl, repeats))
    nf = len(cost_model.FEATURES)
    return (np.asarray(X, np.float64).reshape(-1, nf), np.asarray(y, np.float64),
            np.asarray(Xv, np.float64).reshape(-1, nf), np.asarray(yv, np.float64))


def calibrate(size=(1280, 720), quick: bool = False, save: bool = True, directory=None, ctx=None,
              hierarchies: bool = True):
    """Measure, fit and (optionally) store this machine's cost model.

    Parameters
    ----------
    hierarchies : also measure cluster cuts, point splats and (held out)
        mixed lists of mode "auto" (default)

    Returns
    -------
    (model, path) : the fitted :class:`lod.auto.cost_model.CostModel` and the file
    it was stored in (None when ``save`` is False)
    """
    from render.context import gl_info
    from render.renderer import Renderer

    with Renderer(size=size, ctx=ctx) as renderer:
        name = gl_info(renderer.ctx).get("GL_RENDERER") or ""
        X, y = measure(renderer, quick=quick)
        Xv = yv = None
        if hierarchies:
            sels = hierarchy_selectors()
            Xh, yh, _, _ = measure_hierarchies(renderer, quick=quick, sels=sels, which="fit")
            X, y = np.concatenate([X, Xh]), np.concatenate([y, yh])
        model = cost_model.fit_model(X, y, key=cost_model.machine_key(name))
        if hierarchies:  # mixed lists chosen with the fitted model, as mode auto will choose them
            _, _, Xv, yv = measure_hierarchies(renderer, quick=quick, sels=sels, model=model, which="held")
    if Xv is not None and len(yv):
        model.validation_rel_error = cost_model.relative_error(model, Xv, yv)
    path = cost_model.save(model, directory) if save else None
    return model, path


def summary(model, path=None) -> str:
    """Lines describing a fitted model (coefficients, throughputs, fit error)."""
    c = model.coefficients
    rate = (lambda v: f"{1.0 / v / 1e6:.2f} M/s" if v > 0 else "free")
    lines = [f"cost model for {model.key or 'defaults'} ({model.samples} frames)",
             f"  per frame     {c['frame'] * 1e3:9.3f} ms",
             f"  per triangle  {c['triangles'] * 1e9:9.3f} ns  ({rate(c['triangles'])})",
             f"  per splat     {c['points'] * 1e9:9.3f} ns  ({rate(c['points'])})",
             f"  per batch     {c['batches'] * 1e6:9.3f} us",
             f"  per instance  {c['instances'] * 1e6:9.3f} us  (triangle and cluster paths)",
             f"  per point instance {c['point_instances'] * 1e6:4.3f} us",
             f"  cluster path  {c['cluster_frames'] * 1e3:9.3f} ms per frame drawing any cluster cut",
             f"  per cluster   {c['clusters'] * 1e9:9.3f} ns",
             f"  point pass    {c['splat_pixels'] * 1e9:9.3f} ns per pixel + {c['splat_area'] * 1e9:.3f} ns per "
             f"pixel and squared splat size"]
    if model.median_rel_error is not None:
        lines.append(f"  fit median relative error {100 * model.median_rel_error:.1f} %")
    if getattr(model, "validation_rel_error", None) is not None:
        lines.append(f"  mixed draw lists of mode auto (held out): median relative error "
                     f"{100 * model.validation_rel_error:.1f} %")
    if path is not None:
        lines.append(f"  stored in {path}")
    return "\n".join(lines)


__all__ = ["HIER_PLANS", "PLANS", "calibrate", "hierarchy_selectors", "measure", "measure_hierarchies", "summary"]
