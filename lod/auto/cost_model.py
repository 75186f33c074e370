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

The last two terms are the point splatting pass of ``render/points.py``
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

from lod.atomic_io import atomic_open

#: feature names, in the order of :attr:`CostModel.coefficients` (after ``frame``)
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


def features(drawlist) -> np.ndarray:
    """(9,) float64 counts of a DrawList in :data:`FEATURES` order.

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
    :class:`lod.clusters.mode.ClusterDrawBatch`), else 0.
    """
    bs = [b for b in drawlist.batches if b.n_instances]
    st = getattr(drawlist, "stats", {}) or {}
    tri = st.get("triangles", sum(int(b.triangles) for b in bs))
    pts = st.get("points", sum(int(b.points) for b in bs))
    px = area = 0.0
    if pts:
        w, h = (int(v) for v in drawlist.size)
        s = float((getattr(drawlist, "options", {}) or {}).get("splat_size", 2))
        px = float(w * h)
        area = px * s * s
    pinst = float(sum(b.n_instances for b in bs if getattr(b, "point_jobs", None) is not None))
    inst = float(sum(b.n_instances for b in bs)) - pinst
    cframe = 1.0 if any(getattr(b, "offsets", None) is not None for b in bs) else 0.0
    return np.array([float(tri), float(pts), float(len(bs)), inst, float(st.get("clusters", 0) or 0), px, area, pinst,
                     cframe], np.float64)


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
def _read(path: Path) -> dict:
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(d, dict) or d.get("format") != FORMAT_VERSION or not isinstance(d.get("machines"), dict):
        return {}
    return d


def save(model: CostModel, directory: Path | None = None) -> Path:
    """Store ``model`` under its key in ``cost_model.json`` (other machines'
    entries kept); atomic write. Returns the file path."""
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


def load(renderer: str = "", directory: Path | None = None, key: str | None = None) -> CostModel:
    """The stored model of this machine and GL ``renderer`` string, or the
    defaults (``key == ""``) when none is stored or the file is unreadable."""
    k = machine_key(renderer) if key is None else key
    d = Path(directory) if directory is not None else cache_dir()
    entry = _read(d / FILE_NAME).get("machines", {}).get(k)
    if not isinstance(entry, dict):
        return CostModel()
    try:
        v = entry.get("validation_rel_error")
        return CostModel(entry.get("coefficients", {}), key=k, median_rel_error=entry.get("median_rel_error"),
                         samples=int(entry.get("samples", 0)),
                         validation_rel_error=float(v) if isinstance(v, (int, float)) else None)
    except (TypeError, ValueError):
        return CostModel()


def load_any(directory: Path | None = None) -> CostModel:
    """A model stored for this host (any renderer; the first key in sorted
    order), else the defaults. For ``lod`` code that has no GL context to ask
    for its renderer string."""
    d = Path(directory) if directory is not None else cache_dir()
    machines = _read(d / FILE_NAME).get("machines", {})
    prefix = f"{platform.node()}|{platform.machine()}|"
    for k in sorted(machines):
        if k.startswith(prefix):
            return load(directory=d, key=k)
    return CostModel()


__all__ = ["FEATURES", "COEFFICIENTS", "DEFAULTS", "CostModel", "features", "fit", "fit_model", "relative_error",
           "pass_cost", "refine", "save", "load", "load_any", "machine_key", "cache_dir"]
