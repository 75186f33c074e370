"""``crowd report``: frame-time and accuracy reports over scenes and swept settings (:func:`build_report`).

For each scene and each combination of swept settings (``--sweep KEY=V1,V2``, :mod:`crowd.report.settings`)
the scene runs headless along its camera path (``Engine.run``: frames.csv,
summary.json, trace.json and every k-th frame as PNG; :mod:`crowd.report.runs`). A full-detail reference
run (LOD mode ``none``, same scene, seed and size; the simulation does not
depend on the LOD mode, so the states and cameras of both runs are equal frame
by frame) renders the same sampled frames, and each sampled frame is compared
with its reference by PSNR, SSIM and FLIP (:mod:`crowd.image_metrics`, :mod:`crowd.report.metrics`).
The work runs on :class:`crowd.report.cluster.ClusterPool` (``--cluster``); ``--compare`` checks the frame
times against a baseline report (:mod:`crowd.report.compare`).

The true reference (:mod:`crowd.reference`): each sampled frame (and its successor, for the flicker measure) is
also drawn at full detail with K x K samples per pixel and box-filtered down (``--reference-samples K``, default
4), once: the frames are cached by content (:mod:`crowd.reference_cache`), so a second report of the same scene
draws none. Every setting's image error is taken against it; aliased full detail (mode none, one sample per
pixel) is a setting like any other (added when the sweep has none at a size), and every setting's error against
it is reported beside (``accuracy_aliased``).

The report directory (written atomically, :func:`crowd.output.atomic_dir`)::

    index.html         self-contained page (relative links only; crowd.report.page)
    report.json        every number of the page (non-finite values as null)
    table.md, table.csv  one row per scene and setting (crowd.report.table)
    plots/*.png        matplotlib (Agg) figures (crowd.report.plots; crowd.report.pedestrian for scenes with
                       [[measurement]] areas or lines: PedPy density, speed, flow, fundamental diagram;
                       crowd.report.population for scenes whose agents leave and enter)
    samples/*.png      sampled frames, references and error maps
    runs/<scene>/<setting>/   the runs' own outputs (frames.csv, summary.json, ...)
"""
from __future__ import annotations

import dataclasses
import math
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from crowd.errors import CrowdError
from crowd.report.cluster import DEFAULT_CLUSTER, ClusterPool
from crowd.report.compare import MAD_TO_SIGMA, MIN_REGRESSION, NOISE_K, compare_reports
from crowd.report.metrics import aggregate, metrics_task
from crowd.report.page import render_html
from crowd.report.pedestrian import replay_sources, scene_measures
from crowd.report.plots import _plots
from crowd.report.population import scene_population
from crowd.report.runs import (
    STAGE_COLUMNS,
    RunData,
    _checked,
    frame_seconds,
    run_task,
    test_sleep_seconds,
)
from crowd.report.settings import expand_settings
from crowd.memory import available_memory
from crowd.reference import DEFAULT_K, FILTER, check_fits, check_k, is_reference, plan_tiles, reference_scene
from crowd.reference_cache import reference_task
from crowd.report.settings import Setting, _fmt_value

#: default number of sampled (compared) frames per run
DEFAULT_SAMPLES = 4


class _Lines:
    """Progress where stderr is no terminal (a pipe, a log, CI): one line per finished timed run and reference,
    the steps between (as a tqdm bar's ``update``/``set_postfix_str``, plus :meth:`line`); nothing when ``quiet``."""

    def __init__(self, total: int, quiet: bool = False):
        self.total, self.n, self.quiet = total, 0, quiet

    def update(self, k: int = 1) -> None:
        self.n += k

    def set_postfix_str(self, text: str) -> None:
        self.line(text)

    def line(self, text: str) -> None:
        if not self.quiet:
            print(f"report [{self.n}/{self.total}]: {text}", file=sys.stderr, flush=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class _Bar:
    """tqdm's bar on a terminal; :meth:`line` shows the latest finished step beside it."""

    def __init__(self, total: int):
        from tqdm import tqdm

        self.bar = tqdm(total=total, desc="report", leave=False, file=sys.stderr, dynamic_ncols=True)

    def update(self, k: int = 1) -> None:
        self.bar.update(k)

    def set_postfix_str(self, text: str) -> None:
        self.bar.set_postfix_str(text)

    def line(self, text: str) -> None:
        self.bar.set_postfix_str(text)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.bar.close()  # closed before anything else is printed (no summary glued to a frozen bar)
        return False


def _progress(total: int, quiet: bool):
    """The report's progress: nothing with ``quiet``, a bar on a terminal, else one line per step (stderr)."""
    return _Bar(total) if sys.stderr.isatty() and not quiet else _Lines(total, quiet)


def finite_or_none(x):
    """JSON-safe number: non-finite floats become None."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


@dataclass
class ReportResult:
    out_dir: Path
    data: dict  # as report.json


def build_report(scene_paths: list, sweeps: list, frames: int | None = None, size: tuple | None = None,
                 out: str | Path = "out/report", sample_every: int | None = None, quiet: bool = False,
                 repeat: int | None = None, baseline: dict | None = None, baseline_dir: str | None = None,
                 cluster: str | None = DEFAULT_CLUSTER, reference_samples: int = DEFAULT_K) -> ReportResult:
    """Run every scene x setting plus references, measure, and write the report directory atomically.

    Parameters
    ----------
    scene_paths : list of scene file paths
    sweeps : list of (key, values) (:func:`crowd.report.settings.parse_sweep`)
    frames, size : overrides of every scene's ``frames`` and ``[render] size``
    out : report directory (replaced atomically)
    sample_every : compare every k-th frame (default: ``frames // 4``, at least 1)
    quiet : no progress bar
    repeat : timed runs per setting (default 3 with a baseline, else 1); the first run's images are compared,
        every run's median frame time goes into ``repeat_medians_ms``.
    baseline : a baseline report.json (:func:`crowd.report.compare.load_baseline`); the comparison goes into
        ``data["compare"]`` and the page
    baseline_dir : the baseline's directory, as shown on the page
    cluster : ``"local"`` (default, an embedded dask LocalCluster), ``"none"``/None (this process) or the
        address of a dask scheduler (``tcp://HOST:PORT``): see :class:`ClusterPool`.
    reference_samples : K of the true reference (:mod:`crowd.reference`), 2 to 8

    Notes
    -----
    Two phases. First every timed run (each setting ``repeat`` times, all scenes; aliased full detail among
    them) through :meth:`ClusterPool.timed`: one at a time per host, nothing else running. Then, in parallel on
    every worker, the true references (:func:`crowd.reference_cache.reference_task`, from the cache where
    drawn before) and the image error of every sampled frame against the reference and against aliased full
    detail (:func:`crowd.report.metrics.metrics_task`). The client writes the runs' files, plots and the page.

    Raises
    ------
    crowd.errors.CrowdError
        Bad scene, sweep or ``cluster`` (before anything runs or is written); a user error raised by a run
        (e.g. a broken asset) is raised here with its message, and nothing is written.
    """
    from crowd.image_metrics import flip_available
    from crowd.output import atomic_dir, check_output_dir
    from crowd.images import write_png

    k_ref = check_k(reference_samples)
    all_settings = [(Path(p), expand_settings(p, sweeps, size=size, frames=frames)) for p in scene_paths]
    # true references: one per scene and distinct full-detail drawing (size, light and shadows), each with its
    # aliased full-detail setting (added where the sweep has none)
    groups = [_reference_groups(settings) for _, settings in all_settings]
    for g in (g for gs in groups for g in gs):  # a reference that cannot fit fails before anything runs
        check_fits(plan_tiles(g.scene.render.size, k_ref), available_memory())
    for _, settings in all_settings:  # pedestrian measures (crowd.report.pedestrian) need the first run's trajectories
        s0 = settings[0]
        if getattr(s0.scene, "measurements", ()) and not s0.scene.trajectories:
            s0.scene = dataclasses.replace(s0.scene, trajectories=True)
    names = [s[0].scene.name for _, s in all_settings]
    slugs = _unique_slugs(names)
    out = check_output_dir(out)
    repeat = int(repeat) if repeat is not None else (3 if baseline is not None else 1)
    if repeat < 1:
        raise CrowdError(f"--repeat {repeat}: expected a positive number of runs per setting")
    sleep = test_sleep_seconds()  # a bad test-only setting fails before anything runs
    pool = ClusterPool(cluster)  # a malformed address fails here, before anything runs
    ks = [sample_every or max(1, settings[0].scene.frames // DEFAULT_SAMPLES) for _, settings in all_settings]
    n_timed = sum(repeat * len(s) for _, s in all_settings)
    n_refs = sum(len(g) for g in groups)
    n_metrics = 2 * sum(len(s) * len(range(0, s[0].scene.frames, k)) for (_, s), k in zip(all_settings, ks))
    data = {"scenes": [], "flip": flip_available(), "sweeps": [[k, v] for k, v in sweeps], "machine": None,
            "repeat": repeat, "reference": {"k": k_ref, "filter": FILTER}}
    progress = _progress(n_timed + n_refs + n_metrics, quiet)
    n_set = sum(len(s) for _, s in all_settings)
    n_aliased = sum(s.label.startswith(ALIASED_LABEL) for _, ss in all_settings for s in ss)
    progress.line(f"{len(all_settings)} scene(s), {n_set} setting(s)"
                  + (f" ({n_aliased} of them aliased full detail, added)" if n_aliased else "")
                  + f": {n_timed} timed run(s), {n_refs} reference(s) at K = {k_ref}, {n_metrics} image comparisons; "
                  f"starting {'the cluster' if cluster not in (None, 'none') else 'in this process'}")
    with pool, atomic_dir(out) as tmp, progress as bar:
        data["cluster"] = pool.description
        data["hosts"] = {h: len(w) for h, w in pool.hosts().items()}
        for d in ("plots", "samples", "runs"):
            (tmp / d).mkdir()

        # phase 1: timed runs, never two on one host, nothing else running
        jobs, where = [], []
        for si, ((_, settings), k) in enumerate(zip(all_settings, ks)):
            for st in settings:
                for i in range(repeat):  # the first run writes the sampled frames; repeats are timing only
                    # the first run also records the setting's clip (crowd.video; its time is not frame time)
                    jobs.append((st.scene.with_overrides(video=True) if i == 0 else st.scene, k if i == 0 else 0,
                                 i == 0, sleep))
                    where.append((si, st, i))
        bar.set_postfix_str(f"timed runs on {pool.description}")

        def timed_done(i, v):
            _checked(v)
            bar.update(1)
            si, st, rep = where[i]
            bar.line(f"timed run of {names[si]} [{st.label}]" + (f" (repeat {rep + 1})" if rep else "")
                     + f": median {1e3 * float(np.median(frame_seconds(v['columns']))):.1f} ms over "
                     f"{len(v['columns'].get('frame', []))} frames")

        timed = pool.timed(run_task, jobs, done=timed_done)
        runs_of = [[] for _ in all_settings]  # per scene: (RunData, handle of the first run)
        first = {}
        # when and where each run ran (wall-clock seconds since the epoch): the scheduling, checkable
        data["schedule"] = []
        for (si, st, i), (handle, v) in zip(where, timed):
            data["schedule"].append({"kind": "timed", "scene": names[si], "label": st.label, "run": i,
                                     "host": v.get("host"), "start": v.get("start"), "end": v.get("end")})
            slug = slugs[si]
            rd = tmp / "runs" / slug / (st.slug if i == 0 else f"{st.slug}_r{i}")
            _write_files(rd, v["files"])
            median = float(np.median(frame_seconds(v["columns"])))
            if i == 0:
                run = RunData(st, rd, v["summary"], v["columns"], [rd / "frames" / n for n in v["pngs"]])
                run.host = v.get("host")
                runs_of[si].append(run)
                first[id(run)] = (handle, v)
            runs_of[si][-1].repeat_medians.append(median)

        # phase 2: true references and image error, in parallel on every worker
        bar.set_postfix_str("references and image error")
        ref_handles = {}
        for si, (_, settings) in enumerate(all_settings):
            n = settings[0].scene.frames
            want = sorted({g for f in range(0, n, ks[si]) for g in (f, f + 1) if g < n})
            for g in groups[si]:
                ref_handles[si, g.name] = pool.submit(reference_task, g.scene, want, k_ref)
        mjobs, mhandles = [], []
        for si in range(len(all_settings)):
            for run in runs_of[si]:
                g = next(g for g in groups[si] if run.setting.slug in g.members)
                ref = ref_handles[si, g.name]
                aliased = first[id(next(r for r in runs_of[si] if r.setting.slug == g.aliased))][0]
                handle = first[id(run)][0]
                for name in first[id(run)][1]["pngs"]:
                    frame = int(re.search(r"(\d+)", name).group(1))
                    if frame % ks[si] == 0:  # not the second frame of a flicker pair
                        mjobs.append((si, run, frame))
                        mhandles.append((pool.submit(metrics_task, handle, ref, frame),
                                         pool.submit(metrics_task, handle, aliased, frame)))
        ref_values = dict(zip(ref_handles, pool.results(list(ref_handles.values()), done=lambda: bar.update(1))))
        for (si, name), v in ref_values.items():
            _checked(v)
            secs = list(v["seconds"].values())
            bar.line(f"reference of {names[si]} {name[len('reference_'):]}: {len(v['files'])} frames, "
                     f"{len(v['drawn'])} drawn" + (f" ({float(np.median(secs)):.1f} s each)" if v["drawn"] else "")
                     + f", {len(v['cached'])} from the cache")
            data["schedule"].append({"kind": "reference", "scene": names[si], "label": name[len("reference_"):],
                                     "run": 0, "host": v.get("host"), "start": v.get("start"), "end": v.get("end")})
            _write_files(tmp / "runs" / slugs[si] / name, v["files"])
        flat = pool.results([h for pair in mhandles for h in pair], done=lambda: bar.update(1))
        results = list(zip(flat[0::2], flat[1::2]))

        for si, (path, settings) in enumerate(all_settings):
            slug, k = slugs[si], ks[si]
            for (sj, run, frame), (m, m_aliased) in zip(mjobs, results):
                if sj != si:
                    continue
                ref_dir = tmp / "runs" / slug / next(g.name for g in groups[si] if run.setting.slug in g.members)
                base = f"{slug}_{run.setting.slug}_f{frame:05d}"
                shutil.copyfile(run.out_dir / "frames" / f"frame_{frame:05d}.png", tmp / "samples" / f"{base}.png")
                shutil.copyfile(ref_dir / "frames" / f"frame_{frame:05d}.png", tmp / "samples" / f"{base}_ref.png")
                m = dict(m)
                write_png(tmp / "samples" / f"{base}_err.png", m.pop("error_png"))
                aliased = {q: v for q, v in m_aliased.items() if q != "error_png"}
                run.metrics.append({"frame": frame, **m, "aliased": aliased, "image": f"samples/{base}.png",
                                    "reference": f"samples/{base}_ref.png", "error": f"samples/{base}_err.png"})
            scene_entry = {"name": names[si], "slug": slug, "file": str(path), "frames": settings[0].scene.frames,
                           "sample_every": k, "settings": [],
                           "reference": [_reference_entry(ref_values[si, g.name], g, k_ref, slug)
                                         for g in groups[si]]}
            for run in runs_of[si]:
                scene_entry["settings"].append(_setting_entry(run, tmp))
                if data["machine"] is None:
                    data["machine"] = run.summary.get("machine")
            _plots(tmp, scene_entry, runs_of[si])
            ped = scene_measures(tmp, slug, names[si], runs_of[si][0], settings[0].scene.measurements,
                                 replay_sources(settings[0].scene))
            if ped is not None:
                scene_entry["pedestrian"] = ped
            pop = scene_population(tmp, slug, names[si], runs_of[si][0], settings[0].scene)
            if pop is not None:  # agents left and entered (crowd.report.population)
                scene_entry["population"] = pop
            data["scenes"].append(scene_entry)
        if baseline is not None:
            rows = compare_reports(data, baseline)
            data["compare"] = {"baseline": str(baseline_dir) if baseline_dir is not None else None, "rows": rows,
                               "regressions": sum(r["regression"] for r in rows),
                               "rule": f"ratio of medians > 1 + max({MIN_REGRESSION:g}, {NOISE_K:g} x the larger "
                                       f"relative spread {MAD_TO_SIGMA} MAD / median of the repeated medians "
                                       f"of both reports)"}
        from crowd.output import write_atomic, write_json

        write_json(tmp / "report.json", _json_safe(data))
        write_atomic(tmp / "index.html", render_html(data))
        from crowd.report.table import csv_text, markdown

        write_atomic(tmp / "table.md", markdown(data))  # the page's figures as text (crowd.report.table)
        write_atomic(tmp / "table.csv", csv_text(data))
    return ReportResult(out_dir=out, data=data)


#: label of the aliased full-detail setting a report adds (mode none, one sample per pixel)
ALIASED_LABEL = "full detail (aliased)"


@dataclass
class _RefGroup:
    """The settings of a scene that share one full-detail drawing (:func:`crowd.reference.reference_scene` of
    theirs is the same: size, light, shadows): their true reference (folder ``name`` under the scene's runs) and
    their aliased full-detail setting (slug ``aliased``)."""

    name: str
    scene: object
    members: list
    aliased: str
    label: str


def _reference_groups(settings: list) -> list:
    """Group ``settings`` by their full-detail drawing, appending an aliased full-detail setting to ``settings``
    for each group that has none (labelled by the group's swept values other than LOD keys)."""
    from crowd.reference_cache import reference_identity

    by_key: dict = {}
    for st in list(settings):
        ref = reference_scene(st.scene)
        by_key.setdefault(reference_identity(ref), (ref, []))[1].append(st)
    out = []
    for ref, members in by_key.values():
        shown = {k: v for k, v in members[0].values.items() if not k.startswith("lod.")}
        label = ", ".join(f"{k}={_fmt_value(v)}" for k, v in shown.items())
        own = next((st for st in members if is_reference(st.scene)), None)
        if own is None:
            own = Setting(label=ALIASED_LABEL + (f", {label}" if label else ""), values={}, scene=ref,
                          slug=f"s{len(settings)}")
            settings.append(own)
            members.append(own)
        w, h = ref.render.size
        name = f"reference_{w}x{h}"
        if any(g.name == name for g in out):
            name += f"_{len(out) + 1}"
        out.append(_RefGroup(name=name, scene=ref, members=[st.slug for st in members], aliased=own.slug,
                             label=label))
    return out


def _reference_entry(v: dict, g: _RefGroup, k: int, slug: str) -> dict:
    """What the report says of one true reference: its size, K, tiles, frames drawn now or found in the cache,
    and the seconds a frame took to draw (median)."""
    secs = [float(x) for x in v["seconds"].values()]
    return {"size": list(g.scene.render.size), "k": k, "label": g.label, "frames": len(v["files"]),
            "drawn": len(v["drawn"]), "cached": len(v["cached"]), "tiles": v.get("tiles"),
            "tile_pixels": v.get("tile_pixels"), "seconds_per_frame": float(np.median(secs)) if secs else None,
            "dir": f"runs/{slug}/{g.name}", "settings": g.members, "aliased": g.aliased}


def _write_files(folder: Path, files: dict) -> None:
    """Write a run's files (relative path -> bytes) under ``folder`` (inside the report's temporary folder)."""
    for rel, blob in files.items():
        p = folder / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(blob)


def _unique_slugs(names: list) -> list:
    out, used = [], set()
    for n in names:
        base = re.sub(r"[^A-Za-z0-9_.-]+", "_", n) or "scene"
        s, i = base, 2
        while s in used:
            s, i = f"{base}_{i}", i + 1
        used.add(s)
        out.append(s)
    return out


def _setting_entry(run: RunData, tmp: Path) -> dict:
    from crowd.telemetry import stats

    s, st = run.summary, run.setting
    stages = s["stages"]
    ft = stats(frame_seconds(run.columns))
    clip = None
    if (run.out_dir / "video.mp4").is_file():  # the setting's short clip (crowd.video.REPORT_CLIP)
        clip = f"samples/{run.out_dir.parent.name}_{st.slug}.mp4"
        shutil.copyfile(run.out_dir / "video.mp4", tmp / clip)
    explain = run.out_dir / "explain_lod.jsonl"
    if explain.is_file():  # mode auto: what it drew and why (crowd.explain)
        from crowd.explain import read, summarize

        auto = summarize(read(explain))
    else:
        auto = None
    return {"clip": clip, "label": st.label, "slug": st.slug, "values": st.values, "lod_mode": st.scene.lod_mode,
            "auto": auto,
            "host": run.host,
            "lod_params": dict(st.scene.lod_params), "size": list(st.scene.render.size),
            "run_dir": str(run.out_dir.relative_to(tmp)),
            "frame_ms": {q: ft[q] * 1e3 for q in ("mean", "p50", "p95", "p99", "max")},
            "first_frame_ms": float(frame_seconds(run.columns)[0]) * 1e3 if len(run.columns.get("frame", [])) else None,
            "repeat_medians_ms": [m * 1e3 for m in run.repeat_medians],
            "stage_ms": {k: stages[k]["mean"] * 1e3 for k in STAGE_COLUMNS if stages.get(k)},
            "gpu_ms": (stages["gpu"]["p50"] * 1e3) if stages.get("gpu") else None,
            "triangles": s["counts"]["triangles"]["mean"], "points": s["counts"]["points"]["mean"],
            "instances": s["counts"]["instances"]["mean"],
            "aliased_full_detail": is_reference(st.scene),
            "accuracy": aggregate(run.metrics), "accuracy_aliased": aggregate([m["aliased"] for m in run.metrics]),
            "samples": run.metrics}


def _json_safe(obj):
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        obj = obj.item()
    return finite_or_none(obj)
