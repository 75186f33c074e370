"""Distance fields of goals on a grid, and the per-agent steering read from them.

Treuille, Cooper & Popović, *Continuum crowds* (SIGGRAPH 2006), §4: agents heading to one goal share one
potential field, solved once by fast marching (:mod:`sim.routing.fmm`); here the field is the geodesic distance
through the walkable area kept ``clearance`` away from its walls (the potential of a unit, density-free cost; the
density term of §4.2 is not built). Its gradient alone rounds corners wide (2-9 % longer routes round a U-shaped
wall, docs/routing.md), so agents steer at the next corner of their shortest path (:mod:`sim.routing.corners`,
:func:`steer_one`) and the field serves for the visiting order of those vias, reachability and the clearance band.

Build, per goal, on the router's grid (:func:`march_goal`):

1. free nodes: inside the walkable area and at least ``clearance`` from its boundary (:func:`sim.routing.geometry.
   raster`); the goal's seeds: free nodes within :data:`SEED_CELLS` cells of the goal shape get their exact
   Euclidean distance to it (0 inside a polygon goal); a goal closer to a wall than the clearance is seeded at the
   free nodes nearest to it instead;
2. march the free nodes (second order): ``T`` = distance to the goal; free nodes the front never reaches (another
   component of the free space) are unreachable;
3. the clearance band and the wall rims (:func:`extend_band`): each node the value of its nearest free node plus
   :data:`BAND_SLOWNESS` times the distance to it: an agent whose centre is closer to a wall than the clearance
   (spawned there, pushed there) descends out of the band on its own side of the wall first;
4. store ``float32`` (:data:`UNREACHABLE` where the front never came).

Steering (:func:`directions_kernel`; references :func:`directions_numpy` (gradient) and :func:`steer_numpy`
(vias)): the vias of the four nodes around the agent by exact route length, else the bilinear interpolant's
gradient (normalised, negated); where the gradient vanishes (a ridge between two equally long routes) the agent
heads to the lowest of the four nodes. O(1) per agent.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from sim.routing.corners import VIA_GOAL, VIA_NONE, goal_nearest
from sim.routing.fmm import BLOCKED, FAR, KNOWN, march

#: seeds: free nodes within this many cells of the goal shape take their exact distance to it
SEED_CELLS = 3.0
#: slowness of the march into the clearance band and the wall rims (step 3 of the build)
BAND_SLOWNESS = 3.0
#: wall rim: nodes outside the area within this many cells of its boundary get band values (bilinear cells that
#: straddle the boundary read them)
RIM_CELLS = 2.0
#: stored where the front never came; any value above UNREACHABLE / 2 reads as "no route"
UNREACHABLE = np.float32(1e30)
#: gradients shorter than this (per cell, relative to the unit slope of a distance) fall back to the lowest node
FLAT_GRADIENT = 1e-3


@dataclass(frozen=True)
class Grid:
    """Nodes ``(x0 + i h, z0 + j h)``, ``i < nx``, ``j < nz``; arrays are indexed ``[j, i]``."""

    x0: float
    z0: float
    h: float
    nx: int
    nz: int

    @classmethod
    def covering(cls, bounds: tuple, h: float) -> "Grid":
        """The grid of spacing ``h`` covering ``bounds`` (x0, z0, x1, z1) with a margin of two cells."""
        x0, z0, x1, z1 = bounds
        x0, z0 = x0 - 2.0 * h, z0 - 2.0 * h
        nx = int(math.ceil((x1 + 2.0 * h - x0) / h)) + 1
        nz = int(math.ceil((z1 + 2.0 * h - z0) / h)) + 1
        return cls(float(x0), float(z0), float(h), nx, nz)

    @property
    def nodes(self) -> int:
        return self.nx * self.nz

    def node_xz(self) -> tuple:
        """(X, Z) (nz, nx) float64 node coordinates."""
        return np.meshgrid(self.x0 + np.arange(self.nx) * self.h, self.z0 + np.arange(self.nz) * self.h)


def shape_geometry(shape):
    """A goal shape (``sim.routing.geometry.shape_problem``) as a shapely geometry."""
    import shapely

    kind, g = shape
    if kind == "point":
        return shapely.Point(float(g[0]), float(g[1]))
    if kind == "line":
        return shapely.LineString([tuple(map(float, g[0])), tuple(map(float, g[1]))])
    return shapely.Polygon([tuple(map(float, p)) for p in g])


def seed_values(grid: Grid, free: np.ndarray, shape, clearance: float) -> tuple:
    """(flat node indices, exact distances) of the goal's seeds (module docstring, step 1); empty when no free
    node lies within the clearance and a few cells of the goal."""
    import shapely

    geom = shape_geometry(shape)
    gx0, gz0, gx1, gz1 = geom.bounds
    for reach in (SEED_CELLS * grid.h, clearance + (SEED_CELLS + 1.0) * grid.h):
        i0 = max(int(math.floor((gx0 - reach - grid.x0) / grid.h)), 0)
        i1 = min(int(math.ceil((gx1 + reach - grid.x0) / grid.h)), grid.nx - 1)
        j0 = max(int(math.floor((gz0 - reach - grid.z0) / grid.h)), 0)
        j1 = min(int(math.ceil((gz1 + reach - grid.z0) / grid.h)), grid.nz - 1)
        if i1 < i0 or j1 < j0:
            continue
        jj, ii = np.meshgrid(np.arange(j0, j1 + 1), np.arange(i0, i1 + 1), indexing="ij")
        jj, ii = jj.ravel(), ii.ravel()
        ok = free[jj, ii]
        jj, ii = jj[ok], ii[ok]
        d = shapely.distance(geom, shapely.points(grid.x0 + ii * grid.h, grid.z0 + jj * grid.h))
        near = d <= reach
        if near.any():
            return (jj[near] * grid.nx + ii[near]).astype(np.int64), d[near].astype(np.float64)
    return np.zeros(0, np.int64), np.zeros(0)


def band_sources(free: np.ndarray, rim: np.ndarray) -> tuple:
    """(band (m,) flat indices of the rim nodes that are not free, src (m,) flat index of each one's nearest free
    node, d (m,) its distance in cells): Euclidean distance transform with indices; the same for every goal."""
    from scipy.ndimage import distance_transform_edt

    band = np.nonzero((rim & ~free).ravel())[0]
    if band.size == 0 or not free.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    d, (jj, ii) = distance_transform_edt(~free, return_indices=True)
    nx = free.shape[1]
    src = (jj.ravel()[band] * nx + ii.ravel()[band]).astype(np.int64)
    return band.astype(np.int64), src, d.ravel()[band]


def extend_band(T: np.ndarray, band: tuple, h: float) -> None:
    """Step 3 of the build, in place on the flat T: every rim node that is not free takes the value of its
    nearest free node q plus BAND_SLOWNESS times the distance to q (``band`` = :func:`band_sources`). The nearest
    free node, not the cheapest: a node in the band of a thin wall must descend to its own side of the wall, never
    through the wall to a side that is closer to the goal."""
    nodes, src, d = band
    T[nodes] = T[src] + BAND_SLOWNESS * h * d


def march_goal(grid: Grid, free: np.ndarray, band: tuple, shape, clearance: float, order: int = 2):
    """Steps 1-3 of the build (module docstring): (T (nz * nx,) float64 with inf where unreached, seeds (flat
    node indices)), or (None, seeds) when the goal has no free space around it.

    free : (nz, nx) bool free nodes; band : :func:`band_sources` (step 3)."""
    seeds, d = seed_values(grid, free, shape, clearance)
    if seeds.size == 0:
        return None, seeds
    n = grid.nodes
    T = np.full(n, np.inf)
    flag = np.where(free.ravel(), FAR, BLOCKED).astype(np.int8)
    T[seeds] = d
    flag[seeds] = KNOWN
    march(T, flag, grid.nx, grid.nz, grid.h, 1.0, order)
    extend_band(T, band, grid.h)
    return T, seeds


def store(T: np.ndarray, grid: Grid) -> np.ndarray:
    """Step 4: (nz, nx) float32 with UNREACHABLE where T is inf."""
    return np.where(np.isfinite(T), T, UNREACHABLE).astype(np.float32).reshape(grid.nz, grid.nx)


# ------------------------------------------------------------------------------------------------------ steering
@njit(cache=True, inline="always")
def _sample(F, g, px, pz, x0, z0, h, nx, nz):
    """(dir_x, dir_z, value) at (px, pz) of field g of F (nz, nx, G) (module docstring)."""
    fx = (px - x0) / h
    fz = (pz - z0) / h
    i = min(max(int(math.floor(fx)), 0), nx - 2)
    j = min(max(int(math.floor(fz)), 0), nz - 2)
    tx = min(max(fx - i, 0.0), 1.0)
    tz = min(max(fz - j, 0.0), 1.0)
    d00 = np.float64(F[j, i, g])
    d10 = np.float64(F[j, i + 1, g])
    d01 = np.float64(F[j + 1, i, g])
    d11 = np.float64(F[j + 1, i + 1, g])
    gx = (d10 - d00) * (1.0 - tz) + (d11 - d01) * tz
    gz = (d01 - d00) * (1.0 - tx) + (d11 - d10) * tx
    v = (d00 * (1.0 - tx) + d10 * tx) * (1.0 - tz) + (d01 * (1.0 - tx) + d11 * tx) * tz
    ll = math.sqrt(gx * gx + gz * gz)
    if ll > FLAT_GRADIENT * h:
        return -gx / ll, -gz / ll, v
    # flat: towards the lowest of the four nodes (none lower than the others: stay)
    best, bx, bz = d00, float(i), float(j)
    if d10 < best:
        best, bx, bz = d10, float(i + 1), float(j)
    if d01 < best:
        best, bx, bz = d01, float(i), float(j + 1)
    if d11 < best:
        best, bx, bz = d11, float(i + 1), float(j + 1)
    dx = x0 + bx * h - px
    dz = z0 + bz * h - pz
    ll = math.sqrt(dx * dx + dz * dz)
    if best < max(d00, d10, d01, d11) and ll > 1e-12:
        return dx / ll, dz / ll, v
    return 0.0, 0.0, v


@njit(cache=True, inline="always")
def _consider(c, g, px, pz, corners, D, nxt, ahead, eps, best, bval):
    """Corner c as a candidate of the agent at (px, pz): value D + distance. A corner the agent has passed (it
    stands on it, or beyond the line through it across the way to its next: ``ahead[g, c]``, the next corner or
    the goal's point nearest to it) hands over to its next. Returns (best, bval, goal_next): goal_next: the corner
    handed over to the goal."""
    for _ in range(8):
        cx, cz = corners[c, 0], corners[c, 1]
        d = math.sqrt((cx - px) ** 2 + (cz - pz) ** 2)
        if d >= eps and (px - cx) * (ahead[g, c, 0] - cx) + (pz - cz) * (ahead[g, c, 1] - cz) <= 0.0:
            v = D[g, c] + d
            if v < bval:
                return c, v, False
            return best, bval, False
        c2 = nxt[g, c]
        if c2 == VIA_GOAL:
            return best, bval, True
        if c2 < 0:
            return best, bval, False
        c = c2
    return best, bval, False


@njit(cache=True, inline="always")
def steer_one(F, V, g, px, pz, x0, z0, h, nx, nz, corners, D, nxt, ahead, gseg, gstart, garea, eps, use_via):
    """(dir_x, dir_z, route length) of an agent at (px, pz) heading to goal g: the least of the vias of the four
    nodes around it (module docstring of :mod:`sim.routing.corners`), by exact route length: straight at a
    corner, or at the goal's nearest point; the field's gradient where no node has a via (walls). The common case
    in the open (every node round the agent sees its point goal) is tested first; the rest is :func:`_steer_vias`."""
    if not use_via:
        return _sample(F, g, px, pz, x0, z0, h, nx, nz)
    i = min(max(int(math.floor((px - x0) / h)), 0), nx - 2)
    j = min(max(int(math.floor((pz - z0) / h)), 0), nz - 2)
    s0 = gstart[g]
    if (V[j, i, g] == VIA_GOAL and V[j, i + 1, g] == VIA_GOAL and V[j + 1, i, g] == VIA_GOAL
            and V[j + 1, i + 1, g] == VIA_GOAL and not garea[g] and gstart[g + 1] - s0 == 1
            and gseg[s0, 0] == gseg[s0, 2] and gseg[s0, 1] == gseg[s0, 3]):
        dx, dz = gseg[s0, 0] - px, gseg[s0, 1] - pz
        d = math.sqrt(dx * dx + dz * dz)
        if d > 1e-9:
            return dx / d, dz / d, d
        return 0.0, 0.0, 0.0
    return _steer_vias(F, V, g, px, pz, i, j, x0, z0, h, nx, nz, corners, D, nxt, ahead, gseg, gstart, garea, eps)


@njit(cache=True, inline="always")
def _steer_vias(F, V, g, px, pz, i, j, x0, z0, h, nx, nz, corners, D, nxt, ahead, gseg, gstart, garea, eps):
    """:func:`steer_one` at an agent in cell (i, j) whose nodes do not all see a point goal."""
    best, bval = VIA_NONE, np.inf
    goal = False
    last = VIA_NONE
    for q in range(4):
        c = np.int64(V[j + (q >> 1), i + (q & 1), g])
        if c == VIA_GOAL:
            goal = True
        elif c >= 0 and c != last:  # neighbouring nodes mostly share their via: evaluate it once
            last = c
            best, bval, gn = _consider(c, g, px, pz, corners, D, nxt, ahead, eps, best, bval)
            goal = goal or gn
    if goal:
        d, qx, qz = goal_nearest(px, pz, gseg, gstart[g], gstart[g + 1], garea[g])
        if d <= bval:
            if d > 1e-9:
                return (qx - px) / d, (qz - pz) / d, d
            return 0.0, 0.0, 0.0
    if best >= 0:
        d = math.sqrt((corners[best, 0] - px) ** 2 + (corners[best, 1] - pz) ** 2)
        return (corners[best, 0] - px) / d, (corners[best, 1] - pz) / d, bval
    return _sample(F, g, px, pz, x0, z0, h, nx, nz)


@njit(cache=True, parallel=True)
def directions_kernel(pos, goal, F, V, corners, D, nxt, ahead, gseg, gstart, garea, x0, z0, h, nx, nz, eps, use_via,
                      out, dist):
    """Per agent a: out[a] = unit desired direction (x, z) towards goal goal[a] from pos[a] (x, z = columns 0, 2),
    reading the fields F (nz, nx, G) float32 and vias V (nz, nx, G) int16/int32 (goals interleaved per node: the
    agents at one place share cache lines whatever their goals),
    dist[a] = remaining route length (inf: unreachable); goal[a] < 0: out 0, dist inf. ``use_via``: steer at the
    nodes' vias (:func:`steer_one`), else down the gradient only. Goal g's shape: segments
    ``gseg[gstart[g]:gstart[g + 1]]``, an area when ``garea[g]`` (:func:`sim.routing.corners.goal_nearest`);
    ``ahead`` (G, C, 2): each corner's next corner or nearest goal point (:func:`ahead_points`)."""
    big = np.float64(UNREACHABLE) * 0.5
    for a in prange(pos.shape[0]):
        g = goal[a]
        if g < 0:
            out[a, 0] = 0.0
            out[a, 1] = 0.0
            dist[a] = np.inf
            continue
        ux, uz, v = steer_one(F, V, g, pos[a, 0], pos[a, 2], x0, z0, h, nx, nz, corners, D, nxt, ahead, gseg, gstart,
                              garea, eps, use_via)
        out[a, 0] = ux
        out[a, 1] = uz
        dist[a] = v if v < big else np.inf


def ahead_points(corners: np.ndarray, nxt: np.ndarray, gseg: np.ndarray, area: bool) -> np.ndarray:
    """(C, 2) float64: where each corner's route goes next: its next corner, or the goal's point nearest to it."""
    out = np.empty((corners.shape[0], 2))
    for c in range(corners.shape[0]):
        if nxt[c] >= 0:
            out[c] = corners[nxt[c]]
        else:
            out[c] = goal_nearest(corners[c, 0], corners[c, 1], gseg, 0, gseg.shape[0], area)[1:]
    return out


def directions_numpy(pos, goal, F, grid: Grid):
    """Plain numpy reference of :func:`directions_kernel` with ``use_via`` false (the gradient): returns
    (out (n, 2), dist (n,))."""
    n = pos.shape[0]
    out, dist = np.zeros((n, 2)), np.full(n, np.inf)
    has = goal >= 0
    g = goal[has]
    h = grid.h
    fx = (pos[has, 0] - grid.x0) / h
    fz = (pos[has, 2] - grid.z0) / h
    i = np.clip(np.floor(fx).astype(np.int64), 0, grid.nx - 2)
    j = np.clip(np.floor(fz).astype(np.int64), 0, grid.nz - 2)
    tx, tz = np.clip(fx - i, 0.0, 1.0), np.clip(fz - j, 0.0, 1.0)
    d = [F[j + b, i + a, g].astype(np.float64) for a, b in ((0, 0), (1, 0), (0, 1), (1, 1))]
    gx = (d[1] - d[0]) * (1 - tz) + (d[3] - d[2]) * tz
    gz = (d[2] - d[0]) * (1 - tx) + (d[3] - d[1]) * tx
    v = (d[0] * (1 - tx) + d[1] * tx) * (1 - tz) + (d[2] * (1 - tx) + d[3] * tx) * tz
    ll = np.hypot(gx, gz)
    steep = ll > FLAT_GRADIENT * h
    ux = np.where(steep, -gx / np.where(steep, ll, 1.0), 0.0)
    uz = np.where(steep, -gz / np.where(steep, ll, 1.0), 0.0)
    D = np.stack(d, 1)
    k = np.argmin(D, 1)  # first minimum: the kernel's order (00, 10, 01, 11)
    bx, bz = i + np.array([0, 1, 0, 1])[k], j + np.array([0, 0, 1, 1])[k]
    dx, dz = grid.x0 + bx * h - pos[has, 0], grid.z0 + bz * h - pos[has, 2]
    lb = np.hypot(dx, dz)
    go = ~steep & (D.min(1) < D.max(1)) & (lb > 1e-12)
    ux = np.where(go, dx / np.where(go, lb, 1.0), ux)
    uz = np.where(go, dz / np.where(go, lb, 1.0), uz)
    out[has, 0], out[has, 1] = ux, uz
    dist[has] = np.where(v < float(UNREACHABLE) * 0.5, v, np.inf)
    return out, dist


def steer_numpy(pos, goal, F, V, corners, D, nxt, gseg, gstart, garea, grid: Grid, eps: float):
    """Plain Python reference of :func:`directions_kernel` with ``use_via`` true (one agent at a time, the
    gradient part from :func:`directions_numpy`, the goal's nearest point by shapely): returns (out (n, 2),
    dist (n,))."""
    from sim.routing.corners import goal_nearest_numpy

    n = pos.shape[0]
    out, dist = directions_numpy(pos, goal, F, grid)
    for a in range(n):
        g = int(goal[a])
        if g < 0:
            continue
        px, pz = float(pos[a, 0]), float(pos[a, 2])
        seg, area = gseg[gstart[g]:gstart[g + 1]], bool(garea[g])
        i = min(max(int(math.floor((px - grid.x0) / grid.h)), 0), grid.nx - 2)
        j = min(max(int(math.floor((pz - grid.z0) / grid.h)), 0), grid.nz - 2)
        cands, goal_seen = [], False
        for jj, ii in ((j, i), (j, i + 1), (j + 1, i), (j + 1, i + 1)):
            c = int(V[jj, ii, g])
            if c == VIA_GOAL:
                goal_seen = True
            for _ in range(8):  # hand passed corners over to their next
                if c < 0:
                    break
                c2 = int(nxt[g, c])
                ahead = corners[c2] if c2 >= 0 else np.array(goal_nearest_numpy(corners[c], seg, area)[1:])
                d = math.hypot(corners[c, 0] - px, corners[c, 1] - pz)
                if d >= eps and np.dot((px, pz) - corners[c], ahead - corners[c]) <= 0.0:
                    cands.append((D[g, c] + d, c))
                    break
                goal_seen |= c2 == VIA_GOAL
                c = c2
        best = min(cands, key=lambda t: t[0]) if cands else (math.inf, VIA_NONE)
        res = None
        if goal_seen:
            d, qx, qz = goal_nearest_numpy((px, pz), seg, area)
            if d <= best[0]:
                res = ((qx - px) / d, (qz - pz) / d, d) if d > 1e-9 else (0.0, 0.0, 0.0)
        if res is None and best[1] >= 0:
            c = best[1]
            d = math.hypot(corners[c, 0] - px, corners[c, 1] - pz)
            res = ((corners[c, 0] - px) / d, (corners[c, 1] - pz) / d, best[0])
        if res is not None:
            out[a], dist[a] = res[:2], res[2]
    return out, dist
