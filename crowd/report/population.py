"""``crowd report`` section of a scene whose agents leave and enter (effect ``journeys``, ``[[sources]]``, exits).

From the first run's frames.csv (``agents``, ``entered``, ``exited``, ``left`` per frame; ``crowd.population``)
and summary.json (``journeys``: per source and exit): the agents alive, the cumulative entered and exited agents
against simulated time beside what the sources' rates promise, and a table per source (rate, process, entered,
expected by the end, deviation) and per exit (agents out). The simulation does not depend on the LOD setting, so
one run stands for all.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def expected_arrivals(sources_cfg: list, seed: int, t: float) -> list:
    """Per source, the arrivals its rate promises by simulated time ``t`` (``total`` applied)."""
    from sim.journeys.sources import Source

    out = []
    for i, cfg in enumerate(sources_cfg):
        e = Source(cfg, i, seed).expected(t)
        out.append(float(min(e, cfg["total"])) if cfg.get("total") is not None else float(e))
    return out


def scene_population(tmp: Path, slug: str, scene_name: str, run, scene) -> dict | None:
    """The ``population`` entry of a scene in report.json (None when its count never changes), with its plot."""
    j = run.summary.get("journeys")
    if not j:
        return None
    cols = run.columns
    t = cols.get("sim_time", np.zeros(0))
    cfg = next((e.params for e in scene.effects if e.name == "journeys"), {})
    sources = cfg.get("sources", [])
    t_end = float(t[-1]) if t.size else 0.0
    expect = expected_arrivals(sources, scene.seed, t_end)
    rows = []
    for s, e in zip(sources, expect):
        got = j["sources"][s["name"]]
        rows.append({"name": s["name"], "rate": s["rate"], "process": s.get("process", "uniform"),
                     "entered": got["entered"], "waiting": got["waiting"], "expected": e,
                     "deviation": (got["entered"] / e - 1.0) if e > 0 else None})
    entry = {"agents_start": int(run.summary.get("agents", 0)), "agents_final": int(run.summary.get("agents_final", 0)),
             "agents_max": int(np.nanmax(cols["agents"])) if cols.get("agents") is not None and t.size else 0,
             "entered": j["entered"], "exited": j["exited"], "sources": rows, "exits": dict(j["exits"]),
             "plot": _plot(tmp, slug, scene_name, t, cols, sources, scene.seed)}
    return entry


def _plot(tmp: Path, slug: str, scene_name: str, t, cols, sources, seed) -> str:
    from crowd.report.plots import _plt, _save

    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 3.2), dpi=96)
    ax.plot(t, cols["agents"], label="alive")
    ax.plot(t, np.cumsum(cols["entered"]), label="entered (cumulative)")
    ax.plot(t, np.cumsum(cols["exited"]), label="reached an exit (cumulative)")
    if sources and t.size:
        promised = np.array([sum(expected_arrivals(sources, seed, float(x))) for x in t])
        ax.plot(t, promised, "k--", lw=1, label="sources' rates")
    ax.set_xlabel("simulated time, s")
    ax.set_ylabel("agents")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{scene_name}: agents entering and leaving", fontsize=9)
    return _save(fig, tmp, f"plots/{slug}_population.png")


def html_section(entry: dict) -> str:
    """The page's section of a scene's ``population`` entry."""
    import html

    e = html.escape
    p = entry.get("population")
    if not p:
        return ""
    f = lambda x, fmt="{:.2f}": "–" if x is None else fmt.format(x)  # noqa: E731
    out = ["<h3>Agents entering and leaving</h3>",
           f"<p>{p['agents_start']} agents at the start, {p['agents_max']} at most, {p['agents_final']} at the end; "
           f"{p['entered']} entered, {p['exited']} reached an exit.</p>",
           "<table class='population'><tr><th>source</th><th>rate 1/s</th><th>process</th><th>entered</th>"
           "<th>expected</th><th>deviation</th><th>waiting for room</th></tr>"]
    for r in p["sources"]:
        dev = "–" if r["deviation"] is None else f"{100.0 * r['deviation']:+.1f} %"
        out.append(f"<tr><td>{e(r['name'])}</td><td class='n'>{f(r['rate'], '{:g}')}</td><td>{e(r['process'])}</td>"
                   f"<td class='n'>{r['entered']}</td><td class='n'>{f(r['expected'], '{:.1f}')}</td>"
                   f"<td class='n'>{dev}</td><td class='n'>{r['waiting']}</td></tr>")
    out.append("</table><table class='population'><tr><th>exit</th><th>agents out</th></tr>")
    out.extend(f"<tr><td>{e(k)}</td><td class='n'>{v}</td></tr>" for k, v in p["exits"].items())
    out.append(f"</table><img src='{e(p['plot'])}' alt='agents entering and leaving'>")
    return "\n".join(out)
