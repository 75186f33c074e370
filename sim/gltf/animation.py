"""glTF animation samplers: key times and values, read and checked.

Notes
-----
Follows §3.11 of the glTF 2.0 specification (2.0.1), animations, with
Appendix C (LINEAR, STEP, CUBICSPLINE interpolation, played by
:class:`sim.clip.Channel`). Key times must not decrease; of several keys at
the same time the last is kept. The loader (:mod:`sim.gltf.load`) turns the
channels into clips or keyframes.
"""
from __future__ import annotations

import numpy as np

from sim.clip import Channel
from sim.gltf.container import _Doc, _is_int


def _read_sampler(doc: _Doc, ai: int, anim: dict, si, ncomp: tuple[int, ...] | None):
    """(times (K,), values (K, C) or (K, 3, C), interpolation) of a sampler."""
    where = f"animations[{ai}].samplers[{si}]"
    samplers = anim.get("samplers") or []
    if not _is_int(si) or not 0 <= si < len(samplers):
        doc.fail(f"animations[{ai}]: sampler {si!r} does not exist ({len(samplers)} samplers)")
    s = samplers[si]
    interp = s.get("interpolation", "LINEAR")
    if interp not in ("LINEAR", "STEP", "CUBICSPLINE"):
        doc.fail(f"{where}: interpolation {interp!r}; accepted are LINEAR, STEP, CUBICSPLINE")
    t = doc.floats(s.get("input", -1), f"{where}.input", (1,))[:, 0]
    v = doc.floats(s.get("output", -1), f"{where}.output", ncomp or (1, 2, 3, 4))
    K = t.shape[0]
    if K == 0:
        doc.fail(f"{where}: no keys")
    if np.any(np.diff(t) < 0):
        doc.fail(f"{where}: key times are not increasing")
    if np.any(t < 0):
        doc.fail(f"{where}: negative key time {float(t.min())}")
    per = 3 if interp == "CUBICSPLINE" else 1
    if v.shape[0] % (K * per):
        doc.fail(f"{where}: {v.shape[0]} output values do not match {K} keys ({interp})")
    width = v.shape[0] // (K * per)  # >1 for morph weights
    v = v.reshape(K, per, width * v.shape[1]) if per == 3 else v.reshape(K, width * v.shape[1])
    # duplicate key times: keep the last key of each run (Channel needs strictly increasing)
    keep = np.ones(K, bool)
    keep[:-1] = np.diff(t) > 0
    if not keep.all():
        t, v = t[keep], v[keep]
    return t, v, interp


def _sample_channel(t, v, interp, times):
    """Sample (non-rotation) values at times (N,) -> (N, C) via sim.clip.Channel."""
    ch = Channel(joint=0, path="weights", times=t, values=v, interpolation=interp)
    return ch.sample(np.asarray(times, np.float64))
