"""The router: one distance field per goal on one grid over the walkable area, read by every agent heading there.

``world.resources["routing"]`` (effect ``routing``). Movers (``goals``, ``journeys``) register each goal shape once
with :meth:`Router.goal` at install and ask per step for the agents' desired directions with
:meth:`Router.directions` (their own speed rules then apply). The build of a field is described in
:mod:`sim.routing.field`, the walkable area in :mod:`sim.routing.geometry`.

Memory: ``4 * nx * nz`` bytes per goal (float32 field) plus one bool raster of the free nodes; nothing per
agent (the caller owns the ``(n, 2)`` direction and ``(n,)`` distance buffers).
"""
from __future__ import annotations

import math
import time

import numpy as np

from sim.routing import cache
from sim.routing import corners as cn
from sim.routing.field import Grid, ahead_points, band_sources, directions_kernel, march_goal, store
from sim.routing.geometry import Walkable, raster, shape_problem

#: default grid spacing: this fraction of the clearance (accurate around door jambs), ...
CELL_PER_CLEARANCE = 0.5
#: ... and at most this many nodes per field (the spacing grows for big areas)
MAX_NODES = 4_000_000
#: an agent closer than this many cells to its via corner heads for the corner after it
CORNER_EPS = 0.25
#: never finer than this (metres): a clearance of 0 would otherwise ask for an infinite grid
MIN_CELL = 0.05


class RoutingError(ValueError):
    """A goal the router cannot use (outside the area, no room around it): ``key`` and one phrase."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}" if key else message)
        self.key, self.message = key, message


def auto_cell(walkable: Walkable, clearance: float, max_nodes: int = MAX_NODES) -> float:
    """The default grid spacing (module constants): ``CELL_PER_CLEARANCE * clearance``, at least MIN_CELL,
    coarser when the area's bounding box would need more than ``max_nodes`` nodes."""
    x0, z0, x1, z1 = walkable.bounds
    h = max(CELL_PER_CLEARANCE * clearance, MIN_CELL)
    need = math.sqrt(max((x1 - x0) * (z1 - z0), 1e-12) / max_nodes)
    return float(max(h, need))


class Router:
    """Distance fields of goals over one walkable area (module docstring).

    walkable : sim.routing.geometry.Walkable; clearance : metres kept from walls; cell : grid spacing (0: auto)
    grid : sim.routing.field.Grid; free : (nz, nx) bool free nodes; fields : (nz, nx, G) float32
    build_seconds : list of float, wall time of each goal's field (built, or loaded from the disk cache:
    :mod:`sim.routing.cache`, ``use_cache``); cache_hits : int, goals loaded
    """

    def __init__(self, walkable: Walkable, clearance: float, cell: float = 0.0, order: int = 2,
                 steering: str = "corners", use_cache: bool = True):
        self.walkable = walkable
        self.clearance = float(clearance)
        h = float(cell) if cell > 0 else auto_cell(walkable, self.clearance)
        self.grid = Grid.covering(walkable.bounds, h)
        self.order = int(order)
        g = self.grid
        inside, wall = raster(walkable, g.x0, g.z0, g.h, g.nx, g.nz, self.clearance + 3.0 * g.h)
        self.free = inside & (wall >= self.clearance)
        from sim.routing.field import RIM_CELLS

        self.band = band_sources(self.free, inside | (wall <= RIM_CELLS * g.h))
        self.steering = steering
        self.use_cache = bool(use_cache)
        self.cache_hits = 0
        self.free_space = cn.free_space(walkable.area, self.clearance)
        rings = cn.rings_of(self.free_space)
        corners, wedges = cn.reflex_corners(rings)
        self.corners, self.wedges = np.ascontiguousarray(corners), np.ascontiguousarray(wedges)
        self.buckets = cn.EdgeBuckets(rings, walkable.bounds, 4.0 * g.h)
        self._seeds = None  # corners seeded at the nodes (the same for every goal)
        self._vis = None  # the corners' visibility graph (the same for every goal)
        self.shapes: list = []
        self._index: dict = {}
        self._fields: list = []
        self._vias: list = []
        self._D: list = []
        self._next: list = []
        self._stack = np.zeros((g.nz, g.nx, 0), np.float32)
        self._vstack = np.zeros((g.nz, g.nx, 0), np.int16)
        self.build_seconds: list = []

    # -- goals ------------------------------------------------------------------------------------------------------
    @staticmethod
    def _key(shape) -> tuple:
        kind, g = shape
        if kind == "point":
            return (kind, (float(g[0]), float(g[1])))
        return (kind, tuple((float(p[0]), float(p[1])) for p in g))

    def goal(self, shape, key: str = "") -> int:
        """The id of goal ``shape`` (``("point", (x, z))`` | ``("line", ((x1, z1), (x2, z2)))`` |
        ``("polygon", [(x, z), ...])``), its field built on first use; equal shapes share an id.

        Raises RoutingError (naming ``key``) for a shape outside the walkable area or without free space of the
        clearance around it."""
        k = self._key(shape)
        if k in self._index:
            return self._index[k]
        why = shape_problem(self.walkable, k)
        if why:
            raise RoutingError(key, f"goal {_show(k)} {why}")
        t0 = time.perf_counter()
        g, c = self.grid, self.corners.shape[0]
        ck = cache.field_key(self, k) if self.use_cache else None
        got = cache.load(ck, {"field": (g.nz, g.nx), "via": (g.nz, g.nx), "D": (c,), "next": (c,)}) if ck else None
        if got is None:
            T, seeds = march_goal(self.grid, self.free, self.band, k, self.clearance, self.order)
            if T is None:
                raise RoutingError(key, f"goal {_show(k)} has no walkable space {self.clearance:g} m (the "
                                        "clearance) from the walls around it")
            via, D, nxt = self._vias_of(k, T, seeds)
            got = {"field": store(T, self.grid), "via": via, "D": D, "next": nxt}
            if ck:
                cache.save(ck, got)
        else:
            self.cache_hits += 1
        self.build_seconds.append(time.perf_counter() - t0)
        self._index[k] = len(self.shapes)
        self.shapes.append(k)
        self._fields.append(got["field"])
        self._vias.append(got["via"])
        self._D.append(got["D"])
        self._next.append(got["next"])
        return self._index[k]

    def _vias_of(self, k, T, seeds) -> tuple:
        """The goal's vias (module docstring of :mod:`sim.routing.corners`): (via (nz, nx) int32, D (C,), next
        (C,) int64)."""
        g, C = self.grid, self.corners
        ba = self.buckets.args()
        gseg, area = cn.goal_segments(k)
        gd = np.full(C.shape[0], np.inf)
        for c in range(C.shape[0]):
            d, qx, qz = cn.goal_nearest(C[c, 0], C[c, 1], gseg, 0, gseg.shape[0], area)
            if d == 0.0 or (cn.wedge_ok(self.wedges, c, qx - C[c, 0], qz - C[c, 1])
                            and cn.visible(C[c, 0], C[c, 1], qx, qz, *ba)):
                gd[c] = d
        if self._vis is None:
            self._vis = cn.visibility_matrix(C, self.wedges, self.buckets)
        D, nxt = cn.corner_distances(C, self._vis, gd)
        via = np.full(g.nodes, cn.VIA_NONE, np.int32)
        if self.steering == "corners":
            ok = np.nonzero(self.free.ravel() & np.isfinite(T))[0]
            order = ok[np.argsort(T[ok], kind="stable")]
            if self._seeds is None:
                self._seeds = cn.node_seeds(g, self.free, C)
            kid_start, kids = cn.children_of(nxt)
            cn.via_kernel(order, g.nx, g.x0, g.z0, g.h, C if C.shape[0] else np.zeros((1, 2)),
                          self.wedges if C.shape[0] else np.zeros((1, 4)), D, kid_start, kids, *self._seeds, gseg,
                          area, *ba, via)
            nodes, src, _ = self.band
            via[nodes] = via[src]  # the band steers as its nearest free node
        return via.reshape(g.nz, g.nx), D, nxt

    @property
    def fields(self) -> np.ndarray:
        """(nz, nx, G) float32, the fields interleaved per node (the kernel reads one array; agents at one place
        share its cache lines whatever their goals)."""
        self._restack()
        return self._stack

    def _restack(self) -> None:
        if self._stack.shape[2] == len(self._fields):
            return
        self._stack = np.ascontiguousarray(np.stack(self._fields, 2))
        vtype = np.int16 if self.corners.shape[0] < np.iinfo(np.int16).max else np.int32
        self._vstack = np.ascontiguousarray(np.stack(self._vias, 2).astype(vtype))
        c = max(self.corners.shape[0], 1)
        self._Dstack = np.stack([np.resize(d, c) if d.size else np.full(c, np.inf) for d in self._D], 0)
        self._nstack = np.stack([np.resize(n, c) if n.size else np.full(c, cn.VIA_NONE, np.int64)
                                 for n in self._next], 0)
        segs = [cn.goal_segments(s) for s in self.shapes]
        self._gseg = np.concatenate([sg for sg, _ in segs], 0)
        self._gstart = np.concatenate([[0], np.cumsum([sg.shape[0] for sg, _ in segs])]).astype(np.int64)
        self._garea = np.array([a for _, a in segs], np.bool_)
        self._ahead = np.stack([ahead_points(self.corners, self._next[k], segs[k][0], segs[k][1])
                                if self.corners.shape[0] else np.zeros((1, 2)) for k in range(len(segs))], 0)
        self._corners = self.corners if self.corners.shape[0] else np.zeros((1, 2))

    # -- per step ---------------------------------------------------------------------------------------------------
    def directions(self, position: np.ndarray, goal: np.ndarray, out: np.ndarray, dist: np.ndarray | None = None):
        """Desired directions of agents: ``out`` (n, 2) float64 gets the unit (x, z) direction of steepest descent
        of goal ``goal[i]``'s field at ``position[i]`` ((n, 3) float64, x and z used), 0 for ``goal[i] = -1``;
        ``dist`` (n,) float64, if given, the remaining route length (inf: unreachable or no goal)."""
        n = position.shape[0]
        if dist is None:
            dist = np.empty(n, np.float64)
        if n == 0:
            return out
        F = self.fields
        if F.shape[2] == 0:
            out[:] = 0.0
            dist[:] = np.inf
            return out
        g = self.grid
        directions_kernel(position, np.ascontiguousarray(goal, np.int64), F, self._vstack, self._corners,
                          self._Dstack, self._nstack, self._ahead, self._gseg, self._gstart, self._garea, g.x0, g.z0,
                          g.h, g.nx, g.nz,
                          CORNER_EPS * g.h, self.steering == "corners", out, dist)
        return out

    def follow(self, state, path, target, pstart, wgoal, loop: bool, arrive: float, speed: float,
               integrate: bool, dt: float, vd: np.ndarray) -> np.ndarray:
        """The ``goals`` effect's routed step (:func:`sim.routing.follow.follow_kernel`): desired velocities in
        ``vd`` (n, 2), reached waypoints advanced in ``target``, and the kinematic move when ``integrate``."""
        from sim.routing.follow import follow_kernel

        F = self.fields
        g = self.grid
        follow_kernel(state.position, state.velocity, state.heading, path, target, pstart, wgoal, bool(loop),
                      float(arrive), float(speed), bool(integrate), float(dt), F, self._vstack, self._corners,
                      self._Dstack, self._nstack, self._ahead, self._gseg, self._gstart, self._garea, g.x0, g.z0,
                      g.h, g.nx, g.nz, CORNER_EPS * g.h, self.steering == "corners", vd)
        return vd

    def distance(self, gid: int, xz) -> np.ndarray:
        """(m,) float64 route length from each point (m, 2) to goal ``gid`` (inf: unreachable)."""
        xz = np.asarray(xz, np.float64).reshape(-1, 2)
        pos = np.zeros((xz.shape[0], 3))
        pos[:, 0], pos[:, 2] = xz[:, 0], xz[:, 1]
        out, dist = np.empty((xz.shape[0], 2)), np.empty(xz.shape[0])
        self.directions(pos, np.full(xz.shape[0], gid, np.int64), out, dist)
        return dist

    def reachable(self, gid: int, xz) -> np.ndarray:
        """(m,) bool: a route from each point (m, 2) to goal ``gid`` exists."""
        return np.isfinite(self.distance(gid, xz))

    # -- figures ----------------------------------------------------------------------------------------------------
    @property
    def bytes_per_goal(self) -> int:
        """Field (float32) and vias (int16; int32 past 32,766 corners) of one goal, plus its corner arrays."""
        via = 2 if self.corners.shape[0] < np.iinfo(np.int16).max else 4
        return (4 + via) * self.grid.nodes + 32 * self.corners.shape[0]

    def describe(self) -> str:
        g = self.grid
        return (f"routing: {len(self.shapes)} goal field(s) on {g.nx} x {g.nz} nodes of {g.h:g} m "
                f"({self.bytes_per_goal / 2**20:.1f} MiB each), clearance {self.clearance:g} m")


def _show(k) -> str:
    kind, g = k
    if kind == "point":
        return f"({g[0]:g}, {g[1]:g})"
    return f"{kind} " + ", ".join(f"({x:g}, {z:g})" for x, z in g)
