"""``crowd report`` page: the self-contained index.html (tables, plots, sample frames) of report.json's data.

Only relative links to ``plots/`` and ``samples/``; no scripts, no external resources.
"""
from __future__ import annotations

import html
import math

from crowd.report.runs import STAGE_COLUMNS
from crowd.report.settings import _fmt_value

_CSS = """body{font-family:sans-serif;margin:1.5em;max-width:1200px;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 7px;font-size:13px}
th{background:#eee}td.n{text-align:right;font-variant-numeric:tabular-nums}img{max-width:100%}
.samples img{width:260px;image-rendering:pixelated}h2{border-bottom:2px solid #888;margin-top:2em}
tr.regressed td,b.regressed{background:#fcc;color:#900}b.ok{color:#060}"""


def _num(x, fmt="{:.2f}") -> str:
    if x is None:
        return "–"
    if isinstance(x, float) and math.isinf(x):
        return "∞ (identical)"
    return fmt.format(x)


def _auto_section(sc: dict, autos: list) -> str:
    """Mode auto: the plans it drew, its switches, how well it predicted, its fitted per-unit costs (crowd.explain)
    and the plot of predicted against measured frame time."""
    e = html.escape
    out = ["<h3>Mode auto: what it drew and why</h3><p>Per frame auto prices a mixed plan and one plan per "
           "representation with per-unit costs fitted online to the frames it draws (the calibration as prior), "
           "keeps its plan until another is predicted better beyond the measured noise for several frames, and "
           "tries a plan it is unsure about for a few frames now and then (<code>crowd run --explain-lod</code> "
           "prints the same per frame).</p>",
           "<table><tr><th>setting</th><th>plans drawn (share of frames)</th><th>switches</th><th>states</th>"
           "<th>median |predicted − measured| / measured</th><th>fitted per-unit costs (calibration)</th></tr>"]
    for s in autos:
        a = s["auto"]
        m = a.get("model") or {}
        c, p = m.get("coefficients") or {}, m.get("prior") or {}
        costs = ", ".join(f"{k} {c[k]:.3g} ({p[k]:.3g})" if p.get(k) is not None else f"{k} {c[k]:.3g}"
                          for k in ("frame", "triangles", "points", "instances", "point_instances", "clusters")
                          if k in c)
        out.append(f"<tr><td>{e(s['label'])}</td><td>"
                   + e(", ".join(f"{k} {100 * v:.0f} %" for k, v in sorted(a["plans"].items(), key=lambda kv: -kv[1])))
                   + f"</td><td class='n'>{a['switches']}</td><td>"
                   + e(", ".join(f"{k} {v}" for k, v in a["states"].items())) + "</td><td class='n'>"
                   + (f"{100 * a['pred_err']:.0f} %" if a.get("pred_err") is not None else "–")
                   + f"</td><td>{e(costs)} s per unit</td></tr>")
    out.append("</table>")
    for s in autos:
        img = (sc["plots"].get("auto") or {}).get(s["slug"])
        if img:
            out.append(f"<img src='{e(img)}' alt='auto predicted against measured {e(s['label'])}'>")
    return "\n".join(out)


def render_html(data: dict) -> str:
    """The report page: only relative links to ``plots/`` and ``samples/``; no scripts, no external resources."""
    e = html.escape
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8"><title>crowd report</title>',
           f"<style>{_CSS}</style></head><body>", "<h1>crowd report</h1>"]
    if data["sweeps"]:
        out.append("<p>Sweeps: " + "; ".join(e(f"{k} = {', '.join(_fmt_value(x) for x in v)}")
                                               for k, v in data["sweeps"]) + "</p>")
    ref = data.get("reference") or {}
    k = ref.get("k")
    out.append("<p>Accuracy is measured against the true reference at the same simulated time and camera: full "
               f"detail (LOD mode none, exact animation times) drawn with {k} x {k} samples per pixel and filtered "
               f"down ({e(str(ref.get('filter')))}); the aliased full-detail frame (one sample per pixel) is a "
               "setting like any other, and each setting's PSNR against it is shown beside. Full detail itself is "
               "not at ∞ against the reference: one sample per pixel aliases (edges, and triangles or whole "
               "characters smaller than a pixel), which the reference's samples average. "
               "PSNR (of the mean MSE over the sampled frames), mean SSIM (Wang et al. 2004), mean FLIP "
               f"(Andersson et al. 2020){'' if data['flip'] else ' — not available: flip-evaluator is not installed'}"
               ". Frame time is the wall-clock sum of the stages simulate, select, upload, draw and finish "
               "(the PNG writes of sampled frames are left out); the first frame is included.</p>")
    hosts = data.get("hosts") or {}
    if any(hosts.values()):
        out.append(f"<p>Ran on {e(str(data['cluster']))} ("
                   + ", ".join(e(f"{h}: {n} worker(s)") for h, n in hosts.items() if n)
                   + "). Timed runs ran one at a time per host with nothing else of the report running; the "
                   "reference runs and the image error ran afterwards, in parallel.</p>")
    elif data.get("cluster"):
        out.append(f"<p>Ran in {e(str(data['cluster']))}, one run after the other.</p>")
    cmp_ = data.get("compare")
    if cmp_ is not None:
        n = cmp_["regressions"]
        out.append(f"<h2>Comparison with baseline</h2><p>Baseline: {e(str(cmp_['baseline']))}. "
                   f"{data.get('repeat', 1)} timed run(s) per setting; regression when {e(cmp_['rule'])}. "
                   f"<b class='{'regressed' if n else 'ok'}'>{n} regression(s)</b>.</p>")
        out.append("<table><tr><th>scene</th><th>setting</th><th>baseline ms</th><th>current ms</th><th>ratio</th>"
                   "<th>spread base / current</th><th>threshold</th><th>verdict</th></tr>")
        for r in cmp_["rows"]:
            out.append(f"<tr class='{'regressed' if r['regression'] else 'cmp'}'><td>{e(r['scene'])}</td>"
                       f"<td>{e(r['label'])}</td><td class='n'>{r['baseline_ms']:.3f}</td>"
                       f"<td class='n'>{r['current_ms']:.3f}</td><td class='n'>{r['ratio']:.3f}</td>"
                       f"<td class='n'>{r['spread_baseline']:.1%} / {r['spread_current']:.1%}</td>"
                       f"<td class='n'>+{r['threshold']:.1%}</td>"
                       f"<td>{'REGRESSION' if r['regression'] else 'ok'}</td></tr>")
        out.append("</table>")
    for sc in data["scenes"]:
        out.append(f"<h2>{e(sc['name'])}</h2><p>{e(sc['file'])}: {sc['frames']} frames, every "
                   f"{sc['sample_every']}-th frame compared.</p>")
        for r in sc.get("reference") or ():
            spf = r.get("seconds_per_frame")
            out.append(f"<p>Reference at {r['size'][0]}x{r['size'][1]}, K = {r['k']}: {r['frames']} frames, "
                       f"{r['drawn']} drawn now, {r['cached']} from the cache"
                       + (f"; {spf:.2f} s per frame to draw" if spf is not None else "")
                       + (f" in {r['tiles']} tile(s) of {r['tile_pixels'][0]}x{r['tile_pixels'][1]} pixels"
                          if r.get("tiles") else "") + ".</p>")
        out.append("<table><tr><th>setting</th><th>size</th><th>p50 ms</th><th>p95 ms</th><th>p99 ms</th>"
                   "<th>max ms</th><th>first frame ms (warm-up, in the figures before)</th><th>runs</th>"
                   "<th>mean ms: " + " / ".join(STAGE_COLUMNS) + "</th><th>GPU p50 ms</th>"
                   "<th>triangles/frame</th><th>points/frame</th><th>PSNR dB</th><th>SSIM</th><th>FLIP</th>"
                   "<th>PSNR dB vs aliased full detail</th>"
                   "<th>flicker</th>"
                   "<th>Pareto</th></tr>")
        for s in sc["settings"]:
            fm, a = s["frame_ms"], s["accuracy"]
            stages = " / ".join(f"{s['stage_ms'].get(k, 0.0):.2f}" for k in STAGE_COLUMNS)
            out.append(f"<tr class='setting'><td>{e(s['label'])}</td><td>{s['size'][0]}x{s['size'][1]}</td>"
                       + "".join(f"<td class='n'>{fm[q]:.2f}</td>" for q in ("p50", "p95", "p99", "max"))
                       + f"<td class='n'>{_num(s.get('first_frame_ms'))}</td>"
                       + f"<td class='n'>{len(s.get('repeat_medians_ms') or []) or 1}</td>"
                       + f"<td class='n'>{stages}</td><td class='n'>{_num(s['gpu_ms'])}</td>"
                       f"<td class='n'>{s['triangles']:,.0f}</td><td class='n'>{s['points']:,.0f}</td>"
                       f"<td class='n'>{_num(a['psnr'])}</td><td class='n'>{_num(a['ssim'], '{:.4f}')}</td>"
                       f"<td class='n'>{_num(a['flip'], '{:.4f}')}</td>"
                       f"<td class='n'>{_num((s.get('accuracy_aliased') or {}).get('psnr'))}</td>"
                       f"<td class='n'>{_num(a.get('flicker'), '{:.5f}')}</td>"
                       f"<td>{'front' if s['slug'] in sc['pareto_front'] else ''}</td></tr>")
        out.append("</table>")
        p = sc["plots"]
        out.append(f"<h3>Frame time along the path</h3><img src='{e(p['frame_time'])}' alt='frame time'>")
        for s in sc["settings"]:
            out.append(f"<img src='{e(p['stages'][s['slug']])}' alt='stages {e(s['label'])}'>")
        out.append(f"<h3>Primitives drawn</h3><img src='{e(p['primitives'])}' alt='primitives'>")
        out.append("<h3>LOD flicker</h3><p>Per sampled frame t: mean |(F<sub>t+1</sub> − F<sub>t</sub>) − "
                   "(R<sub>t+1</sub> − R<sub>t</sub>)| over pixels and channels in [0, 1], F the setting's frames, "
                   "R the reference's: the temporal change the reference does not have (LOD popping, "
                   "shimmer); 0 when the setting changes exactly as the reference does.</p>"
                   f"<img src='{e(p['flicker'])}' alt='flicker'>")
        out.append(f"<h3>Accuracy against time ({e(sc['pareto_error'])})</h3>"
                   f"<img src='{e(p['pareto'])}' alt='pareto'>")
        for key, img in (p.get("sweeps") or {}).items():  # a numeric swept setting: error and time against it
            out.append(f"<h3>Accuracy and time against {e(key)}</h3><img src='{e(img)}' alt='sweep {e(key)}'>")
        autos = [s for s in sc["settings"] if s.get("auto")]
        if autos:
            out.append(_auto_section(sc, autos))
        if sc.get("pedestrian"):
            from crowd.report.pedestrian import html_section

            out.append(html_section(sc))
        if sc.get("population"):
            from crowd.report.population import html_section as population_section

            out.append(population_section(sc))
        clips = [s for s in sc["settings"] if s.get("clip")]
        if clips:  # a short clip per setting (crowd.video.REPORT_CLIP), beside its sample frames
            out.append("<h3>Clips</h3><table class='samples'><tr><th>setting</th><th>clip</th></tr>")
            out.extend(f"<tr><td>{e(s['label'])}</td><td><video src='{e(s['clip'])}' controls muted loop "
                       f"preload='metadata' width='480'></video></td></tr>" for s in clips)
            out.append("</table>")
        out.append("<h3>Sample frames</h3><table class='samples'><tr><th>setting</th><th>frame</th><th>frame</th>"
                   "<th>reference</th><th>error map</th><th>PSNR / SSIM / FLIP</th></tr>")
        for s in sc["settings"]:
            for m in s["samples"]:
                out.append(f"<tr><td>{e(s['label'])}</td><td>{m['frame']}</td>"
                           f"<td><img src='{e(m['image'])}' alt='frame'></td>"
                           f"<td><img src='{e(m['reference'])}' alt='reference'></td>"
                           f"<td><img src='{e(m['error'])}' alt='error map'></td>"
                           f"<td>{_num(m['psnr'])} dB<br>{_num(m['ssim'], '{:.4f}')}<br>"
                           f"{_num(m['flip'], '{:.4f}')}</td></tr>")
        out.append("</table>")
    mach = data.get("machine") or {}
    out.append("<h2>Machine</h2><table>")
    for k in ("cpu", "cores", "platform", "gl_renderer", "gl_version"):
        out.append(f"<tr><th>{e(k)}</th><td>{e(str(mach.get(k)))}</td></tr>")
    pk = mach.get("packages") or {}
    out.append("<tr><th>packages</th><td>" + e(", ".join(f"{k} {v}" for k, v in pk.items())) + "</td></tr>")
    out.append("</table></body></html>")
    return "\n".join(out) + "\n"
