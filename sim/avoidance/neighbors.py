"""Shared numba helpers of the avoidance kernels: neighbour buckets of the
grid (:mod:`sim.grid`), the grid-ordered snapshot, line of sight through
obstacles and the push direction of coincident agents.

Every kernel visits the 3 x 3 cells around an agent in a fixed order
(x-offset major, as :mod:`sim.boids`) and, within a cell, agents by index
(the grid's stable sort), so each agent's result depends only on that fixed
order: bit-identical for any thread count.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.config import BOIDS_COINCIDENT_A, BOIDS_COINCIDENT_B
from sim.grid import cell_key
from sim.obstacles import box_dist2


@njit(cache=True, inline="always")
def bucket(o, ix, iz, gx, gz, dense, mask):
    """Bucket of the o-th (0..8) cell around (ix, iz), or -1 when outside the
    dense grid or already reached from an earlier offset (hashed grid)."""
    jx, jz = ix + (o // 3 - 1), iz + (o % 3 - 1)
    if dense:
        if jx < 0 or jz < 0 or jx >= gx or jz >= gz:
            return -1
        return jz * gx + jx
    key = cell_key(jx, jz, np.int64(gx), dense, np.int64(mask))
    for q in range(o):
        if cell_key(ix + (q // 3 - 1), iz + (q % 3 - 1), np.int64(gx), dense, np.int64(mask)) == key:
            return -1
    return key


@njit(cache=True)
def gather(position, radius, order, out):
    """out[k] = (x, z, r) of agent order[k] (neighbours contiguous in memory).
    Serial: memory-bound, and a parallel region costs a thread wake-up."""
    for k in range(order.shape[0]):
        i = order[k]
        out[k, 0] = position[i, 0]
        out[k, 1] = position[i, 2]
        out[k, 2] = radius[i]


@njit(cache=True, inline="always")
def coincident_dir(i, j):
    """Unit direction from agent i towards coincident agent j, hashed from the
    pair and antisymmetric (dir(j, i) = -dir(i, j)): coincident agents part."""
    lo, hi = min(i, j), max(i, j)
    t = (lo * BOIDS_COINCIDENT_A + hi * BOIDS_COINCIDENT_B) % 1.0
    sg = 1.0 if i < j else -1.0
    return sg * math.cos(2.0 * math.pi * t), sg * math.sin(2.0 * math.pi * t)


@njit(cache=True, inline="always")
def _cross(ax, az, bx, bz):
    return ax * bz - az * bx


@njit(cache=True)
def segments_cross(ax, az, bx, bz, cx, cz, dx, dz):
    """True when segments a-b and c-d intersect (touching counts)."""
    ux, uz = bx - ax, bz - az
    vx, vz = dx - cx, dz - cz
    d1 = _cross(ux, uz, cx - ax, cz - az)
    d2 = _cross(ux, uz, dx - ax, dz - az)
    d3 = _cross(vx, vz, ax - cx, az - cz)
    d4 = _cross(vx, vz, bx - cx, bz - cz)
    if ((d1 > 0.0 and d2 < 0.0) or (d1 < 0.0 and d2 > 0.0)) and ((d3 > 0.0 and d4 < 0.0) or (d3 < 0.0 and d4 > 0.0)):
        return True
    return False


@njit(cache=True)
def sight_blocked(px, pz, qx, qz, circles, verts, pstart, pbound, pbox):
    """True when the segment p-q crosses an obstacle (a circle it passes
    through, or a polygon edge it crosses). As JuPedSim's CFSM, neighbours
    behind a wall are ignored. Polygons whose bounding circle the segment
    misses, or whose bounding box (``pbox``, :func:`sim.obstacles.polygon_boxes`)
    does not overlap the segment's, are skipped (none of their edges can cross it)."""
    ux, uz = qx - px, qz - pz
    ll = ux * ux + uz * uz
    for c in range(circles.shape[0]):
        cx, cz, r = circles[c, 0], circles[c, 1], circles[c, 2]
        t = ((cx - px) * ux + (cz - pz) * uz) / ll if ll > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        ex, ez = px + t * ux - cx, pz + t * uz - cz
        if ex * ex + ez * ez < r * r:
            return True
    for k in range(pbound.shape[0]):
        # bounding-circle early out: the segment's closest point to the polygon's centre
        cx, cz, r = pbound[k, 0], pbound[k, 1], pbound[k, 2]
        t = ((cx - px) * ux + (cz - pz) * uz) / ll if ll > 0.0 else 0.0
        t = min(max(t, 0.0), 1.0)
        ex, ez = px + t * ux - cx, pz + t * uz - cz
        if ex * ex + ez * ez > r * r:
            continue
        if (min(px, qx) > pbox[k, 2] or max(px, qx) < pbox[k, 0] or min(pz, qz) > pbox[k, 3]
                or max(pz, qz) < pbox[k, 1]):
            continue
        s, e = pstart[k], pstart[k + 1]
        for a in range(s, e):
            b = a + 1 if a + 1 < e else s
            if segments_cross(px, pz, qx, qz, verts[a, 0], verts[a, 1], verts[b, 0], verts[b, 1]):
                return True
    return False


@njit(cache=True)
def obstacles_near(px, pz, reach, circles, pbound):
    """True when an obstacle's boundary (bounding circle for polygons) is
    within ``reach`` of p."""
    for c in range(circles.shape[0]):
        dx, dz = px - circles[c, 0], pz - circles[c, 1]
        if math.sqrt(dx * dx + dz * dz) - circles[c, 2] < reach:
            return True
    for k in range(pbound.shape[0]):
        dx, dz = px - pbound[k, 0], pz - pbound[k, 1]
        if math.sqrt(dx * dx + dz * dz) - pbound[k, 2] < reach:
            return True
    return False


@njit(cache=True)
def sight_may_block(px, pz, reach, circles, verts, pstart, pbound, pbox):
    """False when no segment from p shorter than ``reach`` can be blocked
    (:func:`sight_blocked` is then False for every neighbour within reach):
    no circle's boundary and no polygon edge is within ``reach`` of p. Exact
    for polygons (the distance to every edge of a polygon whose bounding
    box is near, ``pbox`` of :func:`polygon_boxes`), unlike
    :func:`obstacles_near`: long walls' bounding circles contain a whole room,
    their edges do not come near most agents.
    A segment p-q with |q - p| < reach stays within reach of p, so it can
    cross an edge only when that edge comes within reach."""
    for c in range(circles.shape[0]):
        dx, dz = px - circles[c, 0], pz - circles[c, 1]
        if math.sqrt(dx * dx + dz * dz) - circles[c, 2] < reach:
            return True
    r2 = reach * reach
    for k in range(pbound.shape[0]):
        if box_dist2(px, pz, pbox, k) > r2:
            continue
        s, e = pstart[k], pstart[k + 1]
        for a in range(s, e):
            b = a + 1 if a + 1 < e else s
            ax, az = verts[a, 0], verts[a, 1]
            ux, uz = verts[b, 0] - ax, verts[b, 1] - az
            ll = ux * ux + uz * uz
            t = ((px - ax) * ux + (pz - az) * uz) / ll if ll > 0.0 else 0.0
            t = min(max(t, 0.0), 1.0)
            ex, ez = ax + t * ux - px, az + t * uz - pz
            if ex * ex + ez * ez <= r2:
                return True
    return False
