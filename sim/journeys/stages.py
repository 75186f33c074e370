"""Stages and journeys as flat tables (built once from the validated scene configuration).

Stage kinds (JuPedSim's journeys and stages, Kemloh Wagoum et al.; names follow its Python API):

- ``waypoint`` : a point and a radius; reached within the radius, the agent goes on.
- ``exit`` : a polygon (the agent leaves once inside) or a door line (it leaves once its move crosses the
  segment, PedPy's crossing); an exit ends a journey.
- ``wait`` : a waiting area: slots (given, or a square lattice of ``spacing`` inside its polygon); an agent
  claims a free slot when the stage begins (the nearest one), walks there and waits a time drawn from the
  stage's distribution, then -- when the stage has ``release_at`` times -- until the next release; a full
  area makes agents hold outside it in arrival order until a slot frees.
- ``queue`` : slots every ``spacing`` metres along a polyline from its head; an agent walks to the end of the
  line (the next free slot; past the last slot, ``spacing`` apart short of it) and joins there, so the line
  fills from the head and nobody walks through it (joining where one stands would let late agents block early
  ones); rank r takes slot r, the agent at the head is served for a time drawn from the distribution and
  leaves, and everyone moves up one slot.

A journey is a sequence of entries; an entry is one stage or a weighted choice between stages (drawn when
the agent reaches it, seeded by the scene seed, the agent's id and how many stages it went through, so a
run is deterministic and independent of the order agents are processed in).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.journeys.geometry import Shapes, grid_in_polygon, polyline_slots

WAYPOINT, EXIT, WAIT, QUEUE = 0, 1, 2, 3
KINDS = {"waypoint": WAYPOINT, "exit": EXIT, "wait": WAIT, "queue": QUEUE}
#: time distributions of waiting and service times (``time = {kind = ...}``)
DISTRIBUTIONS = ("fixed", "uniform", "exponential", "normal")


@dataclass
class Stage:
    """One stage. ``shape``: id in the shapes table the agents steer to (for exits the door shrunk by a body
    radius at each end); ``slots``: (m, 2) slot positions (wait, queue) with their point shape ids and the shape
    the router routes an agent bound for a slot to (``slot_routes``: the waiting area, the queue's last place):
    one routing goal per stage, not per slot (each is a distance field); near them agents walk straight."""

    name: str
    kind: int
    shape: int
    radius: float = 0.0
    point: np.ndarray | None = None
    polygon: np.ndarray | None = None
    line: np.ndarray | None = None
    slots: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    slot_shapes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    slot_routes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # the router's goal per slot
    spacing: float = 0.0
    time: dict = field(default_factory=lambda: {"kind": "fixed", "value": 0.0})
    release_at: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hold_distance: float = 0.0  # pending agents of a full waiting area stop this far from its shape


@dataclass
class Journey:
    """A journey: ``entries`` a list of (stage indices (k,), cumulative weights (k,) ending at 1)."""

    name: str
    entries: list
    loop: bool = False
    speed: float = 1.34
    placements: tuple = ()


def build_stages(cfg_stages: list, shapes: Shapes, body_radius: float) -> list:
    """:class:`Stage` of every validated ``[[stages]]`` table; their shapes are added to ``shapes``."""
    out = []
    for s in cfg_stages:
        kind = KINDS[s["kind"]]
        st = Stage(name=s["name"], kind=kind, shape=-1, radius=float(s.get("radius") or 0.0),
                   time=dict(s.get("time") or {"kind": "fixed", "value": 0.0}),
                   release_at=np.sort(np.asarray(s.get("release_at") or [], np.float64)),
                   spacing=float(s.get("spacing") or 0.0))
        if s.get("polygon") is not None:
            st.polygon = np.asarray(s["polygon"], np.float64).reshape(-1, 2)
        if s.get("line") is not None:
            st.line = np.asarray(s["line"], np.float64).reshape(-1, 2)
        if kind == WAYPOINT:
            st.point = np.asarray(s["point"], np.float64)
            st.shape = shapes.add("point", [st.point])
        elif kind == EXIT:
            if st.polygon is not None:
                st.shape = shapes.add("polygon", st.polygon)
            else:
                a, b = st.line
                length = math.dist(a, b)
                cut = min(body_radius, 0.5 * length) / length  # the door less a body radius at each jamb
                st.shape = shapes.add("line", [a + (b - a) * cut, b - (b - a) * cut])
        else:
            if s.get("slots"):
                slots = np.asarray(s["slots"], np.float64).reshape(-1, 2)
            elif kind == WAIT:
                slots = grid_in_polygon(st.polygon, st.spacing)
            else:
                slots = polyline_slots(st.line, st.spacing, s.get("capacity"))
            if kind == WAIT and s.get("capacity"):
                slots = slots[:int(s["capacity"])]
            st.slots = slots
            st.slot_shapes = np.array([shapes.add("point", [p]) for p in slots], np.int64)
            if kind == WAIT:
                if st.polygon is not None:
                    st.shape = shapes.add("polygon", st.polygon)
                    st.hold_distance = max(st.spacing, 2.0 * body_radius)
                else:
                    c = slots.mean(0)
                    st.shape = shapes.add("point", [c])
                    st.hold_distance = float(np.hypot(*(slots - c).T).max()) + max(st.spacing, 2.0 * body_radius)
                st.slot_routes = np.full(slots.shape[0], st.shape, np.int64)
            else:
                st.shape = int(st.slot_shapes[0])
                if st.spacing <= 0.0:
                    st.spacing = float(np.hypot(*(slots[1] - slots[0]))) if len(slots) > 1 else 2.0 * body_radius
                st.slot_routes = np.full(slots.shape[0], st.slot_shapes[-1], np.int64)  # the end of the line
        out.append(st)
    return out


def build_journeys(cfg_journeys: list, default_speed: float) -> list:
    """:class:`Journey` of every validated ``[[journeys]]`` table (entries as stage indices and weights)."""
    out = []
    for j in cfg_journeys:
        entries = []
        for e in j["stages"]:
            idx = np.asarray([k for k, _ in e], np.int64)
            w = np.asarray([float(x) for _, x in e], np.float64)
            entries.append((idx, np.cumsum(w) / w.sum()))
        out.append(Journey(name=j["name"], entries=entries, loop=bool(j.get("loop", False)),
                           speed=float(j.get("speed") or default_speed),
                           placements=tuple(j.get("placements") or ())))
    return out


# ------------------------------------------------------------------------------------------ seeded draws
def uniforms(seed: int, salt: int, ids: np.ndarray, counter: np.ndarray, k: int = 1) -> np.ndarray:
    """(m, k) float64 in [0, 1): independent numbers for (scene seed, salt, agent id, counter), whatever the
    order the agents are processed in (one counter-based stream per agent and event: numpy's Philox keyed by
    a SeedSequence of the four)."""
    ids = np.asarray(ids, np.int64)
    counter = np.asarray(counter, np.int64)
    out = np.empty((ids.shape[0], k), np.float64)
    for i in range(ids.shape[0]):
        ss = np.random.SeedSequence([int(seed), int(salt), int(ids[i]), int(counter[i])])
        out[i] = np.random.Generator(np.random.Philox(ss)).random(k)
    return out


def choose(entry: tuple, u: np.ndarray) -> np.ndarray:
    """The stage of a journey entry (stage indices, cumulative weights) for uniforms ``u`` (m,)."""
    idx, cum = entry
    return idx[np.minimum(np.searchsorted(cum, u, side="right"), idx.shape[0] - 1)]


def sample_time(dist: dict, u: np.ndarray) -> np.ndarray:
    """Times (m,) >= 0 of distribution ``dist`` for uniforms ``u`` (m, 2) (the second for ``normal``)."""
    u = np.asarray(u, np.float64).reshape(-1, 2)
    kind = dist.get("kind", "fixed")
    if kind == "fixed":
        t = np.full(u.shape[0], float(dist.get("value", 0.0)))
    elif kind == "uniform":
        t = float(dist["min"]) + u[:, 0] * (float(dist["max"]) - float(dist["min"]))
    elif kind == "exponential":
        t = -float(dist["mean"]) * np.log1p(-u[:, 0])
    else:  # normal (Box-Muller), truncated at 0
        r = np.sqrt(-2.0 * np.log1p(-u[:, 0]))
        t = float(dist["mean"]) + float(dist["sd"]) * r * np.cos(2.0 * np.pi * u[:, 1])
    return np.maximum(t, 0.0)
