"""A linear model of a frame's rendering cost, fitted to measured frames.

The frame time of a draw list is modelled as a non-negative combination of
the work it submits (issue 7, "a cost model"; the classic per-primitive /
per-call cost decomposition of Funkhouser & Séquin, "Adaptive Display
Algorithm for Interactive Frame Rates During Visualization of Complex
Virtual Environments", SIGGRAPH 1993, §4.1)::

    seconds ≈ c_frame + c_tri·triangles + c_splat·points + c_draw·batches
              + c_inst·instances + c_cluster·clusters
              + c_pass·pixels + c_area·pixels·s²     (when any point is splatted)
              + c_pinst·point_instances + c_cpath·[any cluster cut drawn]

The last two terms are the point splatting pass of ``render/points/draw.py``
(clearing and resolving a depth/colour buffer of the whole viewport,
gathering s x s anchors per pixel for splat size s; Schütz, Kerbl & Wimmer
2021): a per-frame cost that does not depend on how many points are drawn,
and on llvmpipe at 1280x720 the largest single term of a points frame.
``instances`` counts the instances of the triangle and cluster paths (GPU
skinning with a per-instance palette pre-pass), ``point_instances`` those
drawn from point hierarchies (keyframed: no palette, a job table instead),
whose per-instance cost is much lower. ``cluster_frames`` is 1 when the
frame draws any cluster cut (the cluster drawer's fixed work per frame).

The coefficients are fitted by non-negative least squares
(:func:`scipy.optimize.nnls`, Lawson & Hanson 1974) to frames measured on the
machine at hand (``crowd calibrate``, :mod:`crowd.calibrate`), and stored as
JSON per machine and GL renderer string under ``$CROWD_CACHE_DIR`` (default
``~/.cache/crowd``) in ``cost_model.json``; writes are atomic (temp file +
rename). Without a calibration for the current (machine, renderer) the
defaults :data:`DEFAULTS` apply, taken from the figures measured on the
development machine (llvmpipe, 1280x720: ~8 M triangles/s instanced,
~27 M splats/s compute-shader splatting).

This module is pure numpy/scipy: ``lod`` imports only ``sim``; the renderer
string is passed in by the caller.
"""
from __future__ import annotations

import json
import os
import platform
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.atomic_io import atomic_open

#: feature names, in the order of :attr:`CostModel.coefficients` (after ``frame``): what ``crowd calibrate`` fits
FEATURES = ("triangles", "points", "batches", "instances", "clusters", "splat_pixels", "splat_area",
            "point_instances", "cluster_frames")
#: coefficient names: the constant per frame, then one per feature (seconds per unit)
COEFFICIENTS = ("frame",) + FEATURES
#: defaults (seconds per unit) when no calibration exists for this machine and renderer
DEFAULTS = {
    "frame": 1.0e-3,  # clear + palette set-up + finish
    "triangles": 1.0 / 8.0e6,  # ~8 M triangles/s instanced (llvmpipe, 1280x720)
    "points": 1.0 / 27.0e6,  # ~27 M splats/s compute-shader splat
    "batches": 5.0e-5,  # one instanced draw call + state changes
    "instances": 3.0e-5,  # instance upload + palette pre-pass (llvmpipe calibration: ~30 us)
    "clusters": 2.0e-7,  # one cluster record in a cluster cut
    "splat_pixels": 3.0e-8,  # point pass: clear + resolve, per viewport pixel (llvmpipe: ~28 ms at 1280x720)
    "splat_area": 3.5e-9,  # point pass: per viewport pixel and squared splat size (s x s anchors gathered)
    "point_instances": 5.0e-6,  # one instance drawn from a point hierarchy (job table, no skinning palette)
    "cluster_frames": 5.0e-3,  # the cluster drawer's per-frame work when it draws anything (pre-pass, gather)
}
#: further counts a frame may report in ``DrawList.stats`` (the board's agreed interface: other draw paths add
#: theirs here). Only the online fit (:mod:`lod.auto.online`) prices them, from the frames it observes; a
#: count that stays 0 keeps its prior. ``raster_triangles``: triangles rasterised in compute (they leave the
#: ``triangles`` feature, which then counts the raster pipeline's only); ``poses`` and ``posed_vertices``:
#: distinct poses skinned and vertices skinned into the pose buffer; ``placed_points``: points placed per
#: pose; ``props``: triangles of props and obstacle solids (``crowd.world``); ``far``: agents drawn as one
#: far splat each (``lod.far``; they leave the ``points`` and ``instances`` features)
EXTRA_FEATURES = ("raster_triangles", "poses", "posed_vertices", "placed_points", "props", "far")
#: their priors (seconds per unit; guesses for llvmpipe at 1280x720, held with a wide uncertainty)
EXTRA_DEFAULTS = {
    "raster_triangles": 1.0 / 30.0e6,
    "poses": 2.0e-5,
    "posed_vertices": 1.0 / 50.0e6,
    "placed_points": 1.0 / 50.0e6,
    "props": 1.0 / 8.0e6,
    "far": 6.0e-8,  # the far splat and its share of the resolve (scenes/million.toml: ~60 ms for 1 M agents)
}
#: every feature the online fit prices, in its column order (a later version may append names: the fit's
#: state is rebuilt per run, so appending is no format break)
ONLINE_FEATURES = FEATURES + EXTRA_FEATURES
#: file name of the stored calibrations inside the cache folder
FILE_NAME = "cost_model.json"
#: bump when the stored layout changes
FORMAT_VERSION = 1
#: environment variable naming the cache folder (shared with the LOD caches)
CACHE_ENV = "CROWD_CACHE_DIR"


def cache_dir() -> Path:
    """The cache folder: ``$CROWD_CACHE_DIR`` or ``~/.cache/crowd``."""
    d = os.environ.get(CACHE_ENV, "")
    return Path(d).expanduser() if d else Path.home() / ".cache" / "crowd"


def machine_key(renderer: str = "") -> str:
    """``"<host>|<machine>|<GL renderer>"``: what a calibration is stored under."""
    return f"{platform.node()}|{platform.machine()}|{renderer or 'unknown'}"


def features(drawlist, extended: bool = False) -> np.ndarray:
    """(9,) float64 counts of a DrawList in :data:`FEATURES` order, or with
    ``extended`` (15,) in :data:`ONLINE_FEATURES` order.

    Triangles and points are summed over the batches (``stats`` when the
    selector recorded them), batches count non-empty batches, instances the
    instances of batches without point jobs,
    clusters come from ``stats["clusters"]`` (0 when absent); when points
    are drawn, ``splat_pixels`` is the viewport's pixel count and
    ``splat_area`` that times the squared splat size
    (``options["splat_size"]``, default 2), else both are 0;
    ``point_instances`` counts the instances of batches with point jobs
    (``point_jobs``, :class:`lod.points.rep.PointsBatch`); ``cluster_frames``
    is 1.0 when a batch carries a cluster cut (``offsets``,
    :class:`lod.clusters.mode.ClusterDrawBatch`), else 0. The extended
    counts (:data:`EXTRA_FEATURES`) come from ``stats`` (0 when absent or not
    a finite number >= 0); ``raster_triangles`` are taken out of ``triangles``, ``far`` agents (one splat
    each, ``lod.far``) out of ``points`` and ``instances``.
    """
    bs = [b for b in drawlist.batches if b.n_instances]
    st = getattr(drawlist, "stats", {}) or {}
    tri = st.get("triangles", sum(int(b.triangles) for b in bs))
    far = _count(st.get("far"))
    pts = max(0.0, float(st.get("points", sum(int(b.points) for b in bs))) - far)
    px = area = 0.0
    if pts:
        w, h = (int(v) for v in drawlist.size)
        s = float((getattr(drawlist, "options", {}) or {}).get("splat_size", 2))
        px = float(w * h)
        area = px * s * s
    pinst = float(sum(b.n_instances for b in bs if getattr(b, "point_jobs", None) is not None))
    inst = max(0.0, float(sum(b.n_instances for b in bs)) - pinst - far)
    cframe = 1.0 if any(getattr(b, "offsets", None) is not None for b in bs) else 0.0
    base = [float(tri), float(pts), float(len(bs)), inst, float(st.get("clusters", 0) or 0), px, area, pinst, cframe]
    if not extended:
        return np.array(base, np.float64)
    extra = [_count(st.get(k)) for k in EXTRA_FEATURES]
    base[0] = max(0.0, base[0] - extra[0])  # compute-rasterised triangles leave the pipeline's count
    return np.array(base + extra, np.float64)


def _count(v) -> float:
    try:
        v = float(v or 0.0)
    except (TypeError, ValueError):
        return 0.0
    return v if np.isfinite(v) and v > 0.0 else 0.0


def pass_cost(model, size, splat: float) -> float:
    """Predicted seconds of the point splatting pass at viewport ``size`` (w, h)
    and splat size ``splat`` pixels (the per-frame cost of drawing any point)."""
    c = model.coefficients
    px = float(int(size[0]) * int(size[1]))
    return c["splat_pixels"] * px + c["splat_area"] * px * float(splat) ** 2


@dataclass
class CostModel:
    """Coefficients (seconds per unit) of the linear frame-cost model.

    Attributes
    ----------
    coefficients : dict name -> float >= 0 for every name in :data:`COEFFICIENTS`
    key : the :func:`machine_key` it was calibrated for ("" = defaults)
    median_rel_error : median |predicted - measured| / measured of the fit
        (None for the defaults)
    samples : frames the fit used
    validation_rel_error : median |predicted - measured| / measured on draw
        lists held out of the fit (mixed lists of mode "auto"), or None
    """

    coefficients: dict = field(default_factory=lambda: dict(DEFAULTS))
    key: str = ""
    median_rel_error: float | None = None
    samples: int = 0
    validation_rel_error: float | None = None

    def __post_init__(self):
        c = dict(DEFAULTS)
        for k, v in dict(self.coefficients).items():
            if k not in DEFAULTS:
                raise ValueError(f"cost model: unknown coefficient {k!r}; accepted: {', '.join(COEFFICIENTS)}")
            v = float(v)
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f"cost model: coefficient {k!r} must be a finite number >= 0, got {v}")
            c[k] = v
        self.coefficients = c

    @property
    def vector(self) -> np.ndarray:
        """(10,) float64 coefficients in :data:`COEFFICIENTS` order."""
        return np.array([self.coefficients[k] for k in COEFFICIENTS], np.float64)

    @property
    def is_default(self) -> bool:
        return self.key == ""

    def predict_counts(self, triangles=0, points=0, batches=0, instances=0, clusters=0, splat_pixels=0,
                       splat_area=0, point_instances=0, cluster_frames=0):
        """Predicted seconds for the given counts (scalars or arrays broadcast together)."""
        c = self.coefficients
        return (c["frame"] + c["triangles"] * np.asarray(triangles, np.float64)
                + c["points"] * np.asarray(points, np.float64) + c["batches"] * np.asarray(batches, np.float64)
                + c["instances"] * np.asarray(instances, np.float64)
                + c["clusters"] * np.asarray(clusters, np.float64)
                + c["splat_pixels"] * np.asarray(splat_pixels, np.float64)
                + c["splat_area"] * np.asarray(splat_area, np.float64)
                + c["point_instances"] * np.asarray(point_instances, np.float64)
                + c["cluster_frames"] * np.asarray(cluster_frames, np.float64))

    def predict(self, drawlist) -> float:
        """Predicted seconds to render ``drawlist`` (a :class:`lod.drawlist.DrawList`)."""
        return float(self.vector[0] + self.vector[1:] @ features(drawlist))

    def to_dict(self) -> dict:
        return {"coefficients": dict(self.coefficients), "median_rel_error": self.median_rel_error,
                "samples": int(self.samples), "validation_rel_error": self.validation_rel_error}


def fit(X, y) -> tuple[np.ndarray, float]:
    """Non-negative least-squares fit of the frame model.

    Parameters
    ----------
    X : (n, 9) float64 feature counts (:func:`features`), n >= 1
    y : (n,) float64 measured seconds, finite and > 0

    Returns
    -------
    coef : (10,) float64 >= 0, in :data:`COEFFICIENTS` order
    median_rel_error : float, median of |X·coef - y| / y

    Each column is scaled to unit maximum before :func:`scipy.optimize.nnls`
    (counts span ~1 to ~1e7), and the rows are weighted by 1/y so that the
    fit minimises *relative* error (a slow frame does not dominate).
    Columns that are all zero get coefficient 0 (callers substitute defaults).
    """
    from scipy.optimize import nnls

    X = np.asarray(X, np.float64).reshape(-1, len(FEATURES))
    y = np.asarray(y, np.float64).reshape(-1)
    if X.shape[0] != y.shape[0] or X.shape[0] == 0:
        raise ValueError(f"cost model fit: expected matching non-empty samples, got {X.shape[0]} rows and "
                         f"{y.shape[0]} times")
    if not (np.isfinite(X).all() and np.isfinite(y).all() and (y > 0).all() and (X >= 0).all()):
        raise ValueError("cost model fit: counts must be finite and >= 0 and times finite and > 0")
    A = np.concatenate([np.ones((X.shape[0], 1)), X], axis=1)
    scale = A.max(axis=0)
    scale[scale <= 0] = 1.0
    w = 1.0 / y
    sol, _ = nnls(A / scale * w[:, None], y * w)
    coef = sol / scale
    pred = A @ coef
    return coef, float(np.median(np.abs(pred - y) / y))


def relative_error(model: CostModel, X, y) -> float:
    """Median |predicted - measured| / measured of ``model`` on feature rows
    ``X`` (n, 9) and measured seconds ``y`` (n,) > 0."""
    X = np.asarray(X, np.float64).reshape(-1, len(FEATURES))
    y = np.asarray(y, np.float64).reshape(-1)
    if X.shape[0] != y.shape[0] or X.shape[0] == 0 or not (y > 0).all():
        raise ValueError("cost model: relative_error needs matching non-empty samples with times > 0")
    pred = model.vector[0] + X @ model.vector[1:]
    return float(np.median(np.abs(pred - y) / y))


def fit_model(X, y, key: str = "") -> CostModel:
    """:func:`fit` as a :class:`CostModel`; features never exercised (an
    all-zero column) keep their :data:`DEFAULTS` coefficient."""
    coef, err = fit(X, y)
    X = np.asarray(X, np.float64).reshape(-1, len(FEATURES))
    used = np.concatenate([[True], X.max(axis=0) > 0])
    c = {k: (float(v) if u else DEFAULTS[k]) for k, v, u in zip(COEFFICIENTS, coef, used)}
    return CostModel(c, key=key, median_rel_error=err, samples=int(X.shape[0]))


def refine(prior: CostModel, X, y) -> CostModel:
    """The calibration rescaled to the frames observed while rendering.

    Every coefficient of ``prior`` is multiplied by one factor, the median
    (in log space) of measured / predicted over the observed frames, so that
    predictions follow the load and regime the engine really runs in (the
    machine is shared; the calibration's synthetic draw lists are smaller
    than a benchmark frame) while the *relative* costs of the
    representations, which decide mode auto's choices, stay those of the
    calibration: a per-coefficient refit from a few frames of one view is
    ill-conditioned (the features of consecutive frames are nearly
    collinear) and would distort them. The median makes one noisy frame
    harmless.

    Parameters
    ----------
    prior : CostModel
    X : (n, 9) float64 observed feature counts (:func:`features`), n >= 0
    y : (n,) float64 measured seconds; rows with y <= 0 or non-finite values are ignored

    Returns
    -------
    CostModel with the prior's key (``prior`` itself when no row is usable);
    ``median_rel_error`` on the observed rows, ``samples`` their number
    """
    X = np.asarray(X, np.float64).reshape(-1, len(FEATURES))
    y = np.asarray(y, np.float64).reshape(-1)
    ok = np.isfinite(X).all(axis=1) & np.isfinite(y) & (y > 0) & (X >= 0).all(axis=1)
    X, y = X[ok], y[ok]
    pred = prior.vector[0] + X @ prior.vector[1:]
    good = pred > 0
    if not good.any():
        return prior
    f = float(np.exp(np.median(np.log(y[good] / pred[good]))))
    if not (np.isfinite(f) and f > 0):
        return prior
    c = {k: v * f for k, v in prior.coefficients.items()}
    return CostModel(c, key=prior.key, median_rel_error=float(np.median(np.abs(pred * f - y) / y)),
                     samples=int(X.shape[0]), validation_rel_error=prior.validation_rel_error)


# ---------------------------------------------------------------------------- storage
#: what a bad calibration file falls back to (printed in its one line)
FALLBACK = "mode auto starts its online cost fit from the neutral prior (the defaults)"
_warned: set = set()


def _read_checked(path: Path) -> tuple[dict, str | None]:
    """(data, problem): the parsed file, or ({}, a sentence saying why it cannot be used); ({}, None) when
    there is no file."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return {}, None
    except OSError as e:
        return {}, f"cannot be read ({e.strerror or e})"
    try:
        d = json.loads(text)
    except ValueError as e:
        return {}, f"is not valid JSON ({e.msg} at line {e.lineno}); the file is corrupt"
    if not isinstance(d, dict) or not isinstance(d.get("machines"), dict):
        return {}, "is not a cost model file (expected an object with \"format\" and \"machines\")"
    if d.get("format") != FORMAT_VERSION:
        return {}, (f"has format {d.get('format')!r}, this version reads format {FORMAT_VERSION} (written by "
                    f"another version or tool)")
    return d, None


def _read(path: Path) -> dict:
    return _read_checked(path)[0]


def warn_once(path, problem: str) -> None:
    """One line on stderr naming ``path`` and ``problem`` and the fallback (once per process and message)."""
    import sys

    line = f"crowd: {path}: {problem}; {FALLBACK}"
    if line not in _warned:
        _warned.add(line)
        print(line, file=sys.stderr, flush=True)


def _entry_model(entry, k: str) -> tuple[CostModel, str | None]:
    """The model of one stored entry, or (defaults, problem). Coefficient names this version does not know
    are ignored (a later version may store more); a known one that is not a finite number >= 0 is a problem."""
    if not isinstance(entry, dict) or not isinstance(entry.get("coefficients", {}), dict):
        return CostModel(), f"the calibration of {k!r} is not an object of coefficients"
    coef = {}
    for name, v in entry.get("coefficients", {}).items():
        if name not in DEFAULTS:
            continue
        try:
            x = float(v)
        except (TypeError, ValueError):
            return CostModel(), f"coefficient {name!r} of {k!r} is not a number ({v!r})"
        if not (np.isfinite(x) and x >= 0.0):
            return CostModel(), f"coefficient {name!r} of {k!r} is {x!r}, not a finite number >= 0"
        coef[name] = x
    try:
        v = entry.get("validation_rel_error")
        e = entry.get("median_rel_error")
        return CostModel(coef, key=k, median_rel_error=float(e) if isinstance(e, (int, float)) else None,
                         samples=int(entry.get("samples", 0) or 0),
                         validation_rel_error=float(v) if isinstance(v, (int, float)) else None), None
    except (TypeError, ValueError) as err:
        return CostModel(), f"the calibration of {k!r} is malformed ({err})"


def save(model: CostModel, directory: Path | None = None) -> Path:
    """Store ``model`` under its key in ``cost_model.json`` (other machines'
    entries kept; a corrupt file is replaced); atomic write. Returns the file path."""
    if not model.key:
        raise ValueError("cost model: refusing to store a model without a machine key")
    d = Path(directory) if directory is not None else cache_dir()
    d.mkdir(parents=True, exist_ok=True)
    path = d / FILE_NAME
    data = _read(path) or {"format": FORMAT_VERSION, "machines": {}}
    data["machines"][model.key] = model.to_dict()
    with atomic_open(path, "w") as f:
        json.dump(data, f, indent=1, sort_keys=True)
    return path


def load_checked(renderer: str = "", directory: Path | None = None, key: str | None = None,
                 path: Path | None = None) -> tuple[CostModel, str | None]:
    """(model, problem) of this machine and GL ``renderer`` string (or ``key``; ``key=""``: the only or
    first host entry) from ``path`` (default ``cost_model.json`` in ``directory`` or the cache folder).

    The defaults (``key == ""``) and a sentence saying what is wrong when the file is corrupt, has another
    format, holds no calibration of this machine but others', or holds non-finite or negative costs;
    (defaults, None) when there is no file or no entry at all."""
    d = Path(directory) if directory is not None else cache_dir()
    path = Path(path) if path is not None else d / FILE_NAME
    data, problem = _read_checked(path)
    if problem:
        return CostModel(), problem
    machines = data.get("machines", {})
    if key == "":  # the first entry of this host (any renderer), else the file's only entry
        prefix = f"{platform.node()}|{platform.machine()}|"
        mine = [k_ for k_ in sorted(machines) if k_.startswith(prefix)]
        key = mine[0] if mine else None
        if key is None:
            if not machines:
                return CostModel(), None
            return CostModel(), (f"holds no calibration of this machine ({platform.node()}), only of "
                                 f"{', '.join(sorted(map(str, machines))[:3])}")
    k = machine_key(renderer) if key is None else key
    entry = machines.get(k)
    if entry is None:
        if machines and not any(str(m).startswith(f"{platform.node()}|") for m in machines):
            return CostModel(), (f"holds no calibration of this machine ({platform.node()}), only of "
                                 f"{', '.join(sorted(map(str, machines))[:3])}")
        return CostModel(), None
    return _entry_model(entry, k)


def load(renderer: str = "", directory: Path | None = None, key: str | None = None, warn: bool = True) -> CostModel:
    """The stored model of this machine and GL ``renderer`` string, or the
    defaults (``key == ""``) when none is stored or the file cannot be used
    (then, with ``warn``, one line on stderr: :func:`load_checked`)."""
    d = Path(directory) if directory is not None else cache_dir()
    model, problem = load_checked(renderer, d, key)
    if problem and warn:
        warn_once(d / FILE_NAME, problem)
    return model


def load_any(directory: Path | None = None, warn: bool = True) -> CostModel:
    """A model stored for this host (any renderer; the first key in sorted
    order), else the defaults. For ``lod`` code that has no GL context to ask
    for its renderer string. A file that cannot be used gives one line on stderr (``warn``)."""
    return load(directory=directory, key="", warn=warn)


def load_file(path, warn: bool = True) -> CostModel:
    """The model stored in a calibration file of one's own (``cost_model.json`` layout; this host's entry,
    else its only entry), else the defaults with one line on stderr (``warn``)."""
    path = Path(path)
    model, problem = load_checked(path=path, key="")
    if problem and "no calibration of this machine" in problem:
        data = _read(path)
        ms = data.get("machines", {})
        if len(ms) == 1:  # a file of one's own: its only entry, whatever machine wrote it
            (k, entry), = ms.items()
            model, problem = _entry_model(entry, str(k))
    if problem and warn:
        warn_once(path, problem)
    return model


__all__ = ["FEATURES", "COEFFICIENTS", "DEFAULTS", "EXTRA_FEATURES", "EXTRA_DEFAULTS", "ONLINE_FEATURES",
           "load_checked", "load_file", "warn_once", "CostModel", "features", "fit", "fit_model", "relative_error",
           "pass_cost", "refine", "save", "load", "load_any", "machine_key", "cache_dir"]
