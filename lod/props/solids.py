"""Solids of the ``obstacles`` effect's shapes and the ground representation.

Every visible circle, box and polygon of a ``sim.obstacles.ObstacleSet`` is
extruded into a prism of its ``height`` standing on the ground: circles as
:data:`CIRCLE_SEGMENTS`-gons circumscribing the circle (the solid covers the
whole shape agents are kept out of), polygons capped by ear clipping (simple
polygons of either winding, Meisters, *Polygons have ears*, 1975). All solids
are one flat-shaded mesh whose vertices are relative to their centroid (the
instance's translation), so obstacles far from the origin keep their float32
precision once made camera-relative.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lod.props.chain import PropChainRep, bounding_sphere

#: sides of the prism drawn for a circle obstacle
CIRCLE_SEGMENTS = 32
#: linear RGB of obstacle solids
OBSTACLE_COLOR = (0.58, 0.47, 0.36)
#: the solids reach this far below the ground (no gap on uneven terrain)
SINK = 0.05
#: representation keys
OBSTACLES_KEY = "world:obstacles"
GROUND_KEY = "world:ground"
#: linear RGB of the ground plane
GROUND_COLOR = (0.46, 0.47, 0.45)


@dataclass
class GroundRep:
    """The ground plane y = ``height`` (drawn by ``render.world.draw`` with its grid).

    color : (3,) linear RGB
    """

    key: str = GROUND_KEY
    height: float = 0.0
    color: tuple = GROUND_COLOR

    kind = "world"


def _signed_area(p: np.ndarray) -> float:
    x, z = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x * np.roll(z, -1) - np.roll(x, -1) * z))


def triangulate_polygon(points) -> np.ndarray:
    """(k - 2, 3) int64 triangles of a simple polygon (k, 2) by ear clipping, counter-clockwise in
    the (x, z) plane order of the input's own winding made positive; degenerate input gives a fan."""
    p = np.asarray(points, np.float64).reshape(-1, 2)
    n = len(p)
    order = list(range(n)) if _signed_area(p) >= 0 else list(range(n))[::-1]
    tris = []

    def cross(a, b, c):
        return (p[b, 0] - p[a, 0]) * (p[c, 1] - p[a, 1]) - (p[b, 1] - p[a, 1]) * (p[c, 0] - p[a, 0])

    def inside(q, a, b, c):
        return cross(a, b, q) >= 0 and cross(b, c, q) >= 0 and cross(c, a, q) >= 0

    guard = 0
    while len(order) > 3 and guard < 4 * n * n:
        guard += 1
        m = len(order)
        for i in range(m):
            a, b, c = order[i - 1], order[i], order[(i + 1) % m]
            if cross(a, b, c) <= 1e-15:
                continue
            if any(inside(q, a, b, c) for q in order if q not in (a, b, c)):
                continue
            tris.append((a, b, c))
            order.pop(i)
            break
        else:  # no ear (degenerate or self-intersecting input): close with a fan
            break
    for i in range(1, len(order) - 1):
        tris.append((order[0], order[i], order[i + 1]))
    return np.asarray(tris, np.int64).reshape(-1, 3)


def _prism(ring: np.ndarray, bottom: np.ndarray, top: float) -> tuple:
    """Flat-shaded side and top triangles of a prism over ``ring`` (k, 2): positions (3T, 3), normals (3T, 3)."""
    if _signed_area(ring) < 0:
        ring, bottom = ring[::-1], bottom[::-1]
    k = len(ring)
    pos, nrm = [], []
    for i in range(k):
        j = (i + 1) % k
        a0 = [ring[i, 0], bottom[i], ring[i, 1]]
        b0 = [ring[j, 0], bottom[j], ring[j, 1]]
        a1 = [ring[i, 0], top, ring[i, 1]]
        b1 = [ring[j, 0], top, ring[j, 1]]
        ex, ez = ring[j, 0] - ring[i, 0], ring[j, 1] - ring[i, 1]
        ln = math.hypot(ex, ez)
        if ln <= 0:
            continue
        n = [ez / ln, 0.0, -ex / ln]  # outward for a counter-clockwise (x, z) ring
        pos += [a0, b0, b1, a0, b1, a1]
        nrm += [n] * 6
    for t in triangulate_polygon(ring):
        pos += [[ring[q, 0], top, ring[q, 1]] for q in t]
        nrm += [[0.0, 1.0, 0.0]] * 3
    return pos, nrm


def obstacle_rings(obs) -> list:
    """``[(ring (k, 2) float64, height)]`` of the visible shapes of an ObstacleSet with height > 0."""
    out = []
    cd = getattr(obs, "circle_draw", np.zeros((len(obs.circles), 2)))
    for (cx, cz, r), (h, vis) in zip(obs.circles, cd):
        if vis and h > 0:
            a = (np.arange(CIRCLE_SEGMENTS) + 0.5) * (2 * math.pi / CIRCLE_SEGMENTS)
            rr = r / math.cos(math.pi / CIRCLE_SEGMENTS)  # circumscribed: covers the circle
            out.append((np.stack([cx + rr * np.cos(a), cz + rr * np.sin(a)], 1), float(h)))
    pd = getattr(obs, "poly_draw", np.zeros((len(obs.pbound), 2)))
    for k, (h, vis) in enumerate(pd):
        if vis and h > 0:
            out.append((np.asarray(obs.verts[obs.pstart[k]:obs.pstart[k + 1]], np.float64), float(h)))
    return out


def obstacle_solids(obs, ground=None, key: str = OBSTACLES_KEY, color=OBSTACLE_COLOR):
    """The solids of an ObstacleSet as one single-level chain rep and its model rows.

    Parameters
    ----------
    obs : sim.obstacles.ObstacleSet (with ``circle_draw``/``poly_draw``)
    ground : optional ``ground(x, z) -> y`` arrays (terrain height); default y = 0

    Returns
    -------
    (PropChainRep, (1, 3, 4) float64 model rows) or None when nothing is visible
    """
    rings = obstacle_rings(obs)
    if not rings:
        return None
    pos, nrm = [], []
    for ring, h in rings:
        bottom = np.zeros(len(ring)) if ground is None else np.asarray(ground(ring[:, 0], ring[:, 1]), np.float64)
        p, n = _prism(ring, bottom - SINK, float(bottom.max()) + h)
        pos += p
        nrm += n
    pos = np.asarray(pos, np.float64)
    anchor = 0.5 * (pos.min(0) + pos.max(0))
    rel = pos - anchor
    colors = np.ones((len(pos), 4), np.float32)
    colors[:, :3] = color
    rep = PropChainRep(key=key, positions=rel.astype(np.float32), normals=np.asarray(nrm, np.float32),
                       colors=colors, indices=np.arange(len(pos), dtype=np.uint32).reshape(-1, 3),
                       level_first=np.zeros(1, np.int64), level_count=np.array([len(pos) // 3], np.int64),
                       level_error=np.zeros(1), sphere=bounding_sphere(rel))
    rows = np.zeros((1, 3, 4))
    rows[0, :, :3] = np.eye(3)
    rows[0, :, 3] = anchor
    return rep, rows
