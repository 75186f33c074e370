"""``crowd report`` plots (matplotlib, Agg): frame time, per-stage breakdown, primitives drawn, flicker, accuracy
against time.

Figures are written as ``plots/*.png`` of the report directory; :func:`_plots` records their relative paths
(and the Pareto front) in the scene's entry of report.json.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from crowd.report.metrics import pareto_front
from crowd.report.runs import STAGE_COLUMNS, frame_seconds


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _error_axis(settings: list) -> tuple:
    """(name, values) of the error shown on the Pareto plot: mean FLIP, else 1 - SSIM."""
    if all(s["accuracy"]["flip"] is not None for s in settings):
        return "mean FLIP error", [s["accuracy"]["flip"] for s in settings]
    return "1 - SSIM", [1.0 - (s["accuracy"]["ssim"] if s["accuracy"]["ssim"] is not None else 0.0)
                        for s in settings]


def _plots(tmp: Path, entry: dict, runs: list) -> None:
    plt = _plt()
    slug = entry["slug"]
    plots = entry["plots"] = {}

    fig, ax = plt.subplots(figsize=(8, 3.5), dpi=96)
    for run in runs:
        c = run.columns
        ax.plot(c["frame"], frame_seconds(c) * 1e3, label=run.setting.label, lw=1.2)
    ax.set_xlabel("frame (along the camera path)")
    ax.set_ylabel("frame time, ms")
    ax.set_title(f"{entry['name']}: frame time")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    plots["frame_time"] = _save(fig, tmp, f"plots/{slug}_frame_time.png")

    plots["stages"] = {}
    for run in runs:
        c = run.columns
        fig, ax = plt.subplots(figsize=(8, 3), dpi=96)
        ys = [np.nan_to_num(c[k]) * 1e3 for k in STAGE_COLUMNS if k in c]
        ax.stackplot(c["frame"], *ys, labels=[k for k in STAGE_COLUMNS if k in c], alpha=0.85)
        ax.set_xlabel("frame")
        ax.set_ylabel("ms")
        ax.set_title(f"{entry['name']} [{run.setting.label}]: per-stage breakdown", fontsize=9)
        ax.legend(fontsize=7, loc="upper right", ncol=5)
        ax.grid(alpha=0.3)
        plots["stages"][run.setting.slug] = _save(fig, tmp, f"plots/{slug}_{run.setting.slug}_stages.png")

    fig, ax = plt.subplots(figsize=(8, 3.5), dpi=96)
    for run in runs:
        c = run.columns
        prims = np.nan_to_num(c.get("triangles", 0)) + np.nan_to_num(c.get("points", 0))
        ax.plot(c["frame"], prims, label=run.setting.label, lw=1.2)
    ax.set_xlabel("frame")
    ax.set_ylabel("primitives drawn (triangles + points)")
    ax.set_title(f"{entry['name']}: primitives drawn")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    plots["primitives"] = _save(fig, tmp, f"plots/{slug}_primitives.png")

    fig, ax = plt.subplots(figsize=(8, 3.5), dpi=96)
    for s in entry["settings"]:
        pts = [(m["frame"], m["flicker"]) for m in s["samples"] if m["flicker"] is not None]
        if pts:
            ax.plot(*zip(*pts), marker="o", label=s["label"], lw=1.2)
    ax.set_xlabel("frame t (pair t, t+1)")
    ax.set_ylabel("mean |ΔF − ΔR|")
    ax.set_title(f"{entry['name']}: LOD flicker (temporal change the NoLOD reference does not have)")
    ax.grid(alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=7)
    plots["flicker"] = _save(fig, tmp, f"plots/{slug}_flicker.png")

    plots["auto"] = {}
    for run in runs:  # mode auto: its predicted against its measured rendering time (crowd.explain)
        c = run.columns
        if "predicted_ms" in c and "measured_render_ms" in c and np.isfinite(c["predicted_ms"]).any():
            plots["auto"][run.setting.slug] = _auto_plot(plt, tmp, entry, run, c)

    sets = entry["settings"]
    name, errs = _error_axis(sets)
    times = [s["frame_ms"]["p50"] for s in sets]
    fig, ax = plt.subplots(figsize=(6, 4.5), dpi=96)
    ax.scatter(times, errs, zorder=3)
    for i, (t, e, s) in enumerate(zip(times, errs, sets)):  # staggered: settings of equal cost stay readable
        ax.annotate(s["label"], (t, e), fontsize=7, xytext=(4, 4 + 9 * (i % 3)), textcoords="offset points")
    front = pareto_front(times, errs)
    ax.plot([times[i] for i in front], [errs[i] for i in front], "r--", lw=1, marker="o", ms=11, mfc="none",
            label="Pareto front", zorder=2)
    log_x = min(times) > 0 and max(times) > 20 * min(times)  # NoLOD of a big scene is 10-100x the LOD modes
    if log_x:
        ax.set_xscale("log")
    ax.set_xlabel("median frame time, ms" + (" (log scale)" if log_x else ""))
    ax.set_ylabel(name + " vs reference")
    ax.set_title(f"{entry['name']}: accuracy against time")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    plots["pareto"] = _save(fig, tmp, f"plots/{slug}_pareto.png")
    entry["pareto_front"] = [sets[i]["slug"] for i in front]
    entry["pareto_error"] = name
    plots["sweeps"] = _sweep_curves(plt, tmp, entry)


#: swept keys with no curve of their own (the mode is a category; sizes are pairs)
_NO_CURVE = ("lod.mode", "render.size")


def _sweep_curves(plt, tmp: Path, entry: dict) -> dict:
    """key -> plot of the accuracy (PSNR against the reference, crowd.reference) and the median frame time against each
    swept setting with numeric values (e.g. ``lod.pose_rate``: the pose quantisation's error as a curve against
    its rate); a setting's non-numeric value (``pose_rate = "key"``) is a dashed level of its own."""
    out = {}
    sets = entry["settings"]
    keys = sorted({k for s in sets for k in s.get("values", {}) if k not in _NO_CURVE})
    for key in keys:
        num = [(float(s["values"][key]), s) for s in sets
               if isinstance(s["values"].get(key), (int, float)) and not isinstance(s["values"].get(key), bool)]
        other = [s for s in sets if key in s["values"] and isinstance(s["values"][key], str)]
        if len(num) < 2:
            continue
        num.sort(key=lambda vs: vs[0])
        fig, ax = plt.subplots(figsize=(7, 3.8), dpi=96)
        cap = 99.0  # an identical setting (PSNR inf) and the reference itself (no PSNR) are drawn at the top
        ps = [min(cap, s["accuracy"]["psnr"]) if s["accuracy"]["psnr"] is not None else cap for _, s in num]
        ax.plot([v for v, _ in num], ps, marker="o", lw=1.4,
                label="PSNR vs reference (dB; identical at the top)")
        for s in other:
            if s["accuracy"]["psnr"] is not None:
                ax.axhline(min(cap, s["accuracy"]["psnr"]), ls="--", lw=1, color="grey")
                ax.annotate(f"{key.split('.')[-1]} = {s['values'][key]}", (num[0][0], min(cap, s["accuracy"]["psnr"])),
                            fontsize=7, xytext=(2, 3), textcoords="offset points")
        xs = [v for v, _ in num]
        if min(xs) > 0 and max(xs) > 20 * min(xs):
            ax.set_xscale("log")
        ax.set_xlabel(key)
        ax.set_ylabel("PSNR, dB")
        tx = ax.twinx()
        tx.plot(xs, [s["frame_ms"]["p50"] for _, s in num], color="tab:orange", marker="s", lw=1, label="frame ms")
        tx.set_ylabel("median frame time, ms", color="tab:orange")
        ax.set_title(f"{entry['name']}: accuracy and time against {key}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
        out[key] = _save(fig, tmp, f"plots/{entry['slug']}_sweep_{key.replace('.', '_')}.png")
    return out


def _auto_plot(plt, tmp: Path, entry: dict, run, c: dict) -> str:
    """Mode auto's predicted against measured rendering time: along the path, and one against the other."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.5), dpi=96, gridspec_kw={"width_ratios": [2, 1]})
    pred, meas = c["predicted_ms"], c["measured_render_ms"]
    a1.plot(c["frame"], meas, label="measured (upload + draw + finish)", lw=1.2)
    a1.plot(c["frame"], pred, label="predicted by the online fit", lw=1.2, ls="--")
    a1.set_xlabel("frame")
    a1.set_ylabel("ms")
    a1.grid(alpha=0.3)
    a1.legend(fontsize=7)
    ok = np.isfinite(pred) & np.isfinite(meas)
    a2.scatter(meas[ok], pred[ok], s=8, c=c["frame"][ok], cmap="viridis")
    hi = float(max(np.max(meas[ok], initial=1.0), np.max(pred[ok], initial=1.0))) * 1.05
    a2.plot([0, hi], [0, hi], "k:", lw=1)
    a2.set_xlim(0, hi)
    a2.set_ylim(0, hi)
    a2.set_xlabel("measured ms")
    a2.set_ylabel("predicted ms")
    a2.grid(alpha=0.3)
    fig.suptitle(f"{entry['name']} [{run.setting.label}]: mode auto, predicted against measured frame time",
                 fontsize=9)
    return _save(fig, tmp, f"plots/{entry['slug']}_{run.setting.slug}_auto.png")


def _save(fig, tmp: Path, rel: str) -> str:
    import io

    from crowd.output import write_atomic

    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png")
    _plt().close(fig)
    write_atomic(tmp / rel, buf.getvalue())
    return rel
