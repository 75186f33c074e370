"""Hierarchical instantiation of animated characters (Wand & Straßer 2002, §3.6).

A crowd too large to place agent by agent is built as a tree: a *level* is a
list of child transforms (translation, yaw about +Y, uniform scale) and
periodic time offsets; the innermost level arranges copies of one animated
character (the *leaf*: character index, clip index), each outer level
replicates the whole group below it. The paper builds point super-hierarchies
out of sub-hierarchies this way ("Usually, both the motion of the
sub-hierarchies and the super-hierarchy are periodical, but the super
hierarchy may have a larger periodicity"); here each level adds a time offset
``offset_i = (i * phase_step) mod period`` to its i-th child, so the composed
animation of the crowd is periodic and neighbouring groups are out of step.

Levels are given **innermost first**: ``levels[0]`` arranges characters,
``levels[-1]`` is the root's children. Instance ``k`` of the flattened crowd has
the mixed-radix index ``(i_{m-1}, ..., i_0)`` with the outermost index most
significant, so the instances of one group are contiguous.

Layouts
-------
grid : ``nx`` x ``nz`` children, ``spacing = [dx, dz]``, centred on the
    group's origin; ``yaw`` (deg) for every child.
tiers : a stand of ``rows`` rows of ``seats_per_row`` seats; row ``r`` is
    ``r * row_rise`` higher and ``r * row_depth`` further back. Straight
    (``arc = 0``): seats along x, ``seat_spacing`` apart, rows going to -z,
    everyone facing +z. Curved (``arc`` > 0 degrees): seats evenly over the arc
    of radius ``radius + r * row_depth`` around the group's origin, facing it.
list : explicit ``children = [{position=[x,y,z], yaw=deg, scale=s}, ...]``.

Every layout also takes ``phase_step`` (seconds, default 0).

Departure from the paper: the paper's super-hierarchies store point samples of
the sub-hierarchies; here the sim layer only describes the tree and its
transforms. The LOD layer builds its point super-hierarchies from
:class:`Hierarchy` (``levels``, ``counts``, :meth:`Hierarchy.node_transforms`).

The ``instancing`` effect stores the placement hierarchies in
``world.resources["instancing"]`` (an :class:`Instancing`) and adds no step:
it costs nothing per frame; the animation effect advances ``anim_time``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.config import INSTANCING_MAX_INSTANCES
from sim.params import Param, ParamError, validate
from sim.state import CrowdState

_PHASE = Param("float", 0.0, min=0.0, doc="time offset between consecutive children, seconds (mod period)")

LAYOUTS: dict[str, dict[str, Param]] = {
    "grid": {
        "layout": Param("str", choices=("grid",)),
        "nx": Param("int", min=1, max=1_000_000, doc="children along x"),
        "nz": Param("int", min=1, max=1_000_000, doc="children along z"),
        "spacing": Param("vec2", [2.0, 2.0], doc="metres between children along x, z"),
        "yaw": Param("float", 0.0, doc="yaw of every child, degrees"),
        "phase_step": _PHASE,
    },
    "tiers": {
        "layout": Param("str", choices=("tiers",)),
        "rows": Param("int", min=1, max=100_000, doc="number of rows"),
        "seats_per_row": Param("int", min=1, max=1_000_000, doc="seats in each row"),
        "row_rise": Param("float", 0.4, min=0.0, doc="height step between rows, metres"),
        "row_depth": Param("float", 0.8, min=0.0, doc="depth step between rows, metres"),
        "seat_spacing": Param("float", 0.6, min=0.0, doc="distance between seats (straight stand), metres"),
        "arc": Param("float", 0.0, min=0.0, max=360.0, doc="arc of a curved stand, degrees; 0 = straight"),
        "radius": Param("float", 30.0, min=0.0, doc="radius of the first row of a curved stand, metres"),
        "phase_step": _PHASE,
    },
    "list": {
        "layout": Param("str", choices=("list",)),
        "children": Param("list", doc="[{position=[x,y,z], yaw=deg, scale=s}, ...]"),
        "phase_step": _PHASE,
    },
}

_CHILD = {
    "position": Param("vec3", [0.0, 0.0, 0.0]),
    "yaw": Param("float", 0.0),
    "scale": Param("float", 1.0, min=1e-6),
}



@dataclass
class Level:
    """Child transforms of one level of the tree.

    translation : (k, 3) float64, metres, in the parent group's frame
    yaw : (k,) float64, radians about +Y
    scale : (k,) float64
    time_offset : (k,) float64, seconds, in [0, period)
    layout : str, the layout it was built from
    """

    translation: np.ndarray
    yaw: np.ndarray
    scale: np.ndarray
    time_offset: np.ndarray
    layout: str = "list"

    @property
    def count(self) -> int:
        return int(self.yaw.shape[0])


def parse_levels(value, where: str = "levels") -> list[dict]:
    """Validate a ``levels`` list (innermost first); returns validated tables.

    Raises ParamError naming ``where[i].key``.
    """
    if not isinstance(value, list) or not value:
        raise ParamError(where, f"expected a non-empty list of layout tables, got {value!r}")
    out, total = [], 1
    for i, t in enumerate(value):
        w = f"{where}[{i}]"
        if not isinstance(t, dict):
            raise ParamError(w, f"expected a table with a `layout`, got {t!r}")
        lay = t.get("layout")
        if lay not in LAYOUTS:
            raise ParamError(f"{w}.layout", f"expected one of {', '.join(map(repr, LAYOUTS))}, got {lay!r}")
        cfg = validate(LAYOUTS[lay], t, w)
        if lay == "list":
            ch = cfg["children"]
            if not ch:
                raise ParamError(f"{w}.children", "expected at least one child table")
            for j, c in enumerate(ch):
                if not isinstance(c, dict):
                    raise ParamError(f"{w}.children[{j}]", f"expected a table {{position, yaw, scale}}, got {c!r}")
            cfg["children"] = [validate(_CHILD, c, f"{w}.children[{j}]") for j, c in enumerate(ch)]
        out.append(cfg)
        total *= _level_count(cfg)
    if total > INSTANCING_MAX_INSTANCES:
        raise ParamError(where, f"expected at most {INSTANCING_MAX_INSTANCES} instances in all, got {total}")
    return out


def _level_count(cfg: dict) -> int:
    lay = cfg["layout"]
    if lay == "grid":
        return cfg["nx"] * cfg["nz"]
    if lay == "tiers":
        return cfg["rows"] * cfg["seats_per_row"]
    return len(cfg["children"])


def build_level(cfg: dict, period: float) -> Level:
    """Child transforms of one validated layout table; offsets mod ``period``."""
    lay = cfg["layout"]
    if lay == "grid":
        nx, nz = cfg["nx"], cfg["nz"]
        dx, dz = cfg["spacing"]
        iz, ix = np.divmod(np.arange(nx * nz, dtype=np.int64), nx)
        t = np.zeros((nx * nz, 3))
        t[:, 0] = (ix - (nx - 1) / 2.0) * dx
        t[:, 2] = (iz - (nz - 1) / 2.0) * dz
        yaw = np.full(nx * nz, math.radians(cfg["yaw"]))
        scale = np.ones(nx * nz)
    elif lay == "tiers":
        rows, seats = cfg["rows"], cfg["seats_per_row"]
        r, s = np.divmod(np.arange(rows * seats, dtype=np.int64), seats)
        t = np.zeros((rows * seats, 3))
        t[:, 1] = r * cfg["row_rise"]
        if cfg["arc"] > 0:
            arc = math.radians(cfg["arc"])
            step = arc / seats if cfg["arc"] >= 360 else (arc / max(seats - 1, 1) if seats > 1 else 0.0)
            theta = -arc / 2 + s * step if cfg["arc"] < 360 else s * step
            if seats == 1:
                theta = np.zeros_like(theta, dtype=np.float64)
            rad = cfg["radius"] + r * cfg["row_depth"]
            t[:, 0] = rad * np.sin(theta)
            t[:, 2] = -rad * np.cos(theta)
            yaw = -np.asarray(theta, np.float64)  # faces the centre
        else:
            t[:, 0] = (s - (seats - 1) / 2.0) * cfg["seat_spacing"]
            t[:, 2] = -r * cfg["row_depth"]
            yaw = np.zeros(rows * seats)
        scale = np.ones(rows * seats)
    else:
        ch = cfg["children"]
        t = np.array([c["position"] for c in ch], np.float64).reshape(-1, 3)
        yaw = np.radians(np.array([c["yaw"] for c in ch], np.float64))
        scale = np.array([c["scale"] for c in ch], np.float64)
    k = yaw.shape[0]
    step = float(cfg.get("phase_step", 0.0))
    off = np.mod(np.arange(k, dtype=np.float64) * step, period) if period > 0 else np.zeros(k)
    return Level(t, np.asarray(yaw, np.float64), scale, off, lay)


def compose(t_outer, yaw_outer, s_outer, t_inner, yaw_inner, s_inner):
    """Compose transforms x -> t + s R(yaw) x, outer after inner (broadcasting).

    R(yaw) maps +Z to (sin yaw, 0, cos yaw) (heading convention of CrowdState).
    Returns (t, yaw, s).
    """
    c, sn = np.cos(yaw_outer), np.sin(yaw_outer)
    x, y, z = t_inner[..., 0], t_inner[..., 1], t_inner[..., 2]
    t = np.stack([t_outer[..., 0] + s_outer * (c * x + sn * z),
                  t_outer[..., 1] + s_outer * y,
                  t_outer[..., 2] + s_outer * (-sn * x + c * z)], axis=-1)
    return t, yaw_outer + yaw_inner, s_outer * s_inner


class Hierarchy:
    """A tree of instances of one animated character (Wand & Straßer §3.6).

    Parameters
    ----------
    levels : list of validated layout tables (see :func:`parse_levels`) or of
        :class:`Level`, innermost first.
    character, clip : int
        The leaf: character index and clip index of every instance.
    period : float
        Seconds; time offsets of every level are taken modulo it (normally the
        clip duration, or a multiple of it for a longer super-period).
    origin : (3,) metres; yaw : radians. The root transform.
    """

    def __init__(self, levels, character: int = 0, clip: int = 0, period: float = 1.0,
                 origin=(0.0, 0.0, 0.0), yaw: float = 0.0):
        self.period = float(period) if period and period > 0 else 1.0
        self.levels: list[Level] = [lv if isinstance(lv, Level) else build_level(lv, self.period) for lv in levels]
        self.character = int(character)
        self.clip = int(clip)
        self.origin = np.asarray(origin, np.float64).reshape(3)
        self.yaw = float(yaw)
        self._flat: CrowdState | None = None

    @property
    def counts(self) -> list[int]:
        """Children per level, innermost first."""
        return [lv.count for lv in self.levels]

    @property
    def depth(self) -> int:
        return len(self.levels)

    @property
    def n_instances(self) -> int:
        return int(np.prod(self.counts, dtype=np.int64))

    def instances_per_node(self, depth: int) -> int:
        """Instances under one node at ``depth`` (= prod(counts[:depth])); node k
        of that depth owns the contiguous instances ``[k * m, (k + 1) * m)``."""
        if not 0 <= depth <= self.depth:
            raise ValueError(f"depth must be in 0..{self.depth}, got {depth}")
        return int(np.prod(self.counts[:depth], dtype=np.int64))

    def node_transforms(self, depth: int):
        """World transforms of every node whose subtree holds ``levels[:depth]``.

        depth = 0 gives the leaves (one per instance), depth = ``self.depth`` the
        root. Nodes are ordered outermost index first (as instances are).

        Returns
        -------
        translation : (N, 3) float64; yaw : (N,) float64; scale : (N,) float64;
        time_offset : (N,) float64 in [0, period)
        """
        if not 0 <= depth <= self.depth:
            raise ValueError(f"depth must be in 0..{self.depth}, got {depth}")
        t = self.origin[None, :]
        yaw = np.array([self.yaw])
        s = np.ones(1)
        off = np.zeros(1)
        for lv in reversed(self.levels[depth:]):
            t, yaw, s = compose(t[:, None, :], yaw[:, None], s[:, None],
                                lv.translation[None, :, :], lv.yaw[None, :], lv.scale[None, :])
            off = off[:, None] + lv.time_offset[None, :]
            t, yaw, s, off = t.reshape(-1, 3), yaw.reshape(-1), s.reshape(-1), off.reshape(-1)
        return t, yaw, s, np.mod(off, self.period)

    def flatten(self, copy: bool = False) -> CrowdState:
        """The instances as a CrowdState (cached; ``copy=True`` for a private copy).

        Positions and headings are the composed transforms, ``anim_time`` the
        summed time offsets (mod period), ``scale`` the product of scales.
        """
        if self._flat is None:
            t, yaw, s, off = self.node_transforms(0)
            st = CrowdState.empty(t.shape[0])
            st.position[:] = t
            st.heading[:] = np.arctan2(np.sin(yaw), np.cos(yaw))
            st.scale[:] = s
            st.character[:] = self.character
            st.clip[:] = self.clip
            st.anim_time[:] = off
            self._flat = st
        if copy:
            return CrowdState(**{k: v.copy() for k, v in self._flat.arrays().items()})
        return self._flat


@dataclass
class Instancing:
    """``world.resources["instancing"]``: the hierarchies of a scene.

    groups : list of (first_agent, Hierarchy); agents
        ``first_agent .. first_agent + h.n_instances - 1`` of the CrowdState are
        the flattened instances of ``h``.
    """

    groups: list = field(default_factory=list)

    @property
    def hierarchy(self) -> Hierarchy | None:
        """The first hierarchy (scenes with one hierarchy placement)."""
        return self.groups[0][1] if self.groups else None

    @property
    def n_instances(self) -> int:
        return sum(h.n_instances for _, h in self.groups)


PARAMS: dict[str, Param] = {}


def install(world, cfg: dict) -> None:
    """Effect ``instancing``: publish the placement hierarchies, add no step.

    Reads ``world.state.hierarchies`` (set by :func:`sim.placement.concat_states`)
    or ``world.state.hierarchy``. A scene without a ``hierarchy`` placement is
    an error.
    """
    groups = list(getattr(world.state, "hierarchies", None) or [])
    if not groups and getattr(world.state, "hierarchy", None) is not None:
        groups = [(0, world.state.hierarchy)]
    if not groups:
        raise ParamError("effects.instancing", "needs at least one [[placement]] of kind \"hierarchy\"")
    world.resources["instancing"] = Instancing(groups)
