"""Corners of the free space and the exact next corner of every grid node (the string-pulled route).

Descending the gradient of a grid distance field rounds every corner a little wide and wobbles along walls (2-4 %
longer routes around a U-shaped wall at a grid spacing of half the clearance, ``scripts/bench_routing.md``). The
shortest path in a polygonal domain is a taut string: straight segments between reflex vertices of the free space
(Lozano-Pérez & Wesley 1979; the visibility graph, de Berg et al., *Computational Geometry*, ch. 15). So every
node of a goal's grid also stores the first point of its shortest path, its *via*: a corner of the free space or
the goal itself, and agents steer straight at the via of their cell. This module computes, per goal:

- the free space: the walkable area shrunk by the clearance (``buffer(-clearance)``, round joins of
  :data:`ARC_SEGMENTS` per quarter circle: the corners of the clearance arcs are exact, the chords between them
  lie at most ``clearance * (1 - cos(pi / (4 * ARC_SEGMENTS)))`` inside them); its *corners* are the vertices
  where the free space turns towards the walls (reflex vertices);
- ``D``, the exact route length from each corner to the goal: Dijkstra over the visibility graph of the corners
  and the goal (segment tests against the free space's edges, bucketed on a coarse grid: :func:`visible`);
- the via of every free node (:func:`via_kernel`): nodes are visited in increasing field value (the fast
  marching order); a node's candidates are the vias of its eight neighbours visited before it, the corners within
  two cells of it and the goal; the visible candidate with the least ``D(c) + |p - c|`` (the goal: the exact
  distance to it, a line or polygon goal: the field's value) is its via. The set of nodes whose via is corner
  ``c`` is star-shaped around ``c`` (a subpath of a shortest path is one), so it is reached from the nodes next
  to ``c`` through neighbours that share it.

Via codes: ``>= 0`` a corner, :data:`VIA_GOAL` the goal (a point goal: steer at it; a line or polygon goal: the
field's gradient), :data:`VIA_NONE` no via (a node of the clearance band or a wall: the gradient leads out).
"""
from __future__ import annotations

import heapq
import math

import numpy as np
from numba import njit

#: round-join segments per quarter circle of the clearance arcs around wall corners
ARC_SEGMENTS = 4
#: via codes besides corner indices
VIA_GOAL, VIA_NONE = -1, -2
#: edge buckets: about this many edges per bucket on average, never smaller than 4 grid cells
BUCKET_EDGES = 4.0


def free_space(walkable_area, clearance: float):
    """The walkable area shrunk by ``clearance`` (shapely, oriented: exteriors counter-clockwise)."""
    import shapely
    from shapely.geometry.polygon import orient

    g = walkable_area.buffer(-clearance, quad_segs=ARC_SEGMENTS) if clearance > 0 else walkable_area
    polys = [orient(p, 1.0) for p in getattr(g, "geoms", [g]) if p.geom_type == "Polygon" and not p.is_empty]
    return shapely.MultiPolygon(polys) if len(polys) != 1 else polys[0]


def rings_of(free) -> list:
    out = []
    for p in getattr(free, "geoms", [free]):
        if p.is_empty:
            continue
        for ring in [p.exterior, *p.interiors]:
            out.append(np.asarray(ring.coords, np.float64)[:-1])
    return out


def reflex_corners(rings: list) -> tuple:
    """(corners (C, 2) float64, wedges (C, 4) float64): the vertices where an oriented ring (interior on the
    left) turns right, and per corner the directions (ux, uz, wx, wz) to its previous and next vertex, which
    bound the wall's wedge there (less than a half-turn wide: :func:`wedge_ok`)."""
    out, wedges = [], []
    for r in rings:
        if r.shape[0] < 3:
            continue
        a, b, c = np.roll(r, 1, 0), r, np.roll(r, -1, 0)
        cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - b[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - b[:, 0])
        sel = cross < -1e-12
        out.append(r[sel])
        wedges.append(np.concatenate([a[sel] - b[sel], c[sel] - b[sel]], 1))
    if not out:
        return np.zeros((0, 2)), np.zeros((0, 4))
    return np.concatenate(out, 0), np.concatenate(wedges, 0)


@njit(cache=True, inline="always")
def wedge_ok(wedges, c, dx, dz):
    """False when the direction (dx, dz) leaves corner c into its wall (strictly inside the wedge between the
    directions to its previous and next vertex). A segment between two vertices can cross no edge properly and
    still run inside a wall, entering and leaving it at its ends: the wedge test at each end excludes it."""
    ux, uz, wx, wz = wedges[c, 0], wedges[c, 1], wedges[c, 2], wedges[c, 3]
    s = ux * wz - uz * wx
    a = ux * dz - uz * dx
    b = dx * wz - dz * wx
    return not (a * s > 0.0 and b * s > 0.0)


class EdgeBuckets:
    """The free space's edges in a uniform grid of buckets (CSR): ``ex0, ez0, ex1, ez1`` (E,) float64;
    bucket (bi, bj) holds ``items[start[bj * nbx + bi]:start[bj * nbx + bi + 1]]``."""

    def __init__(self, rings: list, bounds: tuple, min_size: float):
        from sim.routing.geometry import edges_of

        self.ex0, self.ez0, self.ex1, self.ez1 = edges_of(rings)
        x0, z0, x1, z1 = bounds
        e = max(self.ex0.shape[0], 1)
        size = max(min_size, math.sqrt(max((x1 - x0) * (z1 - z0), 1e-9) * BUCKET_EDGES / e))
        self.bx0, self.bz0, self.size = float(x0) - size, float(z0) - size, float(size)
        self.nbx = int(math.ceil((x1 - self.bx0) / size)) + 2
        self.nbz = int(math.ceil((z1 - self.bz0) / size)) + 2
        self.start, self.items = _bucket_edges(self.ex0, self.ez0, self.ex1, self.ez1, self.bx0, self.bz0,
                                               self.size, self.nbx, self.nbz)

    def args(self) -> tuple:
        return (self.ex0, self.ez0, self.ex1, self.ez1, self.bx0, self.bz0, self.size, self.nbx, self.nbz,
                self.start, self.items)


@njit(cache=True)
def _bucket_edges(ex0, ez0, ex1, ez1, bx0, bz0, size, nbx, nbz):
    """CSR of the buckets each edge's bounding box overlaps."""
    count = np.zeros(nbx * nbz + 1, np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            for b in range(nbx * nbz):
                count[b + 1] += count[b]
            items = np.empty(count[nbx * nbz], np.int64)
            fill = count[:-1].copy()
        for e in range(ex0.shape[0]):
            i0 = min(max(int((min(ex0[e], ex1[e]) - bx0) / size), 0), nbx - 1)
            i1 = min(max(int((max(ex0[e], ex1[e]) - bx0) / size), 0), nbx - 1)
            j0 = min(max(int((min(ez0[e], ez1[e]) - bz0) / size), 0), nbz - 1)
            j1 = min(max(int((max(ez0[e], ez1[e]) - bz0) / size), 0), nbz - 1)
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    if pass_ == 0:
                        count[j * nbx + i + 1] += 1
                    else:
                        items[fill[j * nbx + i]] = e
                        fill[j * nbx + i] += 1
    return count, items


@njit(cache=True, inline="always")
def _orient(ax, az, bx, bz, cx, cz):
    return (bx - ax) * (cz - az) - (bz - az) * (cx - ax)


@njit(cache=True)
def _crosses_bucket(px, pz, qx, qz, b, ex0, ez0, ex1, ez1, start, items):
    for s in range(start[b], start[b + 1]):
        e = items[s]
        ax, az, bx, bz = ex0[e], ez0[e], ex1[e], ez1[e]
        d1 = _orient(ax, az, bx, bz, px, pz)
        d2 = _orient(ax, az, bx, bz, qx, qz)
        if d1 * d2 >= 0.0:
            continue
        d3 = _orient(px, pz, qx, qz, ax, az)
        d4 = _orient(px, pz, qx, qz, bx, bz)
        if d3 * d4 < 0.0:
            return True
    return False


@njit(cache=True)
def visible(px, pz, qx, qz, ex0, ez0, ex1, ez1, bx0, bz0, size, nbx, nbz, start, items):
    """True when the segment p -> q crosses no edge properly (touching a vertex or running along an edge is not
    a crossing): the buckets along the segment are walked in order (Amanatides & Woo 1987)."""
    fx, fz = (px - bx0) / size, (pz - bz0) / size
    gx, gz = (qx - bx0) / size, (qz - bz0) / size
    i, j = int(math.floor(fx)), int(math.floor(fz))
    ti, tj = int(math.floor(gx)), int(math.floor(gz))
    dx, dz = gx - fx, gz - fz
    si = 1 if dx > 0 else -1
    sj = 1 if dz > 0 else -1
    tdx = abs(1.0 / dx) if dx != 0.0 else np.inf
    tdz = abs(1.0 / dz) if dz != 0.0 else np.inf
    tmx = ((i + 1 - fx) if dx > 0 else (fx - i)) * tdx if dx != 0.0 else np.inf
    tmz = ((j + 1 - fz) if dz > 0 else (fz - j)) * tdz if dz != 0.0 else np.inf
    for _ in range(nbx + nbz + 4):
        if 0 <= i < nbx and 0 <= j < nbz:
            if _crosses_bucket(px, pz, qx, qz, j * nbx + i, ex0, ez0, ex1, ez1, start, items):
                return False
        if i == ti and j == tj:
            break
        if tmx < tmz:
            tmx += tdx
            i += si
        else:
            tmz += tdz
            j += sj
    return True


def visible_numpy(p, q, rings) -> bool:
    """Plain reference of :func:`visible`: every edge tested."""
    from sim.routing.geometry import edges_of

    ex0, ez0, ex1, ez1 = edges_of(rings)
    o = lambda ax, az, bx, bz, cx, cz: (bx - ax) * (cz - az) - (bz - az) * (cx - ax)  # noqa: E731
    d1 = o(ex0, ez0, ex1, ez1, p[0], p[1])
    d2 = o(ex0, ez0, ex1, ez1, q[0], q[1])
    d3 = o(p[0], p[1], q[0], q[1], ex0, ez0)
    d4 = o(p[0], p[1], q[0], q[1], ex1, ez1)
    return not bool(np.any((d1 * d2 < 0) & (d3 * d4 < 0)))


# --------------------------------------------------------------------------------------------- corner distances
@njit(cache=True)
def _visibility_matrix(P, W, ex0, ez0, ex1, ez1, bx0, bz0, size, nbx, nbz, start, items):
    n = P.shape[0]
    vis = np.zeros((n, n), np.bool_)
    for a in range(n):
        vis[a, a] = True
        for b in range(a + 1, n):
            dx, dz = P[b, 0] - P[a, 0], P[b, 1] - P[a, 1]
            if not (wedge_ok(W, a, dx, dz) and wedge_ok(W, b, -dx, -dz)):
                continue
            if visible(P[a, 0], P[a, 1], P[b, 0], P[b, 1], ex0, ez0, ex1, ez1, bx0, bz0, size, nbx, nbz, start,
                       items):
                vis[a, b] = True
                vis[b, a] = True
    return vis


def visibility_matrix(corners: np.ndarray, wedges: np.ndarray, buckets: EdgeBuckets) -> np.ndarray:
    """(C, C) bool: which corners see each other (the edges of the visibility graph; the same for every goal)."""
    if corners.shape[0] == 0:
        return np.zeros((0, 0), np.bool_)
    return _visibility_matrix(np.ascontiguousarray(corners), np.ascontiguousarray(wedges), *buckets.args())


@njit(cache=True)
def _dijkstra_dense(P, vis, D, nxt):
    """Dijkstra on the dense visibility graph (O(C^2), no heap: every corner is a neighbour candidate)."""
    c = P.shape[0]
    done = np.zeros(c, np.bool_)
    for _ in range(c):
        k, best = -1, np.inf
        for m in range(c):
            if not done[m] and D[m] < best:
                k, best = m, D[m]
        if k < 0:
            break
        done[k] = True
        for m in range(c):
            if vis[k, m] and not done[m]:
                v = best + math.sqrt((P[m, 0] - P[k, 0]) ** 2 + (P[m, 1] - P[k, 1]) ** 2)
                if v < D[m]:
                    D[m] = v
                    nxt[m] = k


def corner_distances(corners: np.ndarray, vis: np.ndarray, goal_dist: np.ndarray) -> tuple:
    """(D (C,), next (C,) int64): the route length from each corner to the goal and its next corner
    (VIA_GOAL: the goal directly). ``vis``: :func:`visibility_matrix`; ``goal_dist`` (C,) float64: each corner's
    straight distance to the goal where it sees it, inf elsewhere. Dijkstra over the visibility graph (numba;
    :func:`corner_distances_numpy` is the heap reference)."""
    D = goal_dist.astype(np.float64).copy()
    nxt = np.where(np.isfinite(D), VIA_GOAL, VIA_NONE).astype(np.int64)
    if corners.shape[0]:
        _dijkstra_dense(np.ascontiguousarray(corners, np.float64), vis, D, nxt)
    return D, nxt


def corner_distances_numpy(corners: np.ndarray, vis: np.ndarray, goal_dist: np.ndarray) -> tuple:
    """Plain reference of :func:`corner_distances` (``heapq``)."""
    c = corners.shape[0]
    D = goal_dist.astype(np.float64).copy()
    nxt = np.where(np.isfinite(D), VIA_GOAL, VIA_NONE).astype(np.int64)
    if c == 0:
        return D, nxt
    heap = [(float(D[k]), k) for k in range(c) if np.isfinite(D[k])]
    heapq.heapify(heap)
    done = np.zeros(c, bool)
    while heap:
        d, k = heapq.heappop(heap)
        if done[k] or d > D[k]:
            continue
        done[k] = True
        seen = np.nonzero(vis[k] & ~done)[0]
        nd = d + np.hypot(corners[seen, 0] - corners[k, 0], corners[seen, 1] - corners[k, 1])
        better = nd < D[seen]
        for m, v in zip(seen[better], nd[better]):
            D[m] = v
            nxt[m] = k
            heapq.heappush(heap, (float(v), int(m)))
    return D, nxt


# ------------------------------------------------------------------------------------------------- node vias
def children_of(nxt: np.ndarray) -> tuple:
    """CSR (start (C + 2,), items) of the corners whose next is each corner; row C holds those whose next is the
    goal."""
    c = nxt.shape[0]
    parent = np.where(nxt == VIA_GOAL, c, nxt)
    ok = parent >= 0
    kids = np.nonzero(ok)[0]
    o = np.argsort(parent[ok], kind="stable")
    start = np.zeros(c + 2, np.int64)
    np.add.at(start, parent[ok] + 1, 1)
    return np.cumsum(start), kids[o].astype(np.int64)


@njit(cache=True, inline="always")
def _push(cand, nc, v):
    for t in range(nc):
        if cand[t] == v:
            return nc
    if nc < cand.shape[0]:
        cand[nc] = v
        nc += 1
    return nc


def goal_segments(shape) -> tuple:
    """(segments (S, 4) float64 rows (ax, az, bx, bz), area bool) of a goal shape: a point is one segment of
    length 0, a line one segment, a polygon its edges (area: its inside is the goal too)."""
    kind, g = shape
    if kind == "point":
        return np.array([[g[0], g[1], g[0], g[1]]], np.float64), False
    if kind == "line":
        return np.array([[g[0][0], g[0][1], g[1][0], g[1][1]]], np.float64), False
    p = np.asarray(g, np.float64)
    return np.concatenate([p, np.roll(p, -1, 0)], 1), True


@njit(cache=True, inline="always")
def goal_nearest(px, pz, gseg, s0, s1, area):
    """(distance, qx, qz): the point q of the goal (segments s0..s1 of ``gseg``; ``area``: the polygon they
    bound belongs to it) nearest to p; 0 and p itself inside an area."""
    best, qx, qz = np.inf, px, pz
    inside = False
    for s in range(s0, s1):
        ax, az, bx, bz = gseg[s, 0], gseg[s, 1], gseg[s, 2], gseg[s, 3]
        ux, uz = bx - ax, bz - az
        ll = ux * ux + uz * uz
        t = ((px - ax) * ux + (pz - az) * uz) / ll if ll > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        cx, cz = ax + t * ux, az + t * uz
        d2 = (px - cx) ** 2 + (pz - cz) ** 2
        if d2 < best:
            best, qx, qz = d2, cx, cz
        if area and ((az > pz) != (bz > pz)) and px < ax + (pz - az) / (bz - az) * ux:
            inside = not inside
    if inside:
        return 0.0, px, pz
    return math.sqrt(best), qx, qz


def goal_nearest_numpy(p, seg, area) -> tuple:
    """Plain reference of :func:`goal_nearest` (shapely)."""
    import shapely

    p = shapely.Point(float(p[0]), float(p[1]))
    if area:
        g = shapely.Polygon(np.asarray(seg)[:, :2])
        if g.covers(p):
            return 0.0, p.x, p.y
    else:
        a, b = np.asarray(seg)[0, :2], np.asarray(seg)[0, 2:]
        g = shapely.LineString([a, b]) if np.any(a != b) else shapely.Point(*a)
    q = shapely.shortest_line(g, p).coords[0]
    return float(np.hypot(q[0] - p.x, q[1] - p.y)), float(q[0]), float(q[1])


@njit(cache=True)
def via_kernel(order, nx, x0, z0, h, corners, wedges, D, kid_start, kids, seed_start, seed_items, gseg, area,
               ex0, ez0, ex1, ez1, bx0, bz0, size, nbx, nbz, start, items, via):
    """The via of every node in ``order`` (free nodes by increasing field value; module docstring), in place on
    ``via`` (all VIA_NONE on entry). The goal (segments ``gseg``, ``area``: :func:`goal_nearest`) is a candidate
    when the segment to its nearest point is visible, valued by that distance; it is tested at nodes next to one
    that sees it or within two cells of it (the nodes that see a goal are connected to it, as those of a corner).

    Candidates: the neighbours' vias and the seeded corners; when a candidate is hidden from the node (it lies in
    the shadow of a corner on the way), the corners whose next it is are tried in its place (the corner casting
    the shadow is one of them), down to three levels."""
    nz = via.shape[0] // nx
    C = corners.shape[0]
    cand = np.empty(256, np.int64)
    for q in range(order.shape[0]):
        k = order[q]
        i = k % nx
        j = k // nx
        px = x0 + i * h
        pz = z0 + j * h
        nc = 0
        goal_cand = False
        for dj in range(-1, 2):
            for di in range(-1, 2):
                ii, jj = i + di, j + dj
                if (di == 0 and dj == 0) or ii < 0 or jj < 0 or ii >= nx or jj >= nz:
                    continue
                v = via[jj * nx + ii]
                if v == VIA_GOAL:
                    goal_cand = True
                elif v >= 0:
                    nc = _push(cand, nc, v)
        for s in range(seed_start[k], seed_start[k + 1]):
            nc = _push(cand, nc, seed_items[s])
        best, bval = VIA_NONE, np.inf
        gd, gx, gz = goal_nearest(px, pz, gseg, 0, gseg.shape[0], area)
        if gd == 0.0 or ((goal_cand or gd <= 2.0 * h) and visible(px, pz, gx, gz, ex0, ez0, ex1, ez1, bx0, bz0,
                                                                   size, nbx, nbz, start, items)):
            best, bval = VIA_GOAL, gd
        elif goal_cand:  # the goal is hidden: the corners that see it
            for s in range(kid_start[C], kid_start[C + 1]):
                nc = _push(cand, nc, kids[s])
        t = 0
        level_end = nc
        level = 0
        while t < nc:
            c = cand[t]
            t += 1
            d = math.sqrt((corners[c, 0] - px) ** 2 + (corners[c, 1] - pz) ** 2)
            # a candidate no better than the best so far is not tested (nor are the corners whose next it is: by
            # the triangle inequality they are no better either)
            if D[c] + d < bval:
                if wedge_ok(wedges, c, px - corners[c, 0], pz - corners[c, 1]) and visible(
                        px, pz, corners[c, 0], corners[c, 1], ex0, ez0, ex1, ez1, bx0, bz0, size, nbx, nbz, start,
                        items):
                    best, bval = c, D[c] + d
                elif level < 3:
                    for s in range(kid_start[c], kid_start[c + 1]):
                        nc = _push(cand, nc, kids[s])
            if t == level_end:
                level += 1
                level_end = nc
        via[k] = best


def node_seeds(grid, free: np.ndarray, corners: np.ndarray) -> tuple:
    """CSR (start (N + 1,), items) of the corners seeded at each node: those within two cells of it (free nodes
    only); the same for every goal."""
    h = grid.h
    pairs_n, pairs_c = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    if corners.shape[0]:
        ci = np.round((corners[:, 0] - grid.x0) / h).astype(np.int64)
        cj = np.round((corners[:, 1] - grid.z0) / h).astype(np.int64)
        for dj in range(-2, 3):
            for di in range(-2, 3):
                ii, jj = ci + di, cj + dj
                ok = (ii >= 0) & (jj >= 0) & (ii < grid.nx) & (jj < grid.nz)
                ii, jj, cc = ii[ok], jj[ok], np.nonzero(ok)[0]
                px, pz = grid.x0 + ii * h, grid.z0 + jj * h
                near = (np.hypot(px - corners[cc, 0], pz - corners[cc, 1]) <= 2.0 * h) & free[jj, ii]
                pairs_n.append(jj[near] * grid.nx + ii[near])
                pairs_c.append(cc[near].astype(np.int64))
    nodes = np.concatenate(pairs_n)
    items = np.concatenate(pairs_c)
    o = np.argsort(nodes, kind="stable")
    nodes, items = nodes[o], items[o]
    start = np.zeros(grid.nodes + 1, np.int64)
    np.add.at(start, nodes + 1, 1)
    return np.cumsum(start), items


def via_numpy(order, nx, x0, z0, h, corners, wedges, D, kid_start, kids, seed_start, seed_items, gseg, area,
              rings, n_nodes):
    """Plain Python reference of :func:`via_kernel` (every edge tested by :func:`visible_numpy`, the wedge test
    written out, the goal's nearest point by shapely): returns via (n_nodes,) int32."""
    nz = n_nodes // nx
    via = np.full(n_nodes, VIA_NONE, np.int32)

    def sees(px, pz, c):
        ux, uz, wx, wz = wedges[c]
        dx, dz = px - corners[c, 0], pz - corners[c, 1]
        s = ux * wz - uz * wx
        inside = (ux * dz - uz * dx) * s > 0 and (dx * wz - dz * wx) * s > 0
        return not inside and visible_numpy((px, pz), tuple(corners[c]), rings)

    for k in order:
        i, j = int(k) % nx, int(k) // nx
        px, pz = x0 + i * h, z0 + j * h
        cand, goal_cand = [], False
        for dj in (-1, 0, 1):
            for di in (-1, 0, 1):
                ii, jj = i + di, j + dj
                if (di or dj) and 0 <= ii < nx and 0 <= jj < nz:
                    v = int(via[jj * nx + ii])
                    if v == VIA_GOAL:
                        goal_cand = True
                    elif v >= 0 and v not in cand:
                        cand.append(v)
        cand += [int(v) for v in seed_items[seed_start[k]:seed_start[k + 1]] if int(v) not in cand]
        best, bval = VIA_NONE, math.inf
        gd, gx, gz = goal_nearest_numpy((px, pz), gseg, area)
        if gd == 0.0 or ((goal_cand or gd <= 2.0 * h) and visible_numpy((px, pz), (gx, gz), rings)):
            best, bval = VIA_GOAL, gd
        elif goal_cand:
            cand += [int(c) for c in kids[kid_start[len(corners)]:kid_start[len(corners) + 1]] if c not in cand]
        level_start = 0
        for level in range(4):
            level_end = len(cand)
            for t in range(level_start, level_end):
                c = cand[t]
                v = D[c] + math.hypot(corners[c, 0] - px, corners[c, 1] - pz)
                if not v < bval:
                    continue
                if sees(px, pz, c):
                    best, bval = c, v
                elif level < 3:
                    cand += [int(m) for m in kids[kid_start[c]:kid_start[c + 1]] if m not in cand]
            level_start = level_end
            if level_start == len(cand):
                break
        via[k] = best
    return via
