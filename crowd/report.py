"""``crowd report``: frame-time and accuracy reports over scenes and swept settings.

For each scene and each combination of swept settings (``--sweep KEY=V1,V2``)
the scene runs headless along its camera path (``Engine.run``: frames.csv,
summary.json, trace.json and every k-th frame as PNG). A full-detail reference
run (LOD mode ``none``, same scene, seed and size; the simulation does not
depend on the LOD mode, so the states and cameras of both runs are equal frame
by frame) renders the same sampled frames, and each sampled frame is compared
with its reference by PSNR, SSIM and FLIP (:mod:`crowd.image_metrics`).

The report directory (written atomically, :func:`crowd.output.atomic_dir`)::

    index.html         self-contained page (relative links only)
    report.json        every number of the page (non-finite values as null)
    plots/*.png        matplotlib (Agg) figures
    samples/*.png      sampled frames, references and error maps
    runs/<scene>/<setting>/   the runs' own outputs (frames.csv, summary.json, ...)

Sweep keys are applied to the parsed TOML document *before* validation, so a
swept value is checked exactly as if it were written in the scene file.

Scale-out (:class:`ClusterPool`, ``--cluster``): by default the work runs on an
embedded dask ``LocalCluster`` on loopback (one single-threaded worker process
per core); ``--cluster tcp://HOST:PORT`` uses a running dask scheduler and
``--cluster none`` keeps everything in this process, serially. Timed runs come
first, through one queue per host: a host runs one timed run at a time and
nothing else of the report runs anywhere meanwhile, so no two timed runs share a
machine's cores and no image-error work disturbs them; different hosts time in
parallel. Then the NoLOD reference runs and the image error of every sampled
frame run in parallel on all workers. A run (:func:`run_task`) writes to a
temporary folder on its worker and returns its files as data; the client writes
them into the report. Results are the same as in this process (same frames,
same counts, same image errors; only the wall-clock times differ).

Regression check (``--compare BASELINE_DIR``, :func:`compare_reports`): each
setting runs ``--repeat N`` times (default 3 with ``--compare``, serially, never
two timed runs at once); a run's frame time is the median of its per-frame stage
sums and a setting's is the median of its runs' medians. Per (scene, setting
label) found in both reports, ``ratio = current / baseline`` and the noise of
each report is its relative spread ``1.4826 * MAD / median`` of the repeated
medians (MAD, the median absolute deviation, scaled to estimate a standard
deviation; robust to one slow run, e.g. a cold first run on a shared machine).
A regression is ``ratio > 1 + threshold`` with
``threshold = max(MIN_REGRESSION, NOISE_K * max(spread_current, spread_baseline))``
(5 % and 3: a slowdown must exceed three robust standard deviations of the
noisier report).

Test-only setting: the environment variable ``CROWD_TEST_SLEEP_MS`` makes every
timed frame of a report's runs sleep that long inside the ``select`` stage (the
report wraps the engine's selector; :class:`_SleepySelector`), so a test can
produce an artificially slower run.
"""
from __future__ import annotations

import copy
import csv
import dataclasses
import html
import itertools
import math
import re
import shutil
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from crowd.errors import CrowdError, SceneError

#: swept keys besides ``lod.<key>`` (any key of an LOD mode's PARAMS, and ``lod.mode``)
SIZE_KEYS = ("render.size", "resolution")
#: default number of sampled (compared) frames per run
DEFAULT_SAMPLES = 4
#: frame-time stages of the breakdown plot (crowd.telemetry.STAGES)
STAGE_COLUMNS = ("simulate", "select", "upload", "draw", "finish")


#: smallest relative slowdown flagged as a regression by ``--compare``
MIN_REGRESSION = 0.05
#: a slowdown must exceed NOISE_K times the larger relative spread (1.4826 MAD / median) of both reports
NOISE_K = 3.0
#: MAD -> standard deviation of a normal distribution
MAD_TO_SIGMA = 1.4826
#: environment variable (test-only): milliseconds slept inside each timed frame of the report's runs
SLEEP_ENV = "CROWD_TEST_SLEEP_MS"


class SweepError(CrowdError):
    """A bad ``--sweep`` argument (exit code 2)."""


# ---------------------------------------------------------------------------------------------------------------------
# sweeps and settings
# ---------------------------------------------------------------------------------------------------------------------


def _common_lod_keys() -> tuple:
    """``[lod]`` keys valid for every mode (``lod.keyframed_selection.LOD_COMMON_PARAMS``: keyframe_every, ...)."""
    try:
        from lod.keyframed_selection import LOD_COMMON_PARAMS
    except ImportError:
        return ()
    return tuple(LOD_COMMON_PARAMS)


def _all_lod_keys() -> dict:
    """lod key -> modes accepting it (``mode`` and the common keys are accepted by all)."""
    from lod.modes import mode_names, mode_params

    out = {"mode": list(mode_names())}
    for m in mode_names():
        for k in mode_params(m):
            out.setdefault(k, []).append(m)
    for k in _common_lod_keys():
        out[k] = list(mode_names())
    return out


def parse_sweep(text: str) -> tuple:
    """``KEY=V1,V2,...`` -> (canonical key, [values]).

    Values are TOML literals when they parse as one (``0.5``, ``2``, ``true``),
    else strings (``points``); sizes are ``WxH``. The key is checked here; the
    values are checked by scene validation (:func:`expand_settings`).

    Raises
    ------
    SweepError
        Malformed argument or unknown key (one sentence naming what is accepted).
    """
    from crowd.scene import parse_size

    lod_keys = _all_lod_keys()
    accepted = ", ".join([f"lod.{k}" for k in lod_keys] + list(SIZE_KEYS))
    key, sep, rest = text.partition("=")
    key = key.strip()
    if not sep or not key or not rest.strip():
        raise SweepError(f"--sweep {text!r}: expected KEY=V1,V2,... with KEY one of {accepted}")
    raw = [v.strip() for v in rest.split(",")]
    if any(not v for v in raw):
        raise SweepError(f"--sweep {text!r}: empty value in the list; expected KEY=V1,V2,...")
    if key in SIZE_KEYS:
        values = []
        for v in raw:
            s = parse_size(v)
            if s is None:
                from crowd.scene import SIZE_RANGE

                raise SweepError(f"--sweep {key}: bad size {v!r}; expected WxH with integers in "
                                 f"{SIZE_RANGE[0]} ..= {SIZE_RANGE[1]} (e.g. 640x360)")
            values.append(list(s))
        return "render.size", values
    if not key.startswith("lod.") or key[4:] not in lod_keys:
        raise SweepError(f"--sweep: unknown key {key!r}; accepted: {accepted}")
    values = []
    for v in raw:
        try:
            values.append(tomllib.loads(f"v = {v}")["v"])
        except tomllib.TOMLDecodeError:
            values.append(v)
    if len(set(map(repr, values))) != len(values):
        raise SweepError(f"--sweep {key}: a value is repeated in {rest!r}")
    return key, values


@dataclass
class Setting:
    """One combination of swept values for one scene.

    label : str, e.g. ``lod.mode=points, lod.splat_size=2`` (``scene`` when nothing is swept)
    values : dict canonical key -> value actually applied
    scene : crowd.scene.Scene, validated with the values applied
    """

    label: str
    values: dict
    scene: object
    slug: str = ""


def _fmt_value(v) -> str:
    if isinstance(v, list) and len(v) == 2:
        return f"{v[0]}x{v[1]}"
    return str(v)


def expand_settings(scene_path, sweeps: list, size: tuple | None = None, frames: int | None = None) -> list:
    """Validated settings of one scene: the cartesian product of ``sweeps``.

    Parameters
    ----------
    scene_path : path of a TOML scene file
    sweeps : list of (key, values) from :func:`parse_sweep`
    size : (w, h) or None, the ``--size`` override (a swept render.size wins)
    frames : int or None, the ``--frames`` override

    An ``lod.<key>`` that the combination's LOD mode does not accept is left
    out of that combination (so ``lod.mode=none,clusters`` sweeps with
    ``lod.poe=0.5,2`` give three settings), as are the scene's own ``[lod]``
    keys another mode does not accept. Duplicate combinations are merged.

    Raises
    ------
    crowd.errors.SceneError
        The scene file is invalid, or a swept value is not valid for its key.
    """
    from crowd.scene import load_scene, parse_scene
    from lod.modes import mode_params

    load_scene(scene_path)  # the file itself, with its own errors
    path = Path(scene_path)
    doc0 = tomllib.loads(path.read_text(encoding="utf-8"))
    if size is not None:
        doc0.setdefault("render", {})["size"] = list(size)
    keys = [k for k, _ in sweeps]
    settings, seen = [], set()
    for combo in itertools.product(*[vals for _, vals in sweeps]):
        doc = copy.deepcopy(doc0)
        lod = doc.setdefault("lod", {})
        if not isinstance(lod, dict):
            break  # load_scene above reported this
        applied = {}
        if "lod.mode" in keys:
            lod["mode"] = combo[keys.index("lod.mode")]
            applied["lod.mode"] = lod["mode"]
        mode = lod.get("mode", "none")
        try:
            accepted = set(mode_params(mode)) if isinstance(mode, str) else set()
        except KeyError:
            accepted = set()  # unknown mode: validation below names the accepted ones
        accepted |= set(_common_lod_keys())  # e.g. keyframe_every: every mode takes it
        if "lod.mode" in keys:
            for k in list(lod):
                if k != "mode" and k not in accepted:
                    del lod[k]
        for k, v in zip(keys, combo):
            if k == "lod.mode":
                continue
            if k == "render.size":
                doc.setdefault("render", {})["size"] = v
            elif k[4:] in accepted:
                lod[k[4:]] = v
            else:
                continue
            applied[k] = v
        try:
            scene = parse_scene(doc, path)
        except SceneError as e:
            shown = ", ".join(f"{k}={_fmt_value(v)}" for k, v in applied.items())
            raise SceneError(e.path, e.key, str(e).split(": ", 2)[-1] + f" (with --sweep {shown})") from None
        ident = repr(sorted((k, repr(v)) for k, v in applied.items()))
        if ident in seen:
            continue
        seen.add(ident)
        if frames is not None:
            scene = scene.with_overrides(frames=frames)
        label = ", ".join(f"{k}={_fmt_value(v)}" for k, v in applied.items()) or "scene"
        settings.append(Setting(label=label, values=applied, scene=scene, slug=f"s{len(settings)}"))
    for k, _ in sweeps:
        if k.startswith("lod.") and k != "lod.mode" and not any(k in s.values for s in settings):
            raise SweepError(f"--sweep {k}: no swept LOD mode of {path} accepts {k[4:]!r}; "
                             f"sweep lod.mode too or set [lod] mode in the scene")
    return settings


# ---------------------------------------------------------------------------------------------------------------------
# running and measuring
# ---------------------------------------------------------------------------------------------------------------------


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


class _PairRenderer:
    """Proxy of the engine's renderer that writes only the PNGs of sampled frames ``f % k == 0`` and of their
    successors ``f + 1`` (the consecutive pairs of the flicker measure) when the engine is run with
    ``png_every=1``; the other frames are neither read back nor written. Everything else is delegated."""

    def __init__(self, renderer, every: int):
        self._inner, self._every = renderer, every

    def save_png(self, path):
        f = int(re.search(r"(\d+)", Path(path).name).group(1))
        if f % self._every in (0, 1 % self._every):
            return self._inner.save_png(path)
        return path

    def __getattr__(self, name):
        return getattr(self._inner, name)


def _run(scene, out_dir: Path, png_every: int, pairs: bool = False, sleep: float | None = None) -> tuple:
    """Run ``scene`` headless into ``out_dir``; with ``pairs`` the PNGs of frames ``f % png_every in (0, 1)``.

    ``sleep``: seconds of the test-only per-frame sleep (default: :func:`test_sleep_seconds` of this process).
    Returns (summary, frames.csv columns, sorted paths of the PNGs written)."""
    from crowd.engine import Engine

    sleep = test_sleep_seconds() if sleep is None else float(sleep)
    with Engine(scene, quiet=True) as engine:
        if sleep > 0:
            engine.selector = _SleepySelector(engine.selector, sleep)
        every = png_every
        if pairs and png_every:
            engine.renderer = _PairRenderer(engine.open_renderer(), png_every)
            every = 1
        r = engine.run(frames=scene.frames, out_dir=out_dir, png_every=every)
    return r.summary, read_frames_csv(out_dir / "frames.csv"), sorted(p for p in r.pngs if Path(p).is_file())


def _user_errors() -> tuple:
    """Exceptions that are bad input, not bugs (as ``crowd.cli`` treats them)."""
    from render.context import ContextError
    from sim.errors import AssetError as SimAssetError
    from sim.params import ParamError

    return CrowdError, SimAssetError, ParamError, ContextError


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
    except _user_errors() as e:
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


def _is_reference(scene) -> bool:
    """True when ``scene`` renders its own full-detail reference: mode none, common LOD keys at their defaults."""
    if scene.lod_mode != "none":
        return False
    try:
        from lod.keyframed_selection import LOD_COMMON_PARAMS
    except ImportError:
        return True
    common = dict(getattr(scene, "lod_common", ()) or ())
    return all(common.get(k, p.default) == p.default for k, p in LOD_COMMON_PARAMS.items())


def _reference_scene(scene):
    """The full-detail reference of ``scene``: LOD mode none, no LOD keys (per-frame selection)."""
    extra = {"lod_common": ()} if any(f.name == "lod_common" for f in dataclasses.fields(scene)) else {}
    return dataclasses.replace(scene, lod_mode="none", lod_params=(), **extra)


def _progress(total: int, quiet: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc="report", disable=quiet or not sys.stderr.isatty(), leave=False,
                file=sys.stderr, dynamic_ncols=True)


def finite_or_none(x):
    """JSON-safe number: non-finite floats become None."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


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
    img, ref : (h, w, 3) uint8, the frame and its NoLOD reference
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

    from render.image import read_png

    return read_png(io.BytesIO(data))


def metrics_task(run: dict, ref: dict, frame: int) -> dict:
    """:func:`frame_metrics` of sampled ``frame`` of a run against its reference run (both :func:`run_task`
    results); the pair (frame, frame + 1) feeds the flicker measure when both runs wrote the successor."""
    name, nxt = f"frames/frame_{frame:05d}.png", f"frames/frame_{frame + 1:05d}.png"
    a, b = run["files"], ref["files"]
    pair = nxt in a and nxt in b
    return frame_metrics(_png(a[name]), _png(b[name]), _png(a[nxt]) if pair else None,
                         _png(b[nxt]) if pair else None)


#: default ``--cluster``: an embedded dask LocalCluster on loopback
DEFAULT_CLUSTER = "local"
#: ``--cluster`` value that runs everything in this process, serially
NO_CLUSTER = "none"
#: seconds to wait for a scheduler (``--cluster tcp://...``) and for its first worker
CONNECT_TIMEOUT_S = 10


class _Done:
    """An in-process result with the part of the ``distributed.Future`` interface the pool uses."""

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


def _host(address: str) -> str:
    """``tcp://10.0.0.5:40123`` -> ``10.0.0.5`` (a worker's machine)."""
    rest = address.split("://", 1)[-1]
    return rest.rsplit(":", 1)[0] if ":" in rest else rest


class ClusterPool:
    """Where the work of ``crowd report`` and ``crowd build`` runs: dask.distributed, or this process.

    Parameters
    ----------
    cluster : str or None
        ``"local"`` (the default): an embedded ``LocalCluster`` on loopback (127.0.0.1, no dashboard), one
        single-threaded worker process per core of this machine, no memory limit (``crowd.memory`` guards the
        scenes), and dask's per-worker thread pinning (``OMP_NUM_THREADS=1`` ...) left out, so a timed run has
        the same numba, BLAS and llvmpipe threads as ``crowd run``. ``tcp://HOST:PORT``: a running scheduler
        (its workers need this package and the scenes' assets at the same paths; ``crowd build`` also needs
        the cache folder on a filesystem the workers share). ``"none"`` or None: this process, serially.

    Notes
    -----
    Scheduling. :meth:`timed` runs the timed work so that no two timed runs share a machine's cores: the
    workers are grouped by host (the host part of their addresses), each host gets one queue, and a host's
    next timed task is submitted (pinned to that host's workers) only when its previous one has finished;
    different hosts time in parallel. :meth:`timed` returns when all are done, and the report submits
    nothing else meanwhile, so no image-error work, reference run or build runs beside a timed run either
    (on any host of the cluster; other clients of a shared cluster are not controlled). Untimed work
    (:meth:`submit`) fills every worker. Results move between workers as futures; the client only writes
    them to the report folder.

    Raises
    ------
    crowd.errors.CrowdError
        dask.distributed is not installed, the address is malformed, or the scheduler cannot be reached.
    """

    def __init__(self, cluster: str | None = DEFAULT_CLUSTER):
        if cluster is not None and cluster != NO_CLUSTER and cluster != "local" and "://" not in cluster:
            raise CrowdError(f"--cluster {cluster!r}: expected 'local' (an embedded dask LocalCluster), 'none' "
                             "(this process) or the address tcp://HOST:PORT of a running dask scheduler")
        self.cluster_arg = None if cluster == NO_CLUSTER else cluster
        self._cluster, self._client = None, None
        self.description = "this process"

    @property
    def distributed(self) -> bool:
        """True when the work runs on a dask cluster."""
        return self._client is not None

    def __enter__(self):
        if self.cluster_arg is None:
            return self
        try:
            import dask
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise CrowdError(f"--cluster {self.cluster_arg}: dask.distributed is not installed "
                             "(pip install 'crowd-sandbox[report]' or pip install dask distributed); "
                             "--cluster none runs in this process") from None
        import logging
        import os
        import warnings

        try:
            if self.cluster_arg == "local":
                n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
                env = {k: v for k, v in (dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {}).items()
                       if not k.endswith("_NUM_THREADS")}
                with dask.config.set({"distributed.nanny.pre-spawn-environ": env}), warnings.catch_warnings():
                    warnings.filterwarnings("ignore", message=".*already in use")  # its HTTP port: any free one
                    self._cluster = LocalCluster(n_workers=max(1, n), threads_per_worker=1, processes=True,
                                                 host="127.0.0.1", dashboard_address=None, memory_limit=0,
                                                 silence_logs=logging.ERROR)
                self._client = Client(self._cluster)
                self.description = (f"embedded dask LocalCluster {self._cluster.scheduler_address} "
                                    f"({max(1, n)} single-threaded workers)")
            else:
                self._client = Client(self.cluster_arg, timeout=f"{CONNECT_TIMEOUT_S}s")
                self._client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
                self.description = f"dask scheduler {self.cluster_arg}"
        except (OSError, TimeoutError, ValueError) as e:
            self.__exit__()
            raise CrowdError(f"--cluster {self.cluster_arg}: cannot connect ({type(e).__name__}: {e}); expected "
                             "'local', 'none' or the address tcp://HOST:PORT of a running dask scheduler with "
                             "workers") from None
        return self

    def hosts(self) -> dict:
        """host -> sorted worker addresses on it ({"this process": []} without a cluster)."""
        if self._client is None:
            return {"this process": []}
        out = {}
        for addr, info in self._client.scheduler_info(n_workers=-1)["workers"].items():
            out.setdefault(info.get("host") or _host(addr), []).append(addr)
        return {h: sorted(v) for h, v in sorted(out.items())}

    def submit(self, fn, *args):
        """``fn(*args)`` as untimed work; args may be results of :meth:`submit`/:meth:`timed` (handles).
        Returns a handle (a ``distributed.Future``, or a finished in-process result)."""
        if self._client is None:
            return _Done(fn(*[a.value if isinstance(a, _Done) else a for a in args]))
        return self._client.submit(fn, *args, pure=False)

    def results(self, handles: list, done=None) -> list:
        """Values of ``handles`` in order; ``done()`` is called as each one finishes."""
        if self._client is None:
            for _ in handles:
                if done is not None:
                    done()
            return [h.value for h in handles]
        from distributed import as_completed

        for _ in as_completed(handles):
            if done is not None:
                done()
        return [h.result() for h in handles]

    def timed(self, fn, jobs: list, done=None) -> list:
        """``fn(*args)`` for each args of ``jobs``, never two on one host at a time (class Notes).

        Returns
        -------
        list of (handle, value) in the order of ``jobs``; ``done(value)`` is called as each one finishes.
        """
        out = [None] * len(jobs)
        if self._client is None:
            for i, a in enumerate(jobs):
                v = fn(*a)
                out[i] = (_Done(v), v)
                if done is not None:
                    done(v)
            return out
        from distributed import as_completed

        pending = list(enumerate(jobs))
        running, ac = {}, as_completed()

        def start(host, workers):
            if pending:
                i, a = pending.pop(0)
                f = self._client.submit(fn, *a, workers=workers, allow_other_workers=False, pure=False)
                running[f.key] = (i, host, workers)
                ac.add(f)

        for host, workers in self.hosts().items():
            start(host, workers)
        for f in ac:
            i, host, workers = running.pop(f.key)
            v = f.result()
            out[i] = (f, v)
            if done is not None:
                done(v)
            start(host, workers)
        return out

    def map(self, fn, args: list) -> list:
        """``[fn(*a) for a in args]`` as untimed work, results in order (array arguments are scattered to the
        workers, so they need no shared filesystem)."""
        if self._client is None:
            return [fn(*a) for a in args]
        futures, held = [], []
        for a in args:
            # hash=False: equal images (a NoLOD frame is its own reference) must not share, and then lose, one key;
            # the scattered futures are held until the results are back
            parts = self._client.scatter([x for x in a if x is not None], hash=False)
            held.append(parts)
            it = iter(parts)
            futures.append(self._client.submit(fn, *[next(it) if x is not None else None for x in a], pure=False))
        try:
            return self._client.gather(futures)
        finally:
            del held

    def __exit__(self, *exc):
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        shutdown_dask(client, cluster)


#: the former name (image-error work only); same class
MetricsPool = ClusterPool


def shutdown_dask(client=None, cluster=None) -> None:
    """Close a dask client, then a cluster, quietly.

    Closing a ``LocalCluster`` waits a fixed 5 s (``distributed.nanny.Nanny.close``) for each worker process to
    exit before killing it; on a loaded machine that wait can time out after the work is complete, which is no
    error of the report: the timeout and the log lines it causes are swallowed (the processes are killed).
    """
    import asyncio
    import logging

    loggers = [logging.getLogger(n) for n in ("distributed", "tornado.application", "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    try:
        for obj in (client, cluster):
            if obj is None:
                continue
            try:
                obj.close()
            except (TimeoutError, asyncio.TimeoutError, asyncio.CancelledError, OSError, RuntimeError):
                pass
    finally:
        for lg, lv in zip(loggers, levels):
            lg.setLevel(lv)


@dataclass
class ReportResult:
    out_dir: Path
    data: dict  # as report.json


def load_baseline(path) -> dict:
    """The report.json of a baseline report directory (``--compare``).

    Raises
    ------
    crowd.errors.CrowdError
        The directory has no readable report.json of a crowd report.
    """
    import json

    f = Path(path) / "report.json"
    try:
        data = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise CrowdError(f"--compare {path}: cannot read {f} ({type(e).__name__}); expected the directory of an "
                         f"earlier `crowd report` run") from None
    if not isinstance(data, dict) or not isinstance(data.get("scenes"), list):
        raise CrowdError(f"--compare {path}: {f} is not a crowd report (no 'scenes' list)")
    return data


def _timing(entry: dict) -> tuple:
    """(median ms, relative spread, runs) of a setting entry: the median of its repeated runs' median frame times
    and ``1.4826 * MAD / median`` of them (0 for one run; reports without repeats use their p50)."""
    meds = [float(x) for x in (entry.get("repeat_medians_ms") or []) if x is not None]
    if not meds:
        p50 = (entry.get("frame_ms") or {}).get("p50")
        meds = [float(p50)] if p50 is not None else []
    if not meds:
        return math.nan, math.nan, 0
    m = float(np.median(meds))
    mad = float(np.median(np.abs(np.asarray(meds) - m)))
    spread = MAD_TO_SIGMA * mad / m if m > 0 else 0.0
    return m, spread, len(meds)


def compare_reports(current: dict, baseline: dict, min_regression: float = MIN_REGRESSION,
                    noise_k: float = NOISE_K) -> list:
    """Frame-time comparison per (scene name, setting label) present in both reports.

    The rule (module docstring): ``ratio = median_current / median_baseline``;
    ``threshold = max(min_regression, noise_k * max(spread_current, spread_baseline))``;
    ``regression = ratio > 1 + threshold``.

    Returns
    -------
    list of dict: scene, label, current_ms, baseline_ms, ratio, spread_current,
    spread_baseline, threshold, runs_current, runs_baseline, regression (bool);
    settings without a counterpart in the baseline are left out.
    """
    base = {(sc.get("name"), st.get("label")): st for sc in baseline.get("scenes", [])
            for st in sc.get("settings", [])}
    rows = []
    for sc in current.get("scenes", []):
        for st in sc.get("settings", []):
            b = base.get((sc["name"], st["label"]))
            if b is None:
                continue
            mc, sc_, nc = _timing(st)
            mb, sb, nb = _timing(b)
            if not (math.isfinite(mc) and math.isfinite(mb) and mb > 0):
                continue
            ratio = mc / mb
            thr = max(min_regression, noise_k * max(sc_, sb))
            rows.append({"scene": sc["name"], "label": st["label"], "current_ms": mc, "baseline_ms": mb,
                         "ratio": ratio, "spread_current": sc_, "spread_baseline": sb, "threshold": thr,
                         "runs_current": nc, "runs_baseline": nb, "regression": bool(ratio > 1.0 + thr)})
    return rows


def build_report(scene_paths: list, sweeps: list, frames: int | None = None, size: tuple | None = None,
                 out: str | Path = "out/report", sample_every: int | None = None, quiet: bool = False,
                 repeat: int | None = None, baseline: dict | None = None, baseline_dir: str | None = None,
                 cluster: str | None = DEFAULT_CLUSTER) -> ReportResult:
    """Run every scene x setting plus references, measure, and write the report directory atomically.

    Parameters
    ----------
    scene_paths : list of scene file paths
    sweeps : list of (key, values) (:func:`parse_sweep`)
    frames, size : overrides of every scene's ``frames`` and ``[render] size``
    out : report directory (replaced atomically)
    sample_every : compare every k-th frame (default: ``frames // 4``, at least 1)
    quiet : no progress bar
    repeat : timed runs per setting (default 3 with a baseline, else 1); the first run's images are compared,
        every run's median frame time goes into ``repeat_medians_ms``.
    baseline : a baseline report.json (:func:`load_baseline`); the comparison goes into ``data["compare"]``
        and the page
    baseline_dir : the baseline's directory, as shown on the page
    cluster : ``"local"`` (default, an embedded dask LocalCluster), ``"none"``/None (this process) or the
        address of a dask scheduler (``tcp://HOST:PORT``): see :class:`ClusterPool`.

    Notes
    -----
    Two phases. First every timed run (each setting ``repeat`` times, all scenes) through
    :meth:`ClusterPool.timed`: one at a time per host, nothing else running. Then, in parallel on every
    worker, the NoLOD reference runs (untimed) and the image error of every sampled frame
    (:func:`metrics_task`). The client writes the runs' files, plots and the page.

    Raises
    ------
    crowd.errors.CrowdError
        Bad scene, sweep or ``cluster`` (before anything runs or is written); a user error raised by a run
        (e.g. a broken asset) is raised here with its message, and nothing is written.
    """
    from crowd.image_metrics import flip_available
    from crowd.output import atomic_dir, check_output_dir
    from render.image import write_png

    all_settings = [(Path(p), expand_settings(p, sweeps, size=size, frames=frames)) for p in scene_paths]
    names = [s[0].scene.name for _, s in all_settings]
    slugs = _unique_slugs(names)
    out = check_output_dir(out)
    repeat = int(repeat) if repeat is not None else (3 if baseline is not None else 1)
    if repeat < 1:
        raise CrowdError(f"--repeat {repeat}: expected a positive number of runs per setting")
    sleep = test_sleep_seconds()  # a bad test-only setting fails before anything runs
    pool = ClusterPool(cluster)  # a malformed address fails here, before anything runs
    ks = [sample_every or max(1, settings[0].scene.frames // DEFAULT_SAMPLES) for _, settings in all_settings]
    # reference runs: one per scene and size, unless a setting of mode none without LOD keys is its own
    refs_needed = []
    for (_, settings), k in zip(all_settings, ks):
        own = {tuple(st.scene.render.size) for st in settings if _is_reference(st.scene)}
        refs_needed.append(sorted({tuple(st.scene.render.size) for st in settings} - own))
    n_timed = sum(repeat * len(s) for _, s in all_settings)
    n_refs = sum(len(r) for r in refs_needed)
    n_metrics = sum(len(s) * len(range(0, s[0].scene.frames, k)) for (_, s), k in zip(all_settings, ks))
    data = {"scenes": [], "flip": flip_available(), "sweeps": [[k, v] for k, v in sweeps], "machine": None,
            "repeat": repeat}
    with pool, atomic_dir(out) as tmp, _progress(n_timed + n_refs + n_metrics, quiet) as bar:
        data["cluster"] = pool.description
        data["hosts"] = {h: len(w) for h, w in pool.hosts().items()}
        for d in ("plots", "samples", "runs"):
            (tmp / d).mkdir()

        # phase 1: timed runs, never two on one host, nothing else running
        jobs, where = [], []
        for si, ((_, settings), k) in enumerate(zip(all_settings, ks)):
            for st in settings:
                for i in range(repeat):  # the first run writes the sampled frames; repeats are timing only
                    jobs.append((st.scene, k if i == 0 else 0, i == 0, sleep))
                    where.append((si, st, i))
        bar.set_postfix_str(f"timed runs on {pool.description}")

        def timed_done(v):
            _checked(v)
            bar.update(1)

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

        # phase 2: reference runs and image error, in parallel on every worker
        bar.set_postfix_str("references and image error")
        ref_handles = {}
        for si, (_, settings) in enumerate(all_settings):
            for sz in refs_needed[si]:
                scene = _reference_scene(next(st.scene for st in settings if tuple(st.scene.render.size) == sz))
                ref_handles[si, sz] = pool.submit(run_task, scene, ks[si], True, 0.0)
        mjobs, mhandles = [], []
        for si in range(len(all_settings)):
            for run in runs_of[si]:
                sz = tuple(run.setting.scene.render.size)
                if (si, sz) in ref_handles:
                    ref = ref_handles[si, sz]
                else:  # a NoLOD setting of this size is the reference
                    ref = first[id(next(r for r in runs_of[si] if _is_reference(r.setting.scene)
                                        and tuple(r.setting.scene.render.size) == sz))][0]
                handle = first[id(run)][0]
                for name in first[id(run)][1]["pngs"]:
                    frame = int(re.search(r"(\d+)", name).group(1))
                    if frame % ks[si] == 0:  # not the second frame of a flicker pair
                        mjobs.append((si, run, frame, ref))
                        mhandles.append(pool.submit(metrics_task, handle, ref, frame))
        ref_values = dict(zip(ref_handles, pool.results(list(ref_handles.values()), done=lambda: bar.update(1))))
        for (si, sz), v in ref_values.items():
            _checked(v)
            data["schedule"].append({"kind": "reference", "scene": names[si], "label": f"{sz[0]}x{sz[1]}", "run": 0,
                                     "host": v.get("host"), "start": v.get("start"), "end": v.get("end")})
            _write_files(tmp / "runs" / slugs[si] / f"reference_{sz[0]}x{sz[1]}", v["files"])
        results = pool.results(mhandles, done=lambda: bar.update(1))

        for si, (path, settings) in enumerate(all_settings):
            slug, k = slugs[si], ks[si]
            for (sj, run, frame, ref), m in zip(mjobs, results):
                if sj != si:
                    continue
                sz = tuple(run.setting.scene.render.size)
                ref_dir = (tmp / "runs" / slug / f"reference_{sz[0]}x{sz[1]}" if (si, sz) in ref_handles
                           else next(r.out_dir for r in runs_of[si] if _is_reference(r.setting.scene)
                                     and tuple(r.setting.scene.render.size) == sz))
                base = f"{slug}_{run.setting.slug}_f{frame:05d}"
                shutil.copyfile(run.out_dir / "frames" / f"frame_{frame:05d}.png", tmp / "samples" / f"{base}.png")
                shutil.copyfile(ref_dir / "frames" / f"frame_{frame:05d}.png", tmp / "samples" / f"{base}_ref.png")
                m = dict(m)
                write_png(tmp / "samples" / f"{base}_err.png", m.pop("error_png"))
                run.metrics.append({"frame": frame, **m, "image": f"samples/{base}.png",
                                    "reference": f"samples/{base}_ref.png", "error": f"samples/{base}_err.png"})
            scene_entry = {"name": names[si], "slug": slug, "file": str(path), "frames": settings[0].scene.frames,
                           "sample_every": k, "settings": []}
            for run in runs_of[si]:
                scene_entry["settings"].append(_setting_entry(run, tmp))
                if data["machine"] is None:
                    data["machine"] = run.summary.get("machine")
            _plots(tmp, scene_entry, runs_of[si])
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
    return ReportResult(out_dir=out, data=data)


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


def frame_seconds(columns: dict) -> np.ndarray:
    """Per-frame time, seconds: the sum of the stage columns of frames.csv (simulate, select, upload, draw,
    finish). Unlike ``total`` it leaves out the PNG writes of the sampled frames, which would otherwise
    inflate exactly the frames that are compared, and telemetry bookkeeping."""
    return sum(np.nan_to_num(columns[k]) for k in STAGE_COLUMNS if k in columns)


def _setting_entry(run: RunData, tmp: Path) -> dict:
    from crowd.telemetry import stats

    s, st = run.summary, run.setting
    stages = s["stages"]
    ft = stats(frame_seconds(run.columns))
    return {"label": st.label, "slug": st.slug, "values": st.values, "lod_mode": st.scene.lod_mode,
            "host": run.host,
            "lod_params": dict(st.scene.lod_params), "size": list(st.scene.render.size),
            "run_dir": str(run.out_dir.relative_to(tmp)),
            "frame_ms": {q: ft[q] * 1e3 for q in ("mean", "p50", "p95", "p99", "max")},
            "repeat_medians_ms": [m * 1e3 for m in run.repeat_medians],
            "stage_ms": {k: stages[k]["mean"] * 1e3 for k in STAGE_COLUMNS if stages.get(k)},
            "gpu_ms": (stages["gpu"]["p50"] * 1e3) if stages.get("gpu") else None,
            "triangles": s["counts"]["triangles"]["mean"], "points": s["counts"]["points"]["mean"],
            "instances": s["counts"]["instances"]["mean"],
            "accuracy": aggregate(run.metrics), "samples": run.metrics}


def _json_safe(obj):
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        obj = obj.item()
    return finite_or_none(obj)


# ---------------------------------------------------------------------------------------------------------------------
# plots (matplotlib, Agg)
# ---------------------------------------------------------------------------------------------------------------------


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
    ax.set_ylabel(name + " vs NoLOD")
    ax.set_title(f"{entry['name']}: accuracy against time")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    plots["pareto"] = _save(fig, tmp, f"plots/{slug}_pareto.png")
    entry["pareto_front"] = [sets[i]["slug"] for i in front]
    entry["pareto_error"] = name


def _save(fig, tmp: Path, rel: str) -> str:
    import io

    from crowd.output import write_atomic

    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png")
    _plt().close(fig)
    write_atomic(tmp / rel, buf.getvalue())
    return rel


# ---------------------------------------------------------------------------------------------------------------------
# HTML
# ---------------------------------------------------------------------------------------------------------------------

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


def render_html(data: dict) -> str:
    """The report page: only relative links to ``plots/`` and ``samples/``; no scripts, no external resources."""
    e = html.escape
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8"><title>crowd report</title>',
           f"<style>{_CSS}</style></head><body>", "<h1>crowd report</h1>"]
    if data["sweeps"]:
        out.append("<p>Sweeps: " + "; ".join(e(f"{k} = {', '.join(_fmt_value(x) for x in v)}")
                                               for k, v in data["sweeps"]) + "</p>")
    out.append("<p>Accuracy is measured against full-detail (NoLOD) reference frames at the same simulated time and "
               "camera: PSNR (of the mean MSE over the sampled frames), mean SSIM (Wang et al. 2004), mean FLIP "
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
        out.append("<table><tr><th>setting</th><th>size</th><th>p50 ms</th><th>p95 ms</th><th>p99 ms</th>"
                   "<th>max ms</th><th>mean ms: " + " / ".join(STAGE_COLUMNS) + "</th><th>GPU p50 ms</th>"
                   "<th>triangles/frame</th><th>points/frame</th><th>PSNR dB</th><th>SSIM</th><th>FLIP</th>"
                   "<th>flicker</th>"
                   "<th>Pareto</th></tr>")
        for s in sc["settings"]:
            fm, a = s["frame_ms"], s["accuracy"]
            stages = " / ".join(f"{s['stage_ms'].get(k, 0.0):.2f}" for k in STAGE_COLUMNS)
            out.append(f"<tr class='setting'><td>{e(s['label'])}</td><td>{s['size'][0]}x{s['size'][1]}</td>"
                       + "".join(f"<td class='n'>{fm[q]:.2f}</td>" for q in ("p50", "p95", "p99", "max"))
                       + f"<td class='n'>{stages}</td><td class='n'>{_num(s['gpu_ms'])}</td>"
                       f"<td class='n'>{s['triangles']:,.0f}</td><td class='n'>{s['points']:,.0f}</td>"
                       f"<td class='n'>{_num(a['psnr'])}</td><td class='n'>{_num(a['ssim'], '{:.4f}')}</td>"
                       f"<td class='n'>{_num(a['flip'], '{:.4f}')}</td>"
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
                   "R the NoLOD reference's: the temporal change the reference does not have (LOD popping, "
                   "shimmer); 0 when the setting changes exactly as the reference does.</p>"
                   f"<img src='{e(p['flicker'])}' alt='flicker'>")
        out.append(f"<h3>Accuracy against time ({e(sc['pareto_error'])})</h3>"
                   f"<img src='{e(p['pareto'])}' alt='pareto'>")
        out.append("<h3>Sample frames</h3><table class='samples'><tr><th>setting</th><th>frame</th><th>frame</th>"
                   "<th>NoLOD reference</th><th>error map</th><th>PSNR / SSIM / FLIP</th></tr>")
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
