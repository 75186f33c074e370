"""A recorded crowd: the trajectories of a pedestrian experiment or simulator, read through PedPy's loaders.

A :class:`Recording` holds every person's recorded positions sorted by person and frame, in flat arrays:

    ids    : (P,) int64, the file's person ids
    start  : (P + 1,) int64, person p's rows are ``start[p] .. start[p + 1]``
    frames : (R,) float64, the recorded frame of each row (strictly increasing within a person)
    xy     : (R, 2) float64, metres in the file's floor plane (PedPy's x, y)

and answers, for any (fractional) frame, who is recorded then and where (:meth:`Recording.alive`,
:meth:`Recording.at`: linear interpolation between the person's two recorded frames around it, across gaps).

Formats (``format``; PedPy's loader of each, ``pedpy >= 1.5``):

=============  ==========================================  ==============================================
``format``     what                                        file name
=============  ==========================================  ==============================================
``txt``        PeTrack / PedPy text (and ``crowd run``'s    ``*.txt``
               own ``trajectories.txt``)
``jupedsim``   JuPedSim SQLite                             ``*.sqlite``
``vadere``     Vadere ``postvis.traj`` (needs frame_rate)  ``*.traj``
``pathfinder`` Pathfinder CSV or JSON export               ``*.csv`` (CSV), ``*.json`` (JSON)
``crowdit``    Crowdit CSV                                 (name it)
``viswalk``    Viswalk (PTV Vissim) pedestrian record       (name it)
=============  ==========================================  ==============================================

Units: PedPy reads the text format's unit from its header (``x/m``, ``x/cm``) and converts to metres; ``unit``
names it for a text file whose header does not (and must agree with a header that does). The other formats are
in metres; ``unit = "cm"`` scales one that is not.

A recording is parsed once: its columns are cached by content and memory-mapped on later runs, its frame-major form
streamed from the cache's files (:mod:`sim.replay.cache`, :mod:`sim.replay.frames`).

Bad input raises :class:`sim.params.ParamError` with one sentence naming the file: an unreadable or truncated
file, a format PedPy cannot read, NaN or infinite coordinates, duplicate (id, frame) rows, no rows at all.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.params import ParamError
from sim.replay.frames import FrameTable

#: formats and their loaders (pedpy function names); "pathfinder" picks CSV or JSON by the file's suffix
FORMATS = ("txt", "jupedsim", "vadere", "pathfinder", "crowdit", "viswalk")
#: a file's suffix -> its format when ``format`` is not given
SUFFIX_FORMATS = {".txt": "txt", ".sqlite": "jupedsim", ".traj": "vadere", ".csv": "pathfinder",
                  ".json": "pathfinder"}
#: units of recorded coordinates and their length in metres
UNITS = {"m": 1.0, "cm": 0.01}
#: a frame within this of a person's first or last recorded frame counts as recorded (float frame arithmetic)
FRAME_EPS = 1e-6


@dataclass
class Recording:
    """Every recorded person's positions (module docstring). ``source`` names the file, ``format`` its format,
    ``frame_rate`` the recorded frames per second."""

    source: str
    format: str
    frame_rate: float
    ids: np.ndarray
    start: np.ndarray
    frames: np.ndarray
    xy: np.ndarray
    #: (R,) float64 search keys of :meth:`at` (made from the other columns when not given: a cached entry has them)
    keys: np.ndarray | None = None
    #: (6, P) float64 rows: each person's first and last recorded frame, first position (x, y), last position
    #: (x, y) (made from the rows when not given: a cached entry has them, so opening one reads no row; the
    #: properties below are views of it)
    ends: np.ndarray | None = None
    #: the frame-major form the replay streams (``sim.replay.frames``): a cached entry's files, else built from
    #: the rows on first use (:meth:`frame_table`)
    table: FrameTable | None = None

    @property
    def persons(self) -> int:
        return int(self.ids.shape[0])

    @property
    def rows(self) -> int:
        return int(self.frames.shape[0])

    @property
    def first(self) -> np.ndarray:
        """(P,) float64 first recorded frame of each person."""
        return self._first

    @property
    def last(self) -> np.ndarray:
        """(P,) float64 last recorded frame of each person."""
        return self._last

    @property
    def first_xy(self) -> np.ndarray:
        """(P, 2) float64 first recorded position of each person."""
        return self._first_xy

    @property
    def last_xy(self) -> np.ndarray:
        """(P, 2) float64 last recorded position of each person."""
        return self._last_xy

    def frame_table(self) -> FrameTable:
        """The frame-major form (``sim.replay.frames``; built from the rows the first time when not cached)."""
        if self.table is None:
            self.table = FrameTable.from_rows(self.start, self.frames, self.xy)
        return self.table

    @property
    def first_frame(self) -> float:
        return self._first_frame

    @property
    def last_frame(self) -> float:
        return self._last_frame

    def alive(self, frame: float) -> np.ndarray:
        """(P,) bool: persons recorded at ``frame`` (between their first and last recorded frames, inclusive)."""
        f = float(frame)
        return (self.first <= f + FRAME_EPS) & (self.last >= f - FRAME_EPS)

    def at(self, persons: np.ndarray, frame) -> np.ndarray:
        """(k, 2) float64 positions of ``persons`` ((k,) indices) at ``frame`` (a number or (k,) numbers):
        linear between the two recorded frames around it, clamped to each person's first and last."""
        p = np.asarray(persons, np.int64)
        f = np.broadcast_to(np.asarray(frame, np.float64), p.shape)
        lo, hi = self.start[p], self.start[p + 1] - 1
        f = np.clip(f, self.frames[lo], self.frames[hi])
        # rows of person p are start[p] .. start[p+1]-1 with increasing frames: a global sorted key finds them
        k = np.searchsorted(self.keys, p * self._span + (f - self._f0), side="right") - 1
        k0 = np.clip(k, lo, hi)
        k1 = np.minimum(k0 + 1, hi)
        df = self.frames[k1] - self.frames[k0]
        a = np.where(df > 0, (f - self.frames[k0]) / np.where(df > 0, df, 1.0), 0.0)[:, None]
        return self.xy[k0] * (1.0 - a) + self.xy[k1] * a

    def __post_init__(self):
        if self.ends is None:
            lo, hi = self.start[:-1], self.start[1:] - 1
            self.ends = np.array([self.frames[lo], self.frames[hi], self.xy[lo, 0], self.xy[lo, 1], self.xy[hi, 0],
                                  self.xy[hi, 1]], np.float64).reshape(6, -1)
        e = np.asarray(self.ends, np.float64)  # (a cached entry's stays memory-mapped: views, no copy)
        self._first, self._last, self._first_xy, self._last_xy = e[0], e[1], e[2:4].T, e[4:6].T
        self._first_frame = float(self._first.min()) if self._first.size else 0.0
        self._last_frame = float(self._last.max()) if self._last.size else 0.0
        self._f0 = self.first_frame
        self._span = (self.last_frame - self._f0) + 2.0
        if self.keys is None:  # person p's rows sorted by frame, people back to back: one increasing key
            owner = np.repeat(np.arange(self.persons, dtype=np.float64), np.diff(self.start))
            self.keys = owner * self._span + (self.frames - self._f0)


def from_columns(ids, frames, xy, frame_rate: float, source: str = "recording", format: str = "txt") -> Recording:
    """A :class:`Recording` from unsorted rows (id, frame, x, y). Raises ParamError (naming ``source``) for no
    rows, non-finite values, duplicate (id, frame) rows or a frame rate that is not a positive number."""
    ids = np.asarray(ids)
    frames = np.asarray(frames, np.float64)
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    name = Path(source).name
    if not (np.isfinite(frame_rate) and frame_rate > 0):
        raise ParamError("frame_rate", f"{name}: the frame rate is {frame_rate!r}; expected a positive number")
    if ids.shape[0] == 0:
        raise ParamError("file", f"{name}: no trajectory rows")
    if not (ids.shape[0] == frames.shape[0] == xy.shape[0]):
        raise ParamError("file", f"{name}: the id, frame and position columns differ in length")
    bad = ~(np.isfinite(xy).all(axis=1) & np.isfinite(frames))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ParamError("file", f"{name}: {int(bad.sum())} row(s) hold NaN, infinite or missing values (the first: person "
                                 f"{ids[i]}, frame {frames[i]:g}); expected finite coordinates in every row")
    if not np.issubdtype(ids.dtype, np.integer):
        f = np.asarray(ids, np.float64)
        if not (np.isfinite(f).all() and (f == np.round(f)).all()):
            raise ParamError("file", f"{name}: person ids are not integers")
        ids = f.astype(np.int64)
    ids = ids.astype(np.int64)
    order = np.lexsort((frames, ids))
    ids, frames, xy = ids[order], frames[order], xy[order]
    dup = (np.diff(ids) == 0) & (np.diff(frames) == 0)
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        raise ParamError("file", f"{name}: {int(dup.sum())} duplicate (id, frame) row(s) (the first: person "
                                 f"{ids[i]}, frame {frames[i]:g}); expected one row per person and frame")
    uniq, first_row = np.unique(ids, return_index=True)
    start = np.append(first_row, ids.shape[0]).astype(np.int64)
    return Recording(source=str(source), format=format, frame_rate=float(frame_rate), ids=uniq.astype(np.int64),
                     start=start, frames=frames, xy=xy)


def format_of(path: Path, format: str | None) -> str:
    """The format of ``path``: ``format`` when given, else by its suffix (ParamError when the suffix says none)."""
    if format:
        return format
    fmt = SUFFIX_FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise ParamError("format", f"{path.name}: cannot tell the format from the suffix {path.suffix!r}; give "
                                   f"format = one of {', '.join(map(repr, FORMATS))}")
    return fmt


def _one_line(text: str, sentences: int = 2) -> str:
    """``text`` on one line, cut after its first ``sentences`` sentences (PedPy's messages run on)."""
    words = " ".join(str(text).split())
    parts = words.split(". ")
    return ". ".join(parts[:sentences]).rstrip(".")


def load(path, format: str | None = None, unit: str | None = None, frame_rate: float | None = None) -> Recording:
    """Read a recording through PedPy (module docstring), once: a file read before comes memory-mapped from the
    content-addressed cache (``sim.replay.cache``). Raises ParamError with one sentence naming the file."""
    path = Path(path)
    fmt = format_of(path, format)
    if fmt not in FORMATS:
        raise ParamError("format", f"expected one of {', '.join(map(repr, FORMATS))}, got {fmt!r}")
    if unit is not None and unit not in UNITS:
        raise ParamError("unit", f"{path.name}: unknown unit {unit!r}; expected one of "
                                 f"{', '.join(map(repr, UNITS))}")
    if not path.is_file():
        raise ParamError("file", f"file not found: {path}")
    if fmt == "vadere" and frame_rate is None:
        raise ParamError("frame_rate", f"{path.name}: a Vadere file needs frame_rate (frames per second to "
                                       "sample its event times at)")
    from sim.replay import cache

    try:
        k = cache.key(path, fmt, unit, frame_rate)
    except OSError as e:
        raise ParamError("file", f"{path.name}: cannot read ({e.strerror or e})") from None
    hit = cached(k, path, fmt)
    if hit is not None:  # read before: the columns memory-mapped, the frame-major rows streamed, no parse
        return hit
    rec = _read(path, fmt, unit, frame_rate)
    cache.save(k, rec)
    return rec


def cached(k: str, source, fmt: str) -> Recording | None:
    """The recording of cache entry ``k`` (``sim.replay.cache``; ``source`` names its file, ``fmt`` its format):
    its person-major columns memory-mapped and its frame-major table left in its files, so opening it reads no row;
    None when there is no whole entry."""
    from sim.replay import cache

    hit = cache.load(k)
    if hit is None:
        return None
    cols, meta, table = hit
    return Recording(source=str(source), format=fmt, frame_rate=float(meta["frame_rate"]), ids=cols["ids"],
                     start=cols["start"], frames=cols["frames"], xy=cols["xy"], keys=cols["keys"],
                     ends=cols["ends"], table=table)


def _read(path: Path, fmt: str, unit, frame_rate) -> Recording:
    """Parse a recording through PedPy (:func:`load` checked the arguments)."""
    try:
        import pedpy
    except ImportError:  # pragma: no cover - pedpy is a dependency
        raise ParamError("file", f"{path.name}: replaying a recording needs PedPy (pip install pedpy)") from None
    scale = 1.0
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if fmt == "txt":
                traj = pedpy.load_trajectory_from_txt(
                    trajectory_file=path, default_frame_rate=frame_rate,
                    default_unit=None if unit is None else (pedpy.TrajectoryUnit.METER if unit == "m"
                                                            else pedpy.TrajectoryUnit.CENTIMETER))
            elif fmt == "jupedsim":
                traj = pedpy.load_trajectory_from_jupedsim_sqlite(trajectory_file=path)
            elif fmt == "vadere":
                traj = pedpy.load_trajectory_from_vadere(trajectory_file=path, frame_rate=float(frame_rate))
            elif fmt == "pathfinder":
                loader = (pedpy.load_trajectory_from_pathfinder_json if path.suffix.lower() == ".json"
                          else pedpy.load_trajectory_from_pathfinder_csv)
                traj = loader(trajectory_file=path)
            elif fmt == "crowdit":
                traj = pedpy.load_trajectory_from_crowdit(trajectory_file=path)
            else:
                traj = pedpy.load_trajectory_from_viswalk(trajectory_file=path)
    except ParamError:
        raise
    except Exception as e:  # PedPy's, pandas', sqlite's and json's errors: one sentence naming the file
        raise ParamError("file", f"{path.name}: not a readable {fmt} trajectory file ({_one_line(e) or type(e).__name__})"
                         ) from None
    if fmt != "txt" and unit is not None:
        scale = UNITS[unit]
    d = traj.data
    missing = [c for c in ("id", "frame", "x", "y") if c not in d.columns]
    if missing:
        raise ParamError("file", f"{path.name}: PedPy read no {', '.join(missing)} column(s)")
    rate = float(traj.frame_rate)  # the header's or frame_rate (text, Vadere), else the format's own
    xy = np.stack([d["x"].to_numpy(np.float64), d["y"].to_numpy(np.float64)], axis=1) * scale
    return from_columns(d["id"].to_numpy(), d["frame"].to_numpy(np.float64), xy, rate, source=str(path), format=fmt)
