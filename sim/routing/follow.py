"""The ``goals`` effect's routed step in one pass over the agents (numba): each agent's desired velocity along the
shortest route to its current waypoint, reached waypoints advanced on the way, and (without boids) the kinematic
move. The plain numpy reference is ``sim.goals.Goals.routed_velocity_numpy`` with ``sim.goals.kinematic_numpy``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.routing.field import UNREACHABLE, steer_one


@njit(cache=True, parallel=True)
def follow_kernel(pos, vel, heading, path, target, pstart, wgoal, loop, ar, speed, integrate, dt,
                  F, V, corners, D, nxt, ahead, gseg, gstart, garea, x0, z0, h, nx, nz, eps, use_via, vd):
    """Per agent i with a path (``path[i] >= 0``): the route to waypoint ``target[i]`` (goal ``wgoal[t]`` of the
    router's arrays, :func:`sim.routing.field.steer_one`); within ``ar`` of route length the next waypoint (the
    first again when ``loop``, the last kept otherwise) and its route; speed ``speed``, slowed by the remaining
    route / ``ar`` on the last leg of an open path. ``vd`` (n, 2) gets the desired velocity (0 without a path);
    ``integrate``: velocity = vd, position += vd dt, heading = direction of vd (the goals step without boids)."""
    big = np.float64(UNREACHABLE) * 0.5
    for i in prange(pos.shape[0]):
        k = path[i]
        if k < 0:
            vd[i, 0] = 0.0
            vd[i, 1] = 0.0
            continue
        px, pz = pos[i, 0], pos[i, 2]
        t = target[i]
        first, end = pstart[k], pstart[k + 1]
        ux, uz, d = steer_one(F, V, wgoal[t], px, pz, x0, z0, h, nx, nz, corners, D, nxt, ahead, gseg, gstart,
                              garea, eps, use_via)
        if d < ar:
            t2 = t + 1
            if t2 >= end:
                t2 = first if loop else end - 1
            if t2 != t:
                target[i] = t2
                t = t2
                ux, uz, d = steer_one(F, V, wgoal[t], px, pz, x0, z0, h, nx, nz, corners, D, nxt, ahead, gseg,
                                      gstart, garea, eps, use_via)
        s = speed
        if not loop and t == end - 1:
            s = speed * min(1.0, (d if d < big else ar) / ar)
        vx, vz = ux * s, uz * s
        vd[i, 0] = vx
        vd[i, 1] = vz
        if integrate:
            vel[i, 0] = vx
            vel[i, 1] = 0.0
            vel[i, 2] = vz
            pos[i, 0] = px + vx * dt
            pos[i, 2] = pz + vz * dt
            if math.hypot(vx, vz) > 1e-9:
                heading[i] = math.atan2(vx, vz)
