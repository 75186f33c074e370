"""``crowd report`` pedestrian measures (PedPy) of a scene with ``[[measurement]]`` areas and lines.

From a run's ``trajectories.txt`` (:mod:`crowd.trajectories`, read with ``pedpy.load_trajectory_from_txt``;
PedPy's (x, y) are the sandbox's floor (x, z)) and each measurement (:mod:`crowd.measurement`):

- area (polygon): per frame the classic density N/A (``pedpy.compute_classic_density``), the Voronoi density
  (``compute_individual_voronoi_polygons`` + ``compute_voronoi_density``, walkable area = bounding box of all
  trajectories grown by :data:`VORONOI_MARGIN` (obstacles are not cut out); only when the trajectories have at most
  :data:`VORONOI_MAX_ROWS` rows, else left out and said so), the mean of the individual speeds of the agents
  inside (``compute_individual_speed`` with a centred window of :data:`SPEED_WINDOW_S` seconds, single-sided at
  the ends of a trajectory; ``compute_mean_speed_per_frame``), and the specific flow J_s = rho v (1/(m s));
  the fundamental diagram is v(rho) and J_s(rho) over the frames with at least one agent inside.
- line: N-t (``compute_n_t``: first crossing of each agent), the flow in windows of :data:`FLOW_WINDOW_S`
  seconds (``compute_flow``) and the mean flow (N - 1) / (t_N - t_1) between the first and the last crossing.

References: PedPy (Schrödter et al., doi:10.5281/zenodo.7194992); classic and Voronoi density and the
speed/flow definitions follow Zhang, Klingsch, Schadschneider & Seyfried, *Transitions in pedestrian
fundamental diagrams of straight corridors and T-junctions*, J. Stat. Mech. (2011) P06004, §3. The reference
curve drawn on the diagrams is Weidmann (1993): v(rho) = v0 (1 - exp(-gamma (1/rho - 1/rho_max))).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: centred window of the individual speed, seconds (PedPy frame_step = round(window / 2 * frame rate), >= 1)
SPEED_WINDOW_S = 0.5
#: window of PedPy's flow at a line, seconds
FLOW_WINDOW_S = 5.0
#: Voronoi densities only up to this many trajectory rows (agents x frames): the per-frame Voronoi is slow
VORONOI_MAX_ROWS = 200_000
#: margin of the walkable area around the trajectories' bounding box (Voronoi cells), metres: about a body radius,
#: so where walls bound the crowd the box is about the walkable area (a wider one dilutes the cells next to walls)
VORONOI_MARGIN = 0.25
#: Weidmann (1993) fundamental diagram: free speed m/s, jam density 1/m^2, gamma 1/m^2
WEIDMANN_V0, WEIDMANN_RHO_MAX, WEIDMANN_GAMMA = 1.34, 5.4, 1.913


def weidmann_speed(rho, v0: float = WEIDMANN_V0, rho_max: float = WEIDMANN_RHO_MAX,
                   gamma: float = WEIDMANN_GAMMA) -> np.ndarray:
    """Weidmann's speed at density ``rho`` (1/m^2): v0 (1 - exp(-gamma (1/rho - 1/rho_max))), 0 at and above
    rho_max, v0 at rho -> 0."""
    rho = np.asarray(rho, np.float64)
    with np.errstate(divide="ignore"):
        inv = np.where(rho > 0, 1.0 / np.where(rho > 0, rho, 1.0), np.inf)
    return np.where(rho >= rho_max, 0.0, v0 * (1.0 - np.exp(-gamma * (inv - 1.0 / rho_max))))


def pedpy_available() -> bool:
    try:
        import pedpy  # noqa: F401
    except ImportError:
        return False
    return True


def _finite(x):
    x = float(x)
    return x if math.isfinite(x) else None


def analyse(traj_file: str | Path, measurements, voronoi: bool = True) -> list:
    """PedPy measures of every measurement of a run.

    Parameters
    ----------
    traj_file : a run's trajectories.txt
    measurements : sequence of crowd.measurement.MeasurementSpec
    voronoi : compute the Voronoi density (up to VORONOI_MAX_ROWS rows); False: left out

    Returns
    -------
    list of dict, one per measurement: ``name``; ``area`` (None without a polygon) with ``frames``, ``time``,
    ``density``, ``voronoi_density`` (None when skipped), ``speed``, ``specific_flow`` (lists, frames with an
    agent inside) and ``mean_density``, ``mean_voronoi_density``, ``mean_speed``, ``mean_specific_flow``,
    ``frames_occupied``, ``voronoi_note``; ``line`` (None without one) with ``time``, ``cumulative`` (N-t),
    ``crossings``, ``mean_flow`` ((N - 1) / (t_N - t_1), 1/s), ``window_flows`` (PedPy's windows, 1/s),
    ``mean_window_flow``, ``crossing_speed``.
    """
    import pedpy

    traj = pedpy.load_trajectory_from_txt(trajectory_file=Path(traj_file))
    fps = float(traj.frame_rate)
    df = traj.data
    speed = pedpy.compute_individual_speed(traj_data=traj, frame_step=max(1, round(SPEED_WINDOW_S / 2 * fps)),
                                           speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    want_voronoi, voronoi, voronoi_note = voronoi, None, None
    if want_voronoi and any(m.polygon is not None for m in measurements):
        if len(df) <= VORONOI_MAX_ROWS:
            x0, x1 = float(df.x.min()) - VORONOI_MARGIN, float(df.x.max()) + VORONOI_MARGIN
            y0, y1 = float(df.y.min()) - VORONOI_MARGIN, float(df.y.max()) + VORONOI_MARGIN
            walk = pedpy.WalkableArea([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
            voronoi = pedpy.compute_individual_voronoi_polygons(traj_data=traj, walkable_area=walk)
        else:
            voronoi_note = f"{len(df):,} trajectory rows > {VORONOI_MAX_ROWS:,}: Voronoi density left out"
    out = []
    for m in measurements:
        entry = {"name": m.name, "area": None, "line": None}
        if m.polygon is not None:
            entry["area"] = _area(pedpy, traj, speed, voronoi, m.polygon, fps)
            entry["area"]["voronoi_note"] = voronoi_note
        if m.line is not None:
            entry["line"] = _line(pedpy, traj, speed, m.line, fps)
        out.append(entry)
    return out


def _area(pedpy, traj, speed, voronoi, polygon, fps: float) -> dict:
    area = pedpy.MeasurementArea(list(polygon))
    dens = pedpy.compute_classic_density(traj_data=traj, measurement_area=area)
    sp = pedpy.compute_mean_speed_per_frame(traj_data=traj, individual_speed=speed, measurement_area=area)
    frames = dens.index.to_numpy() if "frame" not in dens.columns else dens["frame"].to_numpy()
    rho = dens["density"].to_numpy(np.float64)
    v = sp.reindex(frames)["speed"].to_numpy(np.float64) if "frame" not in sp.columns else \
        sp.set_index("frame").reindex(frames)["speed"].to_numpy(np.float64)
    occupied = rho > 0  # PedPy reports speed 0 for an empty area: those frames are no measurement
    vor = None
    if voronoi is not None:
        vd, _ = pedpy.compute_voronoi_density(individual_voronoi_data=voronoi, measurement_area=area)
        vd = vd.set_index("frame") if "frame" in vd.columns else vd
        vor = vd.reindex(frames)["density"].to_numpy(np.float64)
    f = frames[occupied]
    r, vv = rho[occupied], np.nan_to_num(v[occupied])
    res = {"frames": f.tolist(), "time": (f / fps).tolist(), "density": r.tolist(), "speed": vv.tolist(),
           "specific_flow": (r * vv).tolist(),
           "voronoi_density": (np.nan_to_num(vor[occupied]).tolist() if vor is not None else None),
           "frames_occupied": int(occupied.sum()), "frames_total": int(frames.size),
           "area_m2": float(area.area)}
    mean = lambda a: _finite(np.mean(a)) if len(a) else None
    res.update(mean_density=mean(r), mean_speed=mean(vv), mean_specific_flow=mean(r * vv),
               mean_voronoi_density=mean(res["voronoi_density"]) if vor is not None else None)
    return res


def _line(pedpy, traj, speed, line, fps: float) -> dict:
    ml = pedpy.MeasurementLine(list(line))
    nt, crossing = pedpy.compute_n_t(traj_data=traj, measurement_line=ml)
    n = int(len(crossing))
    res = {"time": nt["time"].to_numpy(np.float64).tolist(),
           "cumulative": nt["cumulative_pedestrians"].to_numpy(np.int64).tolist(), "crossings": n,
           "mean_flow": None, "window_flows": [], "mean_window_flow": None, "crossing_speed": None,
           "length_m": float(math.dist(*line))}
    if n >= 2:
        fr = np.sort(crossing["frame"].to_numpy(np.float64))
        if fr[-1] > fr[0]:
            res["mean_flow"] = float((n - 1) / ((fr[-1] - fr[0]) / fps))
        delta = max(1, round(FLOW_WINDOW_S * fps))
        if int(nt["frame"].max()) - int(fr[0]) > delta:
            flow = pedpy.compute_flow(nt=nt, crossing_frames=crossing, individual_speed=speed, delta_frame=delta,
                                      frame_rate=fps)
            if len(flow):
                res["window_flows"] = flow["flow"].to_numpy(np.float64).tolist()
                res["mean_window_flow"] = _finite(np.mean(res["window_flows"]))
                res["crossing_speed"] = _finite(np.nanmean(flow["mean_speed"].to_numpy(np.float64)))
    if res["mean_flow"] is not None and res["length_m"] > 0:
        res["specific_flow"] = float(res["mean_flow"] / res["length_m"])
    else:
        res["specific_flow"] = None
    return res


def plots(tmp: Path, slug: str, scene_name: str, results: list) -> dict:
    """Figures of :func:`analyse`'s results: per measurement the time series (density, speed, N-t and flow) and
    the fundamental diagram (speed and specific flow against density, with Weidmann's curve). Returns
    {measurement name: {"series": rel path, "fd": rel path or None}}."""
    from crowd.report.plots import _plt, _save

    plt = _plt()
    out = {}
    for i, m in enumerate(results):
        a, ln = m["area"], m["line"]
        rows = (a is not None) * 2 + (ln is not None)
        fig, axes = plt.subplots(rows, 1, figsize=(8, 2.4 * rows), dpi=96, sharex=True, squeeze=False)
        axes = list(axes[:, 0])
        if a is not None:
            ax = axes.pop(0)
            ax.plot(a["time"], a["density"], ".", ms=3, label="classic N/A")
            if a["voronoi_density"] is not None:
                ax.plot(a["time"], a["voronoi_density"], ".", ms=3, label="Voronoi")
            ax.set_ylabel("density, 1/m²")
            ax.legend(fontsize=7)
            ax.grid(alpha=0.3)
            ax = axes.pop(0)
            ax.plot(a["time"], a["speed"], ".", ms=3, label="mean speed, m/s")
            ax.plot(a["time"], a["specific_flow"], ".", ms=3, label="ρ·v, 1/(m·s)")
            ax.set_ylabel("speed / flow")
            ax.legend(fontsize=7)
            ax.grid(alpha=0.3)
        if ln is not None:
            ax = axes.pop(0)
            ax.step(ln["time"], ln["cumulative"], where="post", label="N(t) crossed")
            ax.set_ylabel("N crossed")
            ax.grid(alpha=0.3)
            if ln["mean_flow"] is not None:
                ax.set_title(f"line: mean flow {ln['mean_flow']:.3f} /s", fontsize=8)
        fig.axes[-1].set_xlabel("simulated time, s")
        fig.suptitle(f"{scene_name} – {m['name']}: time series (PedPy)", fontsize=9)
        entry = {"series": _save(fig, tmp, f"plots/{slug}_meas{i}_series.png"), "fd": None}
        if a is not None and a["density"]:
            fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.6), dpi=96)
            rho = np.asarray(a["density"])
            grid = np.linspace(0.05, WEIDMANN_RHO_MAX, 200)
            ax1.plot(rho, a["speed"], ".", ms=3, label="frames (classic density)")
            ax1.plot(grid, weidmann_speed(grid), "k--", lw=1, label="Weidmann 1993")
            ax1.set_xlabel("density, 1/m²")
            ax1.set_ylabel("speed, m/s")
            ax2.plot(rho, a["specific_flow"], ".", ms=3, label="frames")
            ax2.plot(grid, grid * weidmann_speed(grid), "k--", lw=1, label="Weidmann 1993")
            ax2.set_xlabel("density, 1/m²")
            ax2.set_ylabel("specific flow ρ·v, 1/(m·s)")
            for ax in (ax1, ax2):
                ax.grid(alpha=0.3)
                ax.legend(fontsize=7)
            fig.suptitle(f"{scene_name} – {m['name']}: fundamental diagram", fontsize=9)
            entry["fd"] = _save(fig, tmp, f"plots/{slug}_meas{i}_fd.png")
        out[m["name"]] = entry
    return out


def html_section(entry: dict) -> str:
    """The page's section of a scene's pedestrian measures (``entry["pedestrian"]``): table and plots."""
    import html

    e = html.escape
    ped = entry.get("pedestrian")
    if not ped:
        return ""
    if ped.get("error"):
        return f"<h3>Pedestrian measures</h3><p>{e(ped['error'])}</p>"
    f = lambda x, fmt="{:.3f}": "–" if x is None else fmt.format(x)
    out = ["<h3>Pedestrian measures (PedPy)</h3>",
           f"<p>From {e(ped['trajectories'])} (setting {e(ped['setting'])}; the simulation does not depend on the "
           "LOD setting). Means over the frames with at least one agent in the area; speed: individual speeds, "
           f"centred window {SPEED_WINDOW_S:g} s; flow at a line: (N − 1) / (t<sub>N</sub> − t<sub>1</sub>) "
           f"between first and last crossing, and PedPy's flow in {FLOW_WINDOW_S:g} s windows.</p>",
           "<table class='pedestrian'><tr><th>measurement</th><th>area m²</th><th>frames occupied</th>"
           "<th>classic density 1/m²</th><th>Voronoi density 1/m²</th><th>mean speed m/s</th>"
           "<th>specific flow ρ·v 1/(m·s)</th><th>line crossings</th><th>line flow 1/s</th>"
           "<th>line specific flow 1/(m·s)</th><th>windowed flow 1/s</th></tr>"]
    for s in ped.get("sources") or []:  # a replayed recording: the data's source comes first
        out.insert(1, f"<p class='source'>Data: replayed from {e(s['file'])} ({e(s['format'])}, {s['persons']:,} "
                      f"people recorded over {s['seconds']:.1f} s at {s['frame_rate']:g} fps; sim/replay).</p>")
    for m in ped["measurements"]:
        a, ln = m["area"] or {}, m["line"] or {}
        out.append(f"<tr class='measurement'><td>{e(m['name'])}</td>"
                   f"<td class='n'>{f(a.get('area_m2'), '{:.2f}')}</td>"
                   f"<td class='n'>{f(a.get('frames_occupied'), '{:d}')}</td>"
                   f"<td class='n'>{f(a.get('mean_density'))}</td><td class='n'>{f(a.get('mean_voronoi_density'))}"
                   f"</td><td class='n'>{f(a.get('mean_speed'))}</td><td class='n'>{f(a.get('mean_specific_flow'))}"
                   f"</td><td class='n'>{f(ln.get('crossings'), '{:d}')}</td>"
                   f"<td class='n'>{f(ln.get('mean_flow'))}</td><td class='n'>{f(ln.get('specific_flow'))}</td>"
                   f"<td class='n'>{f(ln.get('mean_window_flow'))}</td></tr>")
    out.append("</table>")
    notes = {m["area"]["voronoi_note"] for m in ped["measurements"] if m["area"] and m["area"].get("voronoi_note")}
    out.extend(f"<p>{e(n)}</p>" for n in sorted(notes))
    for m in ped["measurements"]:
        p = ped["plots"].get(m["name"], {})
        out.append(f"<img src='{e(p['series'])}' alt='time series {e(m['name'])}'>")
        if p.get("fd"):
            out.append(f"<img src='{e(p['fd'])}' alt='fundamental diagram {e(m['name'])}'>")
    return "\n".join(out)


def replay_sources(scene) -> list:
    """The recordings a scene replays (``[[placement]] kind = "trajectories"``, ``sim.replay``): per recording its
    file's name, format, recorded people, frame rate and recorded seconds (what the measures are computed from)."""
    out = []
    for p in getattr(scene, "placements", []):
        rec = p.params.get("recording") if p.kind == "trajectories" else None
        if rec is not None:
            out.append({"file": Path(rec.source).name, "format": rec.format, "persons": rec.persons,
                        "frame_rate": rec.frame_rate,
                        "seconds": (rec.last_frame - rec.first_frame) / rec.frame_rate})
    return out


def scene_measures(tmp: Path, slug: str, scene_name: str, run, measurements, sources: list | None = None
                   ) -> dict | None:
    """The ``pedestrian`` entry of a scene in report.json (None when it has no measurement): analysis of ``run``'s
    trajectories (a :class:`crowd.report.runs.RunData` whose folder holds trajectories.txt) and its plots;
    ``sources``: the recordings the scene replays (:func:`replay_sources`), named on the page."""
    if not measurements:
        return None
    from crowd.trajectories import TRAJECTORY_FILE

    traj = Path(run.out_dir) / TRAJECTORY_FILE
    if not pedpy_available():
        return {"error": "PedPy is not installed (pip install 'crowd-sandbox[report]'): no pedestrian measures"}
    results = analyse(traj, measurements)
    return {"trajectories": str(traj.relative_to(tmp)), "setting": run.setting.label, "measurements": results,
            "plots": plots(tmp, slug, scene_name, results), "sources": list(sources or [])}
