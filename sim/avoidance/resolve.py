"""Hard no-overlap safety of effect ``avoidance`` (step ``avoidance.resolve``).

Neither model guarantees ``|p_i - p_j| >= r_i + r_j`` at a finite ``dt`` in
every case: CFSM cannot part agents that start overlapping or coincident (their
spacing is negative, so their speed is 0), ORCA's half-planes are linearised,
and the obstacles' projection may push an agent into a neighbour. This pass
makes the constraint hold after every step, in the manner of position-based
dynamics (Müller, Heidelberger, Hennix & Ratcliff, *Position based dynamics*,
2007, §3.3, Jacobi form): every overlapping pair is pushed apart along its
centre line, each agent by half of the overlap (to ``RESOLVE_TARGET`` times the
contact distance), all agents from the same snapshot, then agents are
projected out of obstacles (per-agent clearance); repeated until no pair
overlaps or ``iterations`` passes were made (the rest is resolved in the next
steps: a jam of many coincident agents unfolds over a few steps).
Coincident agents part along the hashed antisymmetric direction of
:func:`sim.avoidance.neighbors.coincident_dir`.

Only positions move; velocities stay the model's (so a deep initial overlap
does not turn into a speed). Each agent writes only its own row and sums its
neighbours in the grid's fixed order: deterministic for any thread count. The
first pass reuses nothing but costs one grid build and one scan when no pair
overlaps (the usual case).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.avoidance.neighbors import bucket, coincident_dir, gather
from sim.grid import build_grid
from sim.obstacles import _sdf_point

#: overlapping pairs are pushed to this multiple of r_i + r_j (a hair beyond contact,
#: so that rounding and the obstacle projection do not re-create an overlap)
RESOLVE_TARGET = 1.0 + 1e-4
#: obstacle projection passes per resolve iteration (corners between two obstacles)
RESOLVE_OBSTACLE_PASSES = 4


@njit(cache=True, parallel=True)
def _push_kernel(S, order, cx, cz, start, gx, gz, dense, mask, target, disp, worst):
    """disp[i] = Jacobi push of agent i; worst[i] = largest overlap 1 - d/l of i."""
    n = S.shape[0]
    for k in prange(n):
        i = order[k]
        px, pz, ri = S[k, 0], S[k, 1], S[k, 2]
        mx, mz, w = 0.0, 0.0, 0.0
        ix, iz = np.int64(cx[i]), np.int64(cz[i])
        for o in range(9):
            key = bucket(o, ix, iz, gx, gz, dense, mask)
            if key < 0:
                continue
            for m in range(start[key], start[key + 1]):
                if m == k:
                    continue
                dx, dz = S[m, 0] - px, S[m, 1] - pz
                lt = (ri + S[m, 2]) * target
                d2 = dx * dx + dz * dz
                if d2 >= lt * lt:
                    continue
                d = math.sqrt(d2)
                l = ri + S[m, 2]
                if l > 0.0 and 1.0 - d / l > w:
                    w = 1.0 - d / l
                push = 0.5 * (lt - d)
                if d > 0.0:
                    mx -= push * dx / d
                    mz -= push * dz / d
                else:
                    hx, hz = coincident_dir(i, order[m])
                    mx -= push * hx
                    mz -= push * hz
        disp[i, 0] = mx
        disp[i, 1] = mz
        worst[i] = w


@njit(cache=True, parallel=True)
def _apply_kernel(pos, disp, clearance, circles, verts, pstart, pbound, has_obs, passes):
    for i in prange(pos.shape[0]):
        px, pz = pos[i, 0] + disp[i, 0], pos[i, 2] + disp[i, 1]
        if has_obs:
            r = clearance[i]
            for it in range(passes):
                d, nx, nz = _sdf_point(px, pz, circles, verts, pstart, pbound, r)
                pen = r - d
                if pen <= 0.0:
                    break
                px += nx * pen
                pz += nz * pen
        pos[i, 0] = px
        pos[i, 2] = pz


def resolve(position, radius, clearance=None, obstacles=None, iterations: int = 16):
    """Push overlapping agents apart in place (module docstring).

    Parameters
    ----------
    position : (n, 3) float64, modified in place (x, z)
    radius : (n,) float64 body radii
    clearance : (n,) float64 distances kept from obstacles (default: radius)
    obstacles : sim.obstacles.ObstacleSet or None
    iterations : int >= 0, largest number of passes

    Returns
    -------
    (passes made, largest remaining overlap 1 - d / (r_i + r_j) before the last push; 0 = none)
    """
    from sim.avoidance.cfsm import obstacle_arrays

    n = position.shape[0]
    if n < 2 or iterations <= 0:
        return 0, 0.0
    circles, verts, pstart, pbound = obstacle_arrays(obstacles)
    has_obs = circles.shape[0] + pbound.shape[0] > 0
    clearance = radius if clearance is None else clearance
    rmax = float(radius.max())
    if not rmax > 0:
        return 0, 0.0
    S = np.empty((n, 3), np.float64)
    disp = np.empty((n, 2), np.float64)
    worst = np.empty(n, np.float64)
    grid = None
    w = 0.0
    for it in range(iterations):
        grid = build_grid(position, 2.0 * rmax * RESOLVE_TARGET, out=grid)
        gather(position, radius, grid.order, S)
        _push_kernel(S, grid.order, grid.cx, grid.cz, grid.start, grid.dims[0], grid.dims[1], grid.dense, grid.mask,
                     RESOLVE_TARGET, disp, worst)
        w = float(worst.max())
        if w <= 0.0:
            return it, 0.0
        _apply_kernel(position, disp, clearance, circles, verts, pstart, pbound, has_obs, RESOLVE_OBSTACLE_PASSES)
    return iterations, w

