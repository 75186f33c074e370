"""Run telemetry: per-frame stage timings and counts, written as data.

Files of a run (all written into the run's atomic output directory):

``frames.csv``
    one row per frame: ``frame, sim_time, total, simulate, select, upload,
    draw, finish, gpu, sys.<name>..., instances, culled, triangles, points,
    batches, props, agents, entered, exited, left, samples_passed``; ``props`` counts the triangles of props
    and obstacle solids (``crowd.world``), ``triangles`` those of the characters; ``agents`` the agents alive
    in the frame, ``entered`` those a source added in it, ``exited`` those that reached an exit in it,
    ``left`` those removed at its start (agents(f) = agents(f-1) + entered(f) - left(f); ``crowd.population``). Times are seconds (wall clock,
    ``time.perf_counter``); ``gpu`` is the GL timer-query time, blank when the
    driver has none. ``sys.<name>`` is the wall time of schedule step
    ``<name>`` summed over the frame's sub-steps.
``summary.json``
    per stage and per system: mean, p50, p95, p99, max (seconds); count
    totals and means; scene name, frame count, size; the machine (CPU model,
    cores, GL renderer/version) and package versions.
``trace.json``
    Chrome trace-event format (open in https://ui.perfetto.dev or
    chrome://tracing): a complete ("X") event per stage per frame on the
    "frame" track, per system on the "systems" track (laid end to end inside
    the frame's simulate span: the schedule reports durations, not start
    times), GPU time on the "gpu" track, and counter ("C") events for
    triangles, instances, points and props (triangles of props and obstacle solids).
"""
from __future__ import annotations

import csv
import io
import math
import os
import platform
from dataclasses import dataclass, field

import numpy as np

#: wall-clock stages of a frame, in order
STAGES = ("simulate", "select", "upload", "draw", "finish", "png")
#: per-frame counts taken from the DrawList stats
#: (``pose_passes``: poses evaluated by the renderer, render.renderer.Renderer.pose_evaluations; ``far``: agents
#: drawn as one far splat each, lod.far, also counted in ``points``)
COUNTS = ("instances", "culled", "triangles", "points", "batches", "props", "raster_triangles", "pose_passes", "agents",
          "entered", "exited", "left", "far")
#: percentiles reported in summary.json
PERCENTILES = (50, 95, 99)

_PID = 1
_TID_FRAME, _TID_SYSTEMS, _TID_GPU = 1, 2, 3


@dataclass
class FrameRecord:
    """Telemetry of one frame.

    start : float, seconds since the run's start when the frame began
    stages : dict stage -> (start offset in the frame, seconds)
    """

    frame: int
    sim_time: float
    start: float
    total: float
    stages: dict
    gpu: float | None
    systems: dict
    counts: dict
    samples_passed: int | None = None
    metrics: dict = field(default_factory=dict)  # extra per-frame figures (e.g. the terrain LOD's error terms)


@dataclass
class Telemetry:
    """Collects :class:`FrameRecord` rows and writes the run's telemetry files.

    systems : schedule step names in schedule order (the ``sys.<name>`` columns)
    """

    systems: list = field(default_factory=list)
    frames: list = field(default_factory=list)
    metrics: list = field(default_factory=list)  # names of FrameRecord.metrics seen, in order of appearance

    def add(self, rec: FrameRecord) -> None:
        for name in rec.systems:
            if name not in self.systems:
                self.systems.append(name)
        for name in rec.metrics:
            if name not in self.metrics:
                self.metrics.append(name)
        self.frames.append(rec)

    # ----------------------------------------------------------------------------------------------------- frames.csv
    def columns(self) -> list:
        return (["frame", "sim_time", "total", *STAGES, "gpu"] + [f"sys.{s}" for s in self.systems]
                + [*COUNTS, "samples_passed"] + list(self.metrics))

    def csv_text(self) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.columns())
        for r in self.frames:
            w.writerow([r.frame, _num(r.sim_time), _num(r.total)]
                       + [_num(r.stages.get(s, (0.0, 0.0))[1]) for s in STAGES]
                       + [_num(r.gpu) if r.gpu is not None else ""]
                       + [_num(r.systems.get(s, 0.0)) for s in self.systems]
                       + [int(r.counts.get(c, 0)) for c in COUNTS]
                       + ["" if r.samples_passed is None else int(r.samples_passed)]
                       + [_num(r.metrics[m]) if r.metrics.get(m) is not None else "" for m in self.metrics])
        return buf.getvalue()

    # --------------------------------------------------------------------------------------------------- summary.json
    def summary(self, scene_name: str = "", extra: dict | None = None, machine: dict | None = None) -> dict:
        """Statistics over all frames (seconds; NaN-free: absent values are null)."""
        stages = {s: stats([r.stages.get(s, (0.0, 0.0))[1] for r in self.frames]) for s in STAGES}
        stages["total"] = stats([r.total for r in self.frames])
        gpu = [r.gpu for r in self.frames if r.gpu is not None]
        stages["gpu"] = stats(gpu) if gpu else None
        systems = {s: stats([r.systems.get(s, 0.0) for r in self.frames]) for s in self.systems}
        counts = {}
        for c in COUNTS:
            v = np.array([r.counts.get(c, 0) for r in self.frames], np.float64)
            counts[c] = {"total": int(v.sum()), "mean": float(v.mean()) if v.size else 0.0,
                         "max": int(v.max()) if v.size else 0}
        total = sum(r.total for r in self.frames)
        out = {
            "scene": scene_name,
            "frames": len(self.frames),
            "wall_seconds": total,
            "fps": (len(self.frames) / total) if total > 0 else None,
            "stages": stages,
            "systems": systems,
            "counts": counts,
        }
        if self.metrics:
            out["metrics"] = {m: stats([r.metrics[m] for r in self.frames if r.metrics.get(m) is not None])
                              for m in self.metrics}
        if extra:
            out.update(extra)
        out["machine"] = machine if machine is not None else machine_info()
        return out

    # ----------------------------------------------------------------------------------------------------- trace.json
    def trace(self, scene_name: str = "") -> dict:
        """Chrome trace-event JSON object (``traceEvents`` in microseconds)."""
        ev = [
            {"name": "process_name", "ph": "M", "pid": _PID, "tid": 0, "args": {"name": f"crowd {scene_name}".strip()}},
            {"name": "thread_name", "ph": "M", "pid": _PID, "tid": _TID_FRAME, "args": {"name": "frame"}},
            {"name": "thread_name", "ph": "M", "pid": _PID, "tid": _TID_SYSTEMS, "args": {"name": "systems"}},
            {"name": "thread_name", "ph": "M", "pid": _PID, "tid": _TID_GPU, "args": {"name": "gpu"}},
        ]
        us = 1e6
        for r in self.frames:
            t0 = r.start * us
            ev.append({"name": f"frame {r.frame}", "cat": "frame", "ph": "X", "pid": _PID, "tid": _TID_FRAME,
                       "ts": t0, "dur": r.total * us, "args": {"frame": r.frame, "sim_time": r.sim_time}})
            for s in STAGES:
                if s in r.stages:
                    off, dur = r.stages[s]
                    ev.append({"name": s, "cat": "stage", "ph": "X", "pid": _PID, "tid": _TID_FRAME,
                               "ts": t0 + off * us, "dur": dur * us, "args": {"frame": r.frame}})
            off = r.stages.get("simulate", (0.0, 0.0))[0]
            for name in self.systems:
                if name in r.systems:
                    dur = r.systems[name]
                    ev.append({"name": name, "cat": "system", "ph": "X", "pid": _PID, "tid": _TID_SYSTEMS,
                               "ts": t0 + off * us, "dur": dur * us, "args": {"frame": r.frame}})
                    off += dur
            if r.gpu is not None:
                draw_off = r.stages.get("draw", (0.0, 0.0))[0]
                ev.append({"name": "gpu", "cat": "gpu", "ph": "X", "pid": _PID, "tid": _TID_GPU,
                           "ts": t0 + draw_off * us, "dur": r.gpu * us, "args": {"frame": r.frame}})
            for c in ("triangles", "instances", "points", "props", "agents"):
                ev.append({"name": c, "cat": "count", "ph": "C", "pid": _PID, "ts": t0,
                           "args": {c: int(r.counts.get(c, 0))}})
        return {"traceEvents": ev, "displayTimeUnit": "ms"}

    def write(self, out_dir, scene_name: str = "", extra: dict | None = None, machine: dict | None = None) -> dict:
        """Write frames.csv, summary.json and trace.json into ``out_dir``; return the summary."""
        from crowd.output import write_atomic, write_json

        write_atomic(os.path.join(out_dir, "frames.csv"), self.csv_text())
        summ = self.summary(scene_name, extra, machine)
        write_json(os.path.join(out_dir, "summary.json"), summ)
        write_json(os.path.join(out_dir, "trace.json"), self.trace(scene_name), indent=None)
        return summ


def stats(values) -> dict:
    """mean, p50, p95, p99 and max of ``values`` (seconds); zeros for no values."""
    v = np.asarray(list(values), np.float64)
    if v.size == 0:
        return {"mean": 0.0, **{f"p{p}": 0.0 for p in PERCENTILES}, "max": 0.0}
    out = {"mean": float(v.mean())}
    for p, q in zip(PERCENTILES, np.percentile(v, PERCENTILES)):
        out[f"p{p}"] = float(q)
    out["max"] = float(v.max())
    return out


def _num(x: float) -> str:
    return f"{x:.9g}" if math.isfinite(x) else ""


def cpu_model() -> str:
    """CPU model name from /proc/cpuinfo, else platform.processor()."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def package_versions() -> dict:
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name in ("crowd-sandbox", "numpy", "numba", "moderngl", "scipy", "pygltflib", "trimesh"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def machine_info(gl: dict | None = None) -> dict:
    """CPU model, cores, OS, GL renderer/version (when given) and package versions."""
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "gl_renderer": (gl or {}).get("GL_RENDERER"),
        "gl_version": (gl or {}).get("GL_VERSION"),
        "packages": package_versions(),
    }
