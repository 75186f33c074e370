"""Placement of agents: the ``[[placement]]`` groups of a scene file.

Each placement kind maps to ``(schema, build)``::

    PLACEMENTS[kind] = (dict[str, sim.params.Param], build)
    build(cfg, character_index, clip_index, rng, clip_duration=None) -> CrowdState

The scene loader validates a group's table with ``sim.params.validate(schema,
table, where)`` (keys ``kind``, ``character`` and ``clip`` are part of every
schema), resolves the character and clip names to indices, and calls ``build``
with the validated ``cfg`` and a ``numpy.random.Generator``. The groups are
joined with :func:`concat_states`, which also keeps the hierarchies built by
kind ``"hierarchy"`` (Wand & Straßer 2002, §3.6) for the ``instancing`` effect.

Kinds
-----
grid
    ``rows`` x ``cols`` agents, ``spacing = [dx, dz]`` metres, from ``origin``
    (the first agent's position), optional position ``jitter``.
list
    explicit ``positions = [[x, y, z], ...]`` and optional ``headings`` (deg).
random
    ``count`` agents uniformly in a rectangle ``size = [sx, sz]`` centred on
    ``center``, at least ``min_distance`` apart when that is feasible
    (dart throwing with a bounded number of tries; the rest fall back to
    uniform positions).
trajectories
    a recorded crowd (:mod:`sim.replay`): ``file`` read through PedPy (``format``, ``unit``,
    ``frame_rate`` where the file does not say them); each recorded person is an agent while recorded.
hierarchy
    hierarchical instantiation (:mod:`sim.instancing`): ``levels`` lists the
    layouts **innermost first** (``levels[0]`` arranges the single character,
    ``levels[1]`` replicates that group, ...); the whole is placed at
    ``origin`` rotated by ``yaw`` degrees.

Common keys: ``heading`` (degrees, or ``"random"``), ``phase`` (``"random"``:
uniform over the clip, ``"zero"``), ``scale`` and ``scale_jitter`` (uniform
scale in ``scale * (1 ± scale_jitter)``), ``speed`` (initial ground speed
along the heading, m/s).
"""
from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np
from numba import njit

from sim.config import PLACEMENT_RANDOM_PHASE_SPAN, PLACEMENT_RANDOM_TRIES
from sim.params import Param, ParamError
from sim.replay.recording import FORMATS as REPLAY_FORMATS
from sim.state import CrowdState


class FloatOrChoice(Param):
    """A number (with bounds) or one of the string ``choices`` (e.g. heading =
    45.0 or "random"). Subclass so ``sim.params`` stays unchanged."""

    def check(self, key: str, value: Any) -> Any:
        if isinstance(value, str):
            if self.choices and value in self.choices:
                return value
            raise ParamError(key, f"expected a number or one of {', '.join(map(repr, self.choices or ()))}, got {value!r}")
        return Param("float", min=self.min, max=self.max).check(key, value)

    def describe(self) -> str:
        return "float or one of " + ", ".join(map(repr, self.choices or ()))


def _common(kind: str) -> dict:
    return {
        "kind": Param("str", choices=(kind,), doc="placement kind"),
        "character": Param("str", doc="name of a [[characters]] entry"),
        "clip": Param("str", "", doc="clip name; empty = the character's first clip"),
        "heading": FloatOrChoice("float", 0.0, choices=("random",),
                                 doc="yaw in degrees about +Y (0 faces +Z), or \"random\""),
        "phase": Param("str", "random", choices=("random", "zero"),
                       doc="initial animation time: uniform over the clip, or 0"),
        "scale": Param("float", 1.0, min=1e-3, max=1e3, doc="uniform character scale"),
        "scale_jitter": Param("float", 0.0, min=0.0, max=0.9,
                              doc="relative uniform jitter of the scale, scale*(1±j)"),
        "speed": Param("float", 0.0, min=0.0, max=100.0,
                       doc="initial ground speed along the heading, m/s"),
    }


def _vec3_list(key: str, value: Any) -> np.ndarray:
    if not isinstance(value, list) or not value:
        raise ParamError(key, f"expected a non-empty list of [x, y, z], got {value!r}")
    out = np.empty((len(value), 3), np.float64)
    for i, v in enumerate(value):
        out[i] = Param("vec3").check(f"{key}[{i}]", v)
    return out


class _PositionsParam(Param):
    def check(self, key, value):
        _vec3_list(key, value)
        return [[float(x) for x in v] for v in value]


class _NumberListParam(Param):
    def check(self, key, value):
        if not isinstance(value, list):
            raise ParamError(key, f"expected a list of numbers, got {value!r}")
        return [Param("float").check(f"{key}[{i}]", v) for i, v in enumerate(value)]


class _LevelsParam(Param):
    def check(self, key, value):
        from sim.instancing import parse_levels

        parse_levels(value, key)  # raises ParamError
        return value


def _finish(state: CrowdState, cfg: dict, character_index: int, clip_index: int, rng,
            clip_duration: float | None, headings: np.ndarray | None = None) -> CrowdState:
    """Fill heading, velocity, scale, character, clip and phase of ``state``."""
    n = state.n
    if headings is None:
        h = cfg.get("heading", 0.0)
        if h == "random":
            headings = rng.uniform(-math.pi, math.pi, n)
        else:
            headings = np.full(n, math.radians(float(h)))
    state.heading[:] = np.asarray(headings, np.float64)
    # wrap to (-pi, pi]
    state.heading[:] = np.arctan2(np.sin(state.heading), np.cos(state.heading))
    speed = float(cfg.get("speed", 0.0))
    state.velocity[:, 0] = speed * np.sin(state.heading)
    state.velocity[:, 2] = speed * np.cos(state.heading)
    s, j = float(cfg.get("scale", 1.0)), float(cfg.get("scale_jitter", 0.0))
    state.scale[:] = (s * (1.0 + j * rng.uniform(-1.0, 1.0, n))) if j > 0 else s
    state.character[:] = int(character_index)
    state.clip[:] = int(clip_index)
    if cfg.get("phase", "random") == "random":
        span = float(clip_duration) if clip_duration and clip_duration > 0 else PLACEMENT_RANDOM_PHASE_SPAN
        state.anim_time[:] = rng.uniform(0.0, span, n)
    return state


# --------------------------------------------------------------------- grid
GRID_PARAMS = {
    **_common("grid"),
    "rows": Param("int", min=1, max=10_000_000, doc="agents along z"),
    "cols": Param("int", min=1, max=10_000_000, doc="agents along x"),
    "spacing": Param("vec2", [2.0, 2.0], doc="metres between agents along x, z"),
    "origin": Param("vec3", [0.0, 0.0, 0.0], doc="position of the first agent, metres"),
    "jitter": Param("float", 0.0, min=0.0, doc="uniform position jitter, ± metres in x and z"),
}


def build_grid(cfg: dict, character_index: int, clip_index: int, rng, clip_duration=None) -> CrowdState:
    """``rows`` x ``cols`` agents on a regular XZ grid (row-major: agent
    ``r * cols + c`` at ``origin + (c * dx, 0, r * dz)``)."""
    rows, cols = int(cfg["rows"]), int(cfg["cols"])
    dx, dz = cfg.get("spacing", [2.0, 2.0])
    ox, oy, oz = cfg.get("origin", [0.0, 0.0, 0.0])
    st = CrowdState.empty(rows * cols)
    r, c = np.divmod(np.arange(rows * cols, dtype=np.int64), cols)
    st.position[:, 0] = ox + c * float(dx)
    st.position[:, 1] = oy
    st.position[:, 2] = oz + r * float(dz)
    jit = float(cfg.get("jitter", 0.0))
    if jit > 0:
        st.position[:, [0, 2]] += rng.uniform(-jit, jit, (st.n, 2))
    return _finish(st, cfg, character_index, clip_index, rng, clip_duration)


# --------------------------------------------------------------------- list
LIST_PARAMS = {
    **_common("list"),
    "positions": _PositionsParam("list", doc="agent positions [[x, y, z], ...], metres"),
    "headings": _NumberListParam("list", [], doc="per-agent yaw in degrees (same length as positions); "
                                                 "empty = use `heading`"),
}


def build_list(cfg: dict, character_index: int, clip_index: int, rng, clip_duration=None) -> CrowdState:
    """One agent per entry of ``positions``."""
    pos = _vec3_list("positions", cfg["positions"])
    st = CrowdState.empty(len(pos))
    st.position[:] = pos
    hd = cfg.get("headings") or []
    headings = None
    if hd:
        if len(hd) != len(pos):
            raise ParamError("headings", f"expected {len(pos)} entries (one per position), got {len(hd)}")
        headings = np.radians(np.asarray(hd, np.float64))
    return _finish(st, cfg, character_index, clip_index, rng, clip_duration, headings)


# ------------------------------------------------------------------- random
RANDOM_PARAMS = {
    **_common("random"),
    "count": Param("int", min=1, max=100_000_000, doc="number of agents"),
    "center": Param("vec3", [0.0, 0.0, 0.0], doc="centre of the rectangle, metres"),
    "size": Param("vec2", [50.0, 50.0], doc="rectangle extent along x, z, metres (>= 0)"),
    "min_distance": Param("float", 0.0, min=0.0, doc="minimum distance between agents, metres "
                                                      "(best effort; 0 = none)"),
}


def build_random(cfg: dict, character_index: int, clip_index: int, rng, clip_duration=None) -> CrowdState:
    """``count`` agents uniform in an XZ rectangle; with ``min_distance`` a
    grid-accelerated dart throwing keeps agents apart where it can."""
    n = int(cfg["count"])
    cx, cy, cz = cfg.get("center", [0.0, 0.0, 0.0])
    sx, sz = (max(0.0, float(v)) for v in cfg.get("size", [50.0, 50.0]))
    dmin = float(cfg.get("min_distance", 0.0))
    st = CrowdState.empty(n)
    xz = rng.uniform(0.0, 1.0, (n, 2)) * np.array([sx, sz])
    if dmin > 0 and n > 1 and sx * sz > 0:
        xz = _dart_throw(xz, n, sx, sz, dmin, rng)
    st.position[:, 0] = cx - sx / 2 + xz[:, 0]
    st.position[:, 1] = cy
    st.position[:, 2] = cz - sz / 2 + xz[:, 1]
    return _finish(st, cfg, character_index, clip_index, rng, clip_duration)


def _dart_throw(fallback: np.ndarray, n: int, sx: float, sz: float, dmin: float, rng) -> np.ndarray:
    """Dart throwing with a background grid of cell dmin / sqrt(2) (at most one
    agent per cell); tries are drawn up front so the result depends only on rng."""
    cell = dmin / math.sqrt(2.0)
    gx, gz = max(1, int(sx / cell) + 1), max(1, int(sz / cell) + 1)
    if gx * gz > 50_000_000:
        return fallback
    tries = rng.uniform(0.0, 1.0, (n * PLACEMENT_RANDOM_TRIES, 2)) * np.array([sx, sz])
    out = fallback.copy()
    _dart_kernel(tries, out, n, cell, gx, gz, dmin * dmin)
    return out


@njit(cache=True)
def _dart_kernel(tries, out, n, cell, gx, gz, d2):
    occ = -np.ones((gx, gz), np.int64)
    k = 0
    for t in range(tries.shape[0]):
        if k == n:
            break
        px, pz = tries[t, 0], tries[t, 1]
        i, j = min(int(px / cell), gx - 1), min(int(pz / cell), gz - 1)
        ok = True
        for a in range(max(0, i - 2), min(gx, i + 3)):
            for b in range(max(0, j - 2), min(gz, j + 3)):
                q = occ[a, b]
                if q >= 0 and (out[q, 0] - px) ** 2 + (out[q, 1] - pz) ** 2 < d2:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            out[k, 0] = px
            out[k, 1] = pz
            occ[i, j] = k
            k += 1
    return k


# ---------------------------------------------------------------- hierarchy
HIERARCHY_PARAMS = {
    **_common("hierarchy"),
    "levels": _LevelsParam("list", doc="layouts innermost first, e.g. "
                                       "[{layout=\"grid\", nx=2, nz=2, spacing=[1,1]}, {layout=\"tiers\", ...}]; "
                                       "see sim.instancing"),
    "origin": Param("vec3", [0.0, 0.0, 0.0], doc="translation of the whole hierarchy, metres"),
    "yaw": Param("float", 0.0, doc="rotation of the whole hierarchy about +Y, degrees"),
    "period": Param("float", 0.0, min=0.0, doc="period (s) of the per-level phase offsets; "
                                                 "0 = the clip duration"),
}


def build_hierarchy(cfg: dict, character_index: int, clip_index: int, rng, clip_duration=None) -> CrowdState:
    """Agents of a hierarchical instantiation (Wand & Straßer 2002, §3.6).

    The Hierarchy is attached to the returned state as ``state.hierarchy``
    (a plain attribute, not an array) and kept by :func:`concat_states`.
    Animation phases are the hierarchy's periodic offsets (``phase="zero"``)
    plus one common random offset (``phase="random"``); ``heading`` adds to
    every instance's yaw ("random" draws one yaw per instance).
    """
    from sim.instancing import Hierarchy, parse_levels

    levels = parse_levels(cfg["levels"], "levels")
    period = float(cfg.get("period", 0.0)) or (float(clip_duration) if clip_duration else 1.0)
    h = Hierarchy(levels, character=int(character_index), clip=int(clip_index), period=period,
                  origin=cfg.get("origin", [0.0, 0.0, 0.0]), yaw=math.radians(float(cfg.get("yaw", 0.0))))
    st = h.flatten(copy=True)
    hd = cfg.get("heading", 0.0)
    if hd == "random":
        st.heading[:] = rng.uniform(-math.pi, math.pi, st.n)
    else:
        st.heading[:] = st.heading + math.radians(float(hd))
    st.heading[:] = np.arctan2(np.sin(st.heading), np.cos(st.heading))
    speed = float(cfg.get("speed", 0.0))
    st.velocity[:, 0] = speed * np.sin(st.heading)
    st.velocity[:, 2] = speed * np.cos(st.heading)
    s, j = float(cfg.get("scale", 1.0)), float(cfg.get("scale_jitter", 0.0))
    st.scale[:] = st.scale * ((s * (1.0 + j * rng.uniform(-1.0, 1.0, st.n))) if j > 0 else s)
    if cfg.get("phase", "random") == "random":
        st.anim_time[:] = st.anim_time + rng.uniform(0.0, period)
    st.hierarchy = h
    return st


# ----------------------------------------------------------------------------------------- trajectories
class _CharacterChoice(Param):
    """A character name, or a choice ``{name = weight, ...}`` (the scene loader checks the names and weights)."""

    def check(self, key, value):
        if isinstance(value, dict):
            return dict(value)
        return Param("str").check(key, value)

    def describe(self) -> str:
        return "str or {name = weight, ...}"


TRAJECTORIES_PARAMS = {
    "kind": Param("str", choices=("trajectories",), doc="placement kind"),
    "character": _CharacterChoice("str", doc="a [[characters]] name, or a choice {name = weight, ...}: each "
                                             "recorded person draws one by weight"),
    "clip": Param("str", "", doc="clip name (the walk); empty = the character's first clip"),
    "phase": Param("str", "random", choices=("random", "zero"),
                   doc="animation time of each entering person: uniform over the clip, or 0"),
    "scale": Param("float", 1.0, min=1e-3, max=1e3, doc="uniform character scale"),
    "scale_jitter": Param("float", 0.0, min=0.0, max=0.9, doc="relative uniform jitter of the scale, scale*(1±j)"),
    "file": Param("str", doc="the recording, relative to the scene file (sim.replay.recording)"),
    "format": Param("str", "", choices=("",) + REPLAY_FORMATS,
                    doc="the recording's format; empty = from the file's suffix"),
    "unit": Param("str", "", choices=("", "m", "cm"),
                  doc="unit of the recorded coordinates where the file does not say it; empty = the file's"),
    "frame_rate": Param("float", 0.0, min=0.0, max=1e4,
                        doc="recorded frames per second where the file does not say it (0 = the file's)"),
    "feet": Param("str", "planted", choices=("planted", "recorded"),
                  doc="planted: the stance foot stays where it landed, the body up to 20 cm off the recording "
                      "(sim.replay.planting); recorded: the body exactly on the recording, the feet may slide"),
}


def build_trajectories(cfg: dict, character_index: int, clip_index: int, rng, clip_duration=None) -> CrowdState:
    """The people recorded at the recording's first frame (``cfg["recording"]``, a ``sim.replay.Recording`` the
    scene loader read); the effect ``replay`` adds and moves the rest (``sim.replay``). ``cfg["choice_table"]``:
    ``[(character, clip, weight, character scale, clip duration), ...]`` each person draws from (default: the
    placement's character and clip, scale 1). The state's ``tracks`` attribute is ``[(0, n, Track, persons)]``."""
    from sim.replay.track import Track

    rec = cfg.get("recording")
    if rec is None:
        raise ParamError("file", "the recording was not loaded")
    table = cfg.get("choice_table") or [(character_index, clip_index, 1.0, 1.0, float(clip_duration or 0.0))]
    track = Track(recording=rec, choices=np.array(table, np.float64), scale=float(cfg.get("scale", 1.0)),
                  scale_jitter=float(cfg.get("scale_jitter", 0.0)), phase=cfg.get("phase", "random"), rng=rng,
                  feet=cfg.get("feet", "planted"))
    f0 = track.frame_at(0.0)
    persons = np.flatnonzero(rec.alive(f0))
    st = track.agents(persons, f0)
    st.tracks = [(0, st.n, track, persons)]
    return st


PLACEMENTS: dict[str, tuple[dict[str, Param], Callable]] = {
    "grid": (GRID_PARAMS, build_grid),
    "list": (LIST_PARAMS, build_list),
    "random": (RANDOM_PARAMS, build_random),
    "hierarchy": (HIERARCHY_PARAMS, build_hierarchy),
    "trajectories": (TRAJECTORIES_PARAMS, build_trajectories),
}


def concat_states(states: list) -> CrowdState:
    """Join CrowdStates in order (agent ids of group k follow those of k-1).

    Hierarchies attached by kind ``"hierarchy"`` are collected in the result's
    ``hierarchies`` attribute as ``[(first_agent, Hierarchy), ...]``, and the
    groups in ``groups`` as ``[(first_agent, count), ...]`` (the goals effect
    gives one path per group with ``assign = "group"``).

    Parameters
    ----------
    states : list of CrowdState (may be empty)

    Returns
    -------
    CrowdState
        A new state; arrays keep their dtypes.
    """
    out = CrowdState.empty(0)
    if states:
        arrays = {name: np.concatenate([s.arrays()[name] for s in states], axis=0)
                  for name in out.arrays()}
        out = CrowdState(**arrays)
    hier, groups, tracks, start = [], [], [], 0
    for s in states:
        groups.append((start, s.n))
        for off, count, t, persons in getattr(s, "tracks", []):
            tracks.append((start + off, count, t, persons))
        for off, h in getattr(s, "hierarchies", []):
            hier.append((start + off, h))
        if getattr(s, "hierarchy", None) is not None:
            hier.append((start, s.hierarchy))
        start += s.n
    out.hierarchies = hier
    out.groups = groups
    if tracks:
        out.tracks = tracks
    return out
