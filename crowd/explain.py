"""``crowd run --explain-lod``: why mode auto drew what it drew, frame by frame (issue 26, item 4).

Per frame: the frame plan drawn and the chooser's state (:mod:`lod.auto.control`: steady, pending behind the
hysteresis, exploring, in a faded switch), what each instance group (a character's clip or segment) was
drawn with, the predicted rendering time (with its standard deviation) against the measured one, every
plan's prediction and the gain another plan would need, and the online fit's current per-unit costs beside
the calibration's (:mod:`lod.auto.online`).

Written as ``explain_lod.jsonl`` (one JSON object per frame) in the run's output directory; the text of each
frame (:func:`format_frame`) is what the command prints.
"""
from __future__ import annotations

import json
import math

#: file of the per-frame records in a run's output directory
EXPLAIN_FILE = "explain_lod.jsonl"
#: the per-unit costs printed (name, unit, scale to that unit)
_UNITS = (("frame", "ms/frame", 1e3), ("triangles", "ns/triangle", 1e9), ("points", "ns/point", 1e9),
          ("batches", "us/batch", 1e6), ("instances", "us/instance", 1e6), ("clusters", "ns/cluster", 1e9),
          ("splat_pixels", "ns/pixel", 1e9), ("splat_area", "ns/pixel/s^2", 1e9),
          ("point_instances", "us/point instance", 1e6), ("cluster_frames", "ms/cluster frame", 1e3),
          ("raster_triangles", "ns/raster triangle", 1e9), ("poses", "us/pose", 1e6),
          ("posed_vertices", "ns/posed vertex", 1e9), ("placed_points", "ns/placed point", 1e9),
          ("props", "ns/prop triangle", 1e9))


def record(frame: int, auto: dict, measured_render_s: float | None, warm_up: bool = False) -> dict:
    """The JSON record of one frame from its ``DrawList.stats["auto"]`` and the measured rendering seconds;
    ``warm_up``: the draw made GL objects (``lod.drawlist.DrawList.warm_up``), so the fit left the frame out."""
    keys = ("plan", "state", "incumbent", "fade_from", "fade_t", "threshold", "bound", "predicted_ms",
            "predicted_sd_ms", "plans_ms", "plans_sd_ms", "groups", "model", "select_ms")
    out = {"frame": int(frame)}
    out.update({k: auto.get(k) for k in keys if k in auto})
    out["measured_ms"] = None if measured_render_s is None else 1e3 * float(measured_render_s)
    if warm_up:
        out["warm_up"] = True
    return _finite(out)


def _finite(x):
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _ms(v) -> str:
    return "-" if v is None else f"{v:.1f}"


def format_frame(rec: dict) -> str:
    """Lines describing one frame's record (:func:`record`)."""
    st = rec.get("state") or "-"
    head = f"frame {rec['frame']}: plan {rec.get('plan')} [{st}"
    if rec.get("fade_from"):
        head += f", fading from {rec['fade_from']} t={rec.get('fade_t', 0):.2f}"
    if rec.get("incumbent") and rec.get("incumbent") != rec.get("plan"):
        head += f", incumbent {rec['incumbent']}"
    head += "]"
    pred, sd, meas = rec.get("predicted_ms"), rec.get("predicted_sd_ms"), rec.get("measured_ms")
    if pred is not None and sd is not None and sd > pred:  # the prior's scale alone: nothing measured yet
        head += f"  predicted {_ms(pred)} ms (the prior's guess: no frame fitted yet), measured {_ms(meas)} ms"
    else:
        head += f"  predicted {_ms(pred)} ± {_ms(sd)} ms, measured {_ms(meas)} ms"
    if pred and meas:
        head += f" ({100 * (meas - pred) / pred:+.0f} %)"
    if rec.get("warm_up"):
        head += " (warm-up: GL objects made, not fitted)"
    lines = [head]
    plans = rec.get("plans_ms") or {}
    sds = rec.get("plans_sd_ms") or {}
    if plans:
        thr = rec.get("threshold")
        lines.append("  plans (ms, ± sd of the difference to the incumbent): "
                     + ", ".join(f"{n} {_ms(v)}" + (f" ± {_ms(sds.get(n))}" if sds.get(n) else "")
                                 for n, v in sorted(plans.items(), key=lambda kv: kv[1] or 0.0))
                     + (f"; a switch needs a gain > {100 * thr:.1f} %" if thr is not None else ""))
    for g, counts in sorted((rec.get("groups") or {}).items()):
        lines.append(f"  {g}: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items(), key=lambda kv: -kv[1])))
    m = rec.get("model")
    if m:
        c, p = m.get("coefficients") or {}, m.get("prior") or {}
        used = [(n, u, f) for n, u, f in _UNITS if n in c]
        lines.append(f"  per-unit costs (fit of {m.get('frames', 0)} frames, noise {100 * m.get('noise', 0):.0f} %; "
                     "calibration in brackets): "
                     + ", ".join(f"{c[n] * f:.3g} {u}" + (f" [{p[n] * f:.3g}]" if p.get(n) is not None else "")
                                 for n, u, f in used))
    return "\n".join(lines)


class ExplainWriter:
    """Appends one record per frame to ``path`` (inside a run's atomic output directory) and returns its text."""

    def __init__(self, path):
        self.path = path
        self._f = open(path, "w", encoding="utf-8")

    def frame(self, frame: int, auto: dict, measured_render_s: float | None, warm_up: bool = False) -> str:
        rec = record(frame, auto, measured_render_s, warm_up)
        self._f.write(json.dumps(rec, separators=(",", ":")) + "\n")
        return format_frame(rec)

    def close(self) -> None:
        self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read(path) -> list:
    """The records of an ``explain_lod.jsonl`` file (bad lines skipped)."""
    out = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            try:
                out.append(json.loads(line))
            except ValueError:
                continue
    return out


def summarize(records: list) -> dict:
    """A run's explanation in a few figures (the report's section on mode auto): share of frames per plan,
    frames per chooser state, switches of the incumbent, median |predicted - measured| / measured (warm-up
    frames left out, as the fit leaves them out), and the
    last per-unit costs of the fit beside the calibration's."""
    if not records:
        return {}
    n = len(records)
    plans, states = {}, {}
    for r in records:
        plans[r.get("plan")] = plans.get(r.get("plan"), 0) + 1
        states[r.get("state")] = states.get(r.get("state"), 0) + 1
    inc = [r.get("incumbent") for r in records]
    err = sorted(abs(r["measured_ms"] - r["predicted_ms"]) / r["measured_ms"] for r in records
                 if r.get("measured_ms") and r.get("predicted_ms") is not None and not r.get("warm_up"))
    model = next((r["model"] for r in reversed(records) if r.get("model")), None)
    return {"frames": n, "plans": {k: v / n for k, v in plans.items()}, "states": states,
            "switches": sum(1 for a, b in zip(inc, inc[1:]) if a != b),
            "pred_err": err[len(err) // 2] if err else None, "model": model}


__all__ = ["EXPLAIN_FILE", "ExplainWriter", "format_frame", "read", "record", "summarize"]
