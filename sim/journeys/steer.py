"""Steering at the current target: the desired velocity of every agent, the kinematic move, and the
straight-line router that stands in for ``sim.routing`` while no walkable area is routed.

The router interface (agreed with the routing effect, docs/scenes.md "Journeys"):

    gid = router.goal(shape)                       # ("point", (x, z)) | ("polygon", [(x, z), ...]) |
                                                   # ("line", ((x1, z1), (x2, z2))); equal shapes share an id
    router.directions(position, goal, out, dist)   # (n, 3) float64, (n,) int64 (-1: none) -> (n, 2) unit (x, z),
                                                   # dist (n,) float64 the remaining route length (inf: none)
    router.reachable(gid, xz)                      # (m, 2) -> (m,) bool

:class:`StraightRouter` points every agent straight at the nearest point of its goal (what ``sim.goals``
does) and knows no walls; ``world.resources["routing"]``, when a scene routes, replaces it.

Desired velocity (:func:`desired_kernel`, numpy reference :func:`desired_reference`), per agent walking to a
target shape: far from the target (the route to its goal and the straight line to the target both longer than
``approach`` metres, and never nearer since the goal was set: a slot's goal is its stage's, e.g. a queue's
last place, from where the agent walks along the line to its place) along the router's direction; within it
straight at the target's nearest point -- through a door line (towards a point ``approach`` metres behind
it, on the side the agent is not on) and into an exit polygon -- at the journey's speed, slowed linearly
within ``slow_radius`` of where it must stop (``stop_at`` metres before a waiting slot, a queue place, a
final waypoint; -1: pass through). Holding, idle and leaving agents want to stand.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.journeys.geometry import LINE, Shapes, nearest, nearest_one, nearest_reference

#: agent phases: walking to the target, waiting for a free slot of a full waiting area, holding at a slot,
#: done with a journey that has no exit, reached an exit (removed before the next frame)
WALK, PENDING, HOLD, IDLE, LEAVING = 0, 1, 2, 3, 4


class StraightRouter:
    """The router of a scene without routing: straight at the goal, every goal reachable."""

    def __init__(self):
        self.shapes = Shapes()
        self._arrays = None

    def goal(self, shape) -> int:
        kind, points = shape
        self._arrays = None
        return self.shapes.add(kind, [points] if kind == "point" else points)

    def directions(self, position: np.ndarray, goal: np.ndarray, out: np.ndarray, dist=None) -> np.ndarray:
        if self._arrays is None:
            self._arrays = self.shapes.arrays()
        kind, start, verts = self._arrays
        d = np.empty(position.shape[0]) if dist is None else dist
        _straight_kernel(position, np.asarray(goal, np.int64), kind, start, verts, out, d)
        return out

    def reachable(self, gid: int, xz: np.ndarray) -> np.ndarray:
        return np.ones(np.asarray(xz).reshape(-1, 2).shape[0], bool)


@njit(cache=True, parallel=True)
def _straight_kernel(position, goal, kind, start, verts, out, dist):
    for i in prange(position.shape[0]):
        out[i, 0] = 0.0
        out[i, 1] = 0.0
        dist[i] = np.inf
        k = goal[i]
        if k < 0:
            continue
        qx, qz, inside = nearest_one(kind, start, verts, k, position[i, 0], position[i, 2])
        dx, dz = qx - position[i, 0], qz - position[i, 2]
        d = math.hypot(dx, dz)
        dist[i] = 0.0 if inside else d
        if not inside and d > 1e-12:
            out[i, 0] = dx / d
            out[i, 1] = dz / d


@njit(cache=True, parallel=True)
def desired_kernel(position, phase, tshape, stop_at, speed, rdir, rdist, near, kind, start, verts, approach,
                   slow_radius, out):
    """Desired (vx, vz) of every agent into ``out`` (n, 2) (module docstring); ``near`` (n,) int8 in/out: the
    agent came within ``approach`` of its router goal, and walks straight from then on (until its goal changes)."""
    for i in prange(position.shape[0]):
        out[i, 0] = 0.0
        out[i, 1] = 0.0
        k = tshape[i]
        if k < 0 or phase[i] > PENDING:
            continue
        px, pz = position[i, 0], position[i, 2]
        qx, qz, inside = nearest_one(kind, start, verts, k, px, pz)
        if inside:
            continue
        dx, dz = qx - px, qz - pz
        d = math.hypot(dx, dz)
        ux, uz = 0.0, 0.0
        if rdist[i] < approach:
            near[i] = 1
        if near[i] or d < approach or (rdir[i, 0] == 0.0 and rdir[i, 1] == 0.0):
            if kind[k] == LINE:  # through the door: at a point `approach` behind it
                a = start[k]
                ex, ez = verts[a + 1, 0] - verts[a, 0], verts[a + 1, 1] - verts[a, 1]
                el = math.hypot(ex, ez)
                if el > 0.0:
                    nx, nz = -ez / el, ex / el
                else:  # a door narrower than two body radii: its midpoint, crossed along the approach
                    nx, nz = (dx / d, dz / d) if d > 1e-12 else (1.0, 0.0)
                side = ex * (pz - verts[a, 1]) - ez * (px - verts[a, 0]) if el > 0.0 else -1.0
                far = -1.0 if side > 0.0 else 1.0
                dx, dz = qx + far * nx * approach - px, qz + far * nz * approach - pz
            dd = math.hypot(dx, dz)
            if dd > 1e-12:
                ux, uz = dx / dd, dz / dd
        else:
            ux, uz = rdir[i, 0], rdir[i, 1]
        s = speed[i]
        if stop_at[i] >= 0.0:
            s *= min(1.0, max(0.0, (d - stop_at[i]) / slow_radius))
        out[i, 0] = ux * s
        out[i, 1] = uz * s


def desired_reference(position, phase, tshape, stop_at, speed, rdir, rdist, near, shapes: Shapes, approach,
                      slow_radius):
    """Plain Python reference of :func:`desired_kernel` ((n, 2) float64; ``near`` updated in place)."""
    out = np.zeros((position.shape[0], 2))
    for i in range(position.shape[0]):
        k = int(tshape[i])
        if k < 0 or phase[i] > PENDING:
            continue
        name, pts = shapes.shape(k)
        p = np.array([position[i, 0], position[i, 2]])
        qx, qz, inside = nearest_reference(pts, name, p)
        if inside:
            continue
        q = np.array([qx, qz])
        d = float(np.hypot(*(q - p)))
        if rdist[i] < approach:
            near[i] = 1
        if near[i] or d < approach or not np.any(rdir[i]):
            t = q
            if name == "line":
                e = pts[1] - pts[0]
                el = float(np.hypot(*e))
                if el > 0:
                    n = np.array([-e[1], e[0]]) / el
                    side = e[0] * (p[1] - pts[0, 1]) - e[1] * (p[0] - pts[0, 0])
                else:
                    n = (q - p) / d if d > 1e-12 else np.array([1.0, 0.0])
                    side = -1.0
                t = q + (-1.0 if side > 0 else 1.0) * n * approach
            dd = float(np.hypot(*(t - p)))
            u = (t - p) / dd if dd > 1e-12 else np.zeros(2)
        else:
            u = np.asarray(rdir[i], np.float64)
        s = float(speed[i])
        if stop_at[i] >= 0:
            s *= min(1.0, max(0.0, (d - stop_at[i]) / slow_radius))
        out[i] = u * s
    return out


@njit(cache=True, parallel=True)
def move_kernel(position, velocity, heading, active, vd, dt):
    """Kinematic move of the agents ``active`` (no boids): velocity = desired, position += v dt, heading =
    direction of v when moving."""
    for i in prange(position.shape[0]):
        if not active[i]:
            continue
        vx, vz = vd[i, 0], vd[i, 1]
        velocity[i, 0] = vx
        velocity[i, 1] = 0.0
        velocity[i, 2] = vz
        position[i, 0] += vx * dt
        position[i, 2] += vz * dt
        if vx * vx + vz * vz > 1e-18:
            heading[i] = math.atan2(vx, vz)


def move_reference(position, velocity, heading, active, vd, dt) -> None:
    """Plain numpy reference of :func:`move_kernel`."""
    a = np.asarray(active, bool)
    velocity[a, 0], velocity[a, 1], velocity[a, 2] = vd[a, 0], 0.0, vd[a, 1]
    position[a, 0] += vd[a, 0] * dt
    position[a, 2] += vd[a, 1] * dt
    mv = a & (vd[:, 0] ** 2 + vd[:, 1] ** 2 > 1e-18)
    heading[mv] = np.arctan2(vd[mv, 0], vd[mv, 1])


def nearest_points(shapes_arrays: tuple, tshape: np.ndarray, position: np.ndarray) -> tuple:
    """(qx, qz, inside) of every agent's target shape (-1: its own position)."""
    kind, start, verts = shapes_arrays
    n = position.shape[0]
    qx, qz, inside = np.empty(n), np.empty(n), np.empty(n, np.bool_)
    nearest(kind, start, verts, np.asarray(tshape, np.int64), np.ascontiguousarray(position[:, 0]),
            np.ascontiguousarray(position[:, 2]), qx, qz, inside)
    return qx, qz, inside
