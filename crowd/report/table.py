"""``crowd report`` tables beside the page: ``table.md`` and ``table.csv``, one row per scene and setting.

The figures of the page's per-scene table, for reading in a terminal, a diff or a spreadsheet: frame time (p50,
p95, p99, max over every frame; the first frame, warm-up, named apart), the timed runs behind them and the spread
of their medians (a single run has none: the table says so), what was drawn, and the image error against the
true reference (:mod:`crowd.reference`) and against aliased full detail.
"""
from __future__ import annotations

import csv
import io
import math

#: columns of table.csv (table.md shows the same, formatted)
COLUMNS = ("scene", "setting", "size", "aliased_full_detail", "runs", "p50_ms", "p95_ms", "p99_ms", "max_ms",
           "first_frame_ms", "spread_of_run_medians_ms", "triangles", "points", "instances", "psnr_db", "ssim",
           "flip", "flicker", "psnr_vs_aliased_db")


def rows(data: dict) -> list:
    """One dict per scene and setting of report.json's ``data`` (keys :data:`COLUMNS`; None where absent;
    an image error of identical images is ``inf``)."""
    def db(acc):
        p = acc.get("psnr")
        return math.inf if p is None and acc.get("identical") else p

    out = []
    for sc in data["scenes"]:
        for s in sc["settings"]:
            a, al, fm = s["accuracy"], s.get("accuracy_aliased") or {}, s["frame_ms"]
            meds = s.get("repeat_medians_ms") or []

            out.append({"scene": sc["name"], "setting": s["label"], "size": f"{s['size'][0]}x{s['size'][1]}",
                        "aliased_full_detail": bool(s.get("aliased_full_detail")), "runs": len(meds) or 1,
                        "p50_ms": fm["p50"], "p95_ms": fm["p95"], "p99_ms": fm["p99"], "max_ms": fm["max"],
                        "first_frame_ms": s.get("first_frame_ms"),
                        "spread_of_run_medians_ms": (max(meds) - min(meds)) if len(meds) > 1 else None,
                        "triangles": s["triangles"], "points": s["points"], "instances": s.get("instances"),
                        "psnr_db": db(a), "ssim": a.get("ssim"), "flip": a.get("flip"), "flicker": a.get("flicker"),
                        "psnr_vs_aliased_db": db(al)})
    return out


def csv_text(data: dict) -> str:
    """table.csv: :data:`COLUMNS`, numbers as Python writes them (``inf`` for identical images, empty for none)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in rows(data):
        w.writerow({k: ("" if v is None else v) for k, v in r.items()})
    return buf.getvalue()


def _f(x, fmt: str) -> str:
    if x is None:
        return "–"
    if isinstance(x, float) and math.isinf(x):
        return "∞ (identical)"
    return fmt.format(x)


def markdown(data: dict) -> str:
    """table.md: the rows, and what the columns are measured against."""
    ref = data.get("reference") or {}
    k = ref.get("k")
    lines = ["# crowd report", "",
             f"Image error against the true reference: full detail with {k} x {k} samples per pixel "
             f"({ref.get('filter')}); aliased full detail (one sample per pixel) is a setting like any other. "
             "Frame times are medians and percentiles over every frame of the setting's first timed run, the first "
             "frame (warm-up: uploads, first compilations) included and also shown apart; 'runs' is the number of "
             "timed runs, and the spread of their medians is given when there is more than one (one run states no "
             "spread: `--repeat N`).", "",
             "| scene | setting | size | runs | p50 ms | p95 ms | p99 ms | max ms | first frame ms | spread of run "
             "medians ms | triangles | points | PSNR dB | SSIM | FLIP | flicker | PSNR dB vs aliased |",
             "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
             "---: | ---: |"]
    for r in rows(data):
        spread = _f(r["spread_of_run_medians_ms"], "{:.2f}") if r["runs"] > 1 else "one run"
        lines.append(f"| {r['scene']} | {r['setting']} | {r['size']} | {r['runs']} | {r['p50_ms']:.2f} | "
                     f"{r['p95_ms']:.2f} | {r['p99_ms']:.2f} | {r['max_ms']:.2f} | {_f(r['first_frame_ms'], '{:.2f}')} | "
                     f"{spread} | {r['triangles']:,.0f} | {r['points']:,.0f} | {_f(r['psnr_db'], '{:.2f}')} | "
                     f"{_f(r['ssim'], '{:.4f}')} | {_f(r['flip'], '{:.4f}')} | {_f(r['flicker'], '{:.5f}')} | "
                     f"{_f(r['psnr_vs_aliased_db'], '{:.2f}')} |")
    return "\n".join(lines) + "\n"
