"""``crowd report`` image metrics: the error of each sampled frame against the true reference (crowd.reference), per setting.

Each sampled frame is compared with its reference by PSNR, SSIM and FLIP (:mod:`crowd.image_metrics`), each
consecutive pair by the LOD flicker measure; :func:`metrics_task` is the unit of work sent to a dask worker.
:func:`aggregate` sums a setting up, :func:`pareto_front` picks the settings no other beats in both time and
error.
"""
from __future__ import annotations

import math

import numpy as np


def aggregate(metrics: list) -> dict:
    """Per-setting accuracy over its sampled frames: ``psnr`` of the mean MSE (inf when every frame is
    identical), mean ``ssim``, mean ``flip`` (None without FLIP), ``identical`` (all frames), mean ``flicker``
    (:func:`crowd.image_metrics.flicker` of the frames that have a successor; None when none has)."""
    if not metrics:
        return {"psnr": None, "ssim": None, "flip": None, "identical": None, "samples": 0, "flicker": None}
    m = float(np.mean([x["mse"] for x in metrics]))
    flips = [x["flip"] for x in metrics if x["flip"] is not None]
    return {"psnr": math.inf if m == 0.0 else 10.0 * math.log10(1.0 / m),
            "ssim": float(np.mean([x["ssim"] for x in metrics])),
            "flip": float(np.mean(flips)) if flips else None,
            "identical": all(x["identical"] for x in metrics), "samples": len(metrics),
            "flicker": float(np.mean(fl)) if (fl := [x["flicker"] for x in metrics
                                                     if x.get("flicker") is not None]) else None}


def pareto_front(times, errors) -> list:
    """Indices of the points not dominated (lower time and lower error is better), sorted by time.

    A point is dominated when another has time <= and error <= with one of them strictly smaller.
    """
    idx = sorted(range(len(times)), key=lambda i: (times[i], errors[i]))
    front, best = [], math.inf
    for i in idx:
        if errors[i] < best:
            front.append(i)
            best = errors[i]
    return front


def frame_metrics(img: np.ndarray, ref: np.ndarray, nxt: np.ndarray | None = None,
                  ref_nxt: np.ndarray | None = None) -> dict:
    """Image error of one sampled frame (the unit of work sent to a dask worker).

    Parameters
    ----------
    img, ref : (h, w, 3) uint8, the frame and its reference
    nxt, ref_nxt : (h, w, 3) uint8 or None, the following frame of both (for the flicker measure)

    Returns
    -------
    dict: psnr (inf when identical), ssim, flip (None without flip-evaluator), mse, identical, flicker (None
    without a following frame), error_png ((h, w, 3) uint8 error map).
    """
    from crowd.image_metrics import compare, flicker, mse

    m = compare(img, ref)
    flick = flicker(img, nxt, ref, ref_nxt) if nxt is not None and ref_nxt is not None else None
    return {"psnr": m["psnr"], "ssim": m["ssim"], "flip": m["flip"], "mse": mse(img, ref),
            "identical": m["identical"], "flicker": flick,
            "error_png": (np.clip(m["error_map"], 0, 1) * 255 + 0.5).astype(np.uint8)}


def _png(data: bytes) -> np.ndarray:
    """PNG bytes -> (h, w, 3) uint8."""
    import io

    from crowd.images import read_png

    return read_png(io.BytesIO(data))


def metrics_task(run: dict, ref: dict, frame: int) -> dict:
    """:func:`frame_metrics` of sampled ``frame`` of a run against its reference run (both
    :func:`crowd.report.runs.run_task` results); the pair (frame, frame + 1) feeds the flicker measure when both
    runs wrote the successor."""
    name, nxt = f"frames/frame_{frame:05d}.png", f"frames/frame_{frame + 1:05d}.png"
    a, b = run["files"], ref["files"]
    pair = nxt in a and nxt in b
    return frame_metrics(_png(a[name]), _png(b[name]), _png(a[nxt]) if pair else None,
                         _png(b[nxt]) if pair else None)
