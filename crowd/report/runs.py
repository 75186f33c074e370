"""``crowd report`` runs: one headless run of a setting (:func:`run_task`), timed or as the NoLOD reference.

For each scene and each setting (:mod:`crowd.report.settings`) the scene runs headless along its camera path
(``Engine.run``: frames.csv, summary.json, trace.json and every k-th frame as PNG). A full-detail reference
run (LOD mode ``none``, same scene, seed and size; the simulation does not depend on the LOD mode, so the
states and cameras of both runs are equal frame by frame) renders the same sampled frames
(:func:`crowd.reference.reference_scene`). A run (:func:`run_task`) writes to a temporary folder on its worker and returns
its files as data; the client writes them into the report. A run's frame time is the sum of its stage
columns (:func:`frame_seconds`).

Test-only setting: the environment variable ``CROWD_TEST_SLEEP_MS`` makes every
timed frame of a report's runs sleep that long inside the ``select`` stage (the
report wraps the engine's selector; :class:`_SleepySelector`), so a test can
produce an artificially slower run.
"""
from __future__ import annotations

import csv
import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from crowd.errors import CrowdError, user_errors
from crowd.report.settings import Setting

#: frame-time stages of the breakdown plot (crowd.telemetry.STAGES)
STAGE_COLUMNS = ("simulate", "select", "upload", "draw", "finish")
#: environment variable (test-only): milliseconds slept inside each timed frame of the report's runs
SLEEP_ENV = "CROWD_TEST_SLEEP_MS"


def read_frames_csv(path) -> dict:
    """frames.csv -> column name -> float64 array (blank cells are NaN)."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    cols = rows[0].keys() if rows else []
    return {c: np.array([float(r[c]) if r[c] != "" else np.nan for r in rows], np.float64) for c in cols}


@dataclass
class RunData:
    """A finished run of one setting: its directory, summary and frames.csv columns."""

    setting: Setting
    out_dir: Path
    summary: dict
    columns: dict
    pngs: list
    metrics: list = field(default_factory=list)  # per sampled frame: dict frame, psnr, ssim, flip, mse, flicker, ...
    repeat_medians: list = field(default_factory=list)  # median frame seconds of each repeated run
    host: str | None = None  # the machine of the timed runs


class _SleepySelector:
    """Test-only proxy of an LOD selector whose ``select`` first sleeps ``seconds`` (inside the engine's timed
    ``select`` stage, so the report's frame times grow by that much); everything else is delegated."""

    def __init__(self, selector, seconds: float):
        self._inner, self._seconds = selector, seconds

    def select(self, *args, **kwargs):
        import time

        time.sleep(self._seconds)
        return self._inner.select(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self._inner, name)


def test_sleep_seconds() -> float:
    """Seconds of the test-only per-frame sleep (``CROWD_TEST_SLEEP_MS``; 0 when unset).

    Raises
    ------
    crowd.errors.CrowdError
        The variable is set but not a finite number of milliseconds >= 0.
    """
    import os

    raw = os.environ.get(SLEEP_ENV, "").strip()
    if not raw:
        return 0.0
    try:
        ms = float(raw)
    except ValueError:
        ms = math.nan
    if not math.isfinite(ms) or ms < 0:
        raise CrowdError(f"environment variable {SLEEP_ENV}={raw!r}: expected milliseconds, a number >= 0")
    return ms / 1e3


test_sleep_seconds.__test__ = False  # not a pytest test


def _run(scene, out_dir: Path, png_every: int, pairs: bool = False, sleep: float | None = None) -> tuple:
    """Run ``scene`` headless into ``out_dir``; with ``pairs`` the PNGs of frames ``f % png_every in (0, 1)``.

    ``sleep``: seconds of the test-only per-frame sleep (default: :func:`test_sleep_seconds` of this process).
    Returns (summary, frames.csv columns, sorted paths of the PNGs written)."""
    from crowd.engine import Engine

    sleep = test_sleep_seconds() if sleep is None else float(sleep)
    with Engine(scene, quiet=True) as engine:
        if scene.video:  # the clip the page embeds (crowd.video.REPORT_CLIP)
            from crowd.video import REPORT_CLIP

            engine.video_options = dict(REPORT_CLIP)
        if scene.lod_mode == "auto":  # explain_lod.jsonl: the report's section on mode auto (crowd.explain)
            engine.explain_lod = True
        if sleep > 0:
            engine.selector = _SleepySelector(engine.selector, sleep)
        every = png_every
        if pairs and png_every:
            # the sampled frames f % k == 0 and their successors f + 1 (the flicker measure's consecutive pairs);
            # the other frames are neither read back nor written
            engine.png_frames = lambda f, k=png_every: f % k in (0, 1 % k)
            every = 1
        r = engine.run(frames=scene.frames, out_dir=out_dir, png_every=every)
    return r.summary, read_frames_csv(out_dir / "frames.csv"), sorted(p for p in r.pngs if Path(p).is_file())


def run_task(scene, png_every: int, pairs: bool = False, sleep: float = 0.0) -> dict:
    """One headless run of ``scene``: the unit of work of a timed or reference run, in this process or on a dask
    worker.

    The run goes to a temporary folder and everything it wrote comes back as data, so a worker needs no
    filesystem shared with the client (only this package, and the scene's asset files at the same paths).

    Parameters
    ----------
    scene : crowd.scene.Scene (validated)
    png_every : k, write the PNGs of frames ``f % k == 0`` (0: none)
    pairs : also the PNG of each such frame's successor ``f + 1`` (the flicker measure's pairs)
    sleep : seconds of the test-only per-frame sleep (:data:`SLEEP_ENV`, read by the client)

    Returns
    -------
    dict
        ``summary`` (summary.json), ``columns`` (frames.csv: name -> (frames,) float64), ``files`` (path relative
        to the run folder -> bytes: frames.csv, summary.json, trace.json, frames/frame_NNNNN.png), ``pngs``
        (sorted PNG file names), ``host`` (its name), ``start``/``end`` (wall-clock seconds since the epoch,
        the task's interval on its worker); or ``{"error": message, "exit_code": code}`` for bad input (an
        asset, the memory guard, no GL context, NaN in the simulation), which the client raises as
        :class:`crowd.errors.CrowdError` with that exit code.
    """
    import socket
    import tempfile
    import time

    start = time.time()
    try:
        with tempfile.TemporaryDirectory(prefix="crowd-run-") as d:
            rd = Path(d) / "run"
            summary, columns, pngs = _run(scene, rd, png_every, pairs=pairs, sleep=sleep)
            files = {p.relative_to(rd).as_posix(): p.read_bytes() for p in sorted(rd.rglob("*")) if p.is_file()}
    except user_errors() as e:
        return {"error": str(e).splitlines()[0] if str(e) else type(e).__name__,
                "exit_code": int(getattr(e, "exit_code", 2))}  # e.g. 3: NaN/Inf in the simulation
    return {"summary": summary, "columns": columns, "files": files, "pngs": [Path(p).name for p in pngs],
            "host": socket.gethostname(), "start": start, "end": time.time()}


def _checked(result: dict) -> dict:
    """A task's result, or its user error raised here (one sentence; the task's exit code, 2 by default)."""
    if "error" in result:
        err = CrowdError(result["error"])
        err.exit_code = int(result.get("exit_code", 2))
        raise err
    return result


def frame_seconds(columns: dict) -> np.ndarray:
    """Per-frame time, seconds: the sum of the stage columns of frames.csv (simulate, select, upload, draw,
    finish). Unlike ``total`` it leaves out the PNG writes of the sampled frames, which would otherwise
    inflate exactly the frames that are compared, and telemetry bookkeeping."""
    return sum(np.nan_to_num(columns[k]) for k in STAGE_COLUMNS if k in columns)
