"""``crowd calibrate``: measure this machine's frame-cost coefficients.

A short headless run (a few seconds) renders synthetic draw lists of the
full-detail mode (:mod:`lod.nolod`) of two procedural humanoids of different
triangle counts, varying the number of instances and splitting batches into
several draw calls, times every frame (instance upload + submission +
``ctx.finish``, the same stages ``crowd run`` times), fits the linear model of
:mod:`lod.cost_model` by non-negative least squares and stores it under this
machine and GL renderer string. Features the run does not exercise (points,
clusters) keep their :data:`lod.cost_model.DEFAULTS` coefficients.
"""
from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np

from lod import cost_model
from lod.drawlist import DrawBatch
from lod.nolod import NoLodSelector, build_rep
from lod.view import Camera
from sim.procedural import humanoid

#: (humanoid triangles, instance counts, batch splits) per calibration level
PLANS = {
    "quick": ((600, (8, 96, 480), (1, 16)), (5000, (4, 48, 160), (1, 8))),
    "full": ((600, (8, 64, 256, 800), (1, 8, 48)), (5000, (4, 32, 96, 240), (1, 4, 24))),
}


def _state(n: int, rng) -> SimpleNamespace:
    """``n`` agents scattered like a crowd seen from its edge: in a 50-degree
    wedge in front of the camera, 8 to 120 m away (most draws far and small,
    as in the benchmark scenes, so pixel fill does not dominate)."""
    d = 8.0 + 112.0 * np.sqrt(rng.uniform(0.0, 1.0, n))
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
    X : (n, 5) float64 feature counts (:func:`lod.cost_model.features`)
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


def calibrate(size=(1280, 720), quick: bool = False, save: bool = True, directory=None, ctx=None):
    """Measure, fit and (optionally) store this machine's cost model.

    Returns
    -------
    (model, path) : the fitted :class:`lod.cost_model.CostModel` and the file
    it was stored in (None when ``save`` is False)
    """
    from render.context import gl_info
    from render.renderer import Renderer

    with Renderer(size=size, ctx=ctx) as renderer:
        name = gl_info(renderer.ctx).get("GL_RENDERER") or ""
        X, y = measure(renderer, quick=quick)
    model = cost_model.fit_model(X, y, key=cost_model.machine_key(name))
    path = cost_model.save(model, directory) if save else None
    return model, path


def summary(model, path=None) -> str:
    """Lines describing a fitted model (coefficients, throughputs, fit error)."""
    c = model.coefficients
    rate = (lambda v: f"{1.0 / v / 1e6:.2f} M/s" if v > 0 else "free")
    lines = [f"cost model for {model.key or 'defaults'} ({model.samples} frames)",
             f"  per frame     {c['frame'] * 1e3:9.3f} ms",
             f"  per triangle  {c['triangles'] * 1e9:9.3f} ns  ({rate(c['triangles'])})",
             f"  per splat     {c['points'] * 1e9:9.3f} ns  ({rate(c['points'])}; default, not measured)",
             f"  per batch     {c['batches'] * 1e6:9.3f} us",
             f"  per instance  {c['instances'] * 1e6:9.3f} us",
             f"  per cluster   {c['clusters'] * 1e9:9.3f} ns  (default, not measured)"]
    if model.median_rel_error is not None:
        lines.append(f"  fit median relative error {100 * model.median_rel_error:.1f} %")
    if path is not None:
        lines.append(f"  stored in {path}")
    return "\n".join(lines)


__all__ = ["PLANS", "measure", "calibrate", "summary"]
