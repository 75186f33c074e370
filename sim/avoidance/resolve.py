"""Hard no-overlap safety of effect ``avoidance`` (step ``avoidance.resolve``).

Neither model guarantees ``|p_i - p_j| >= r_i + r_j`` at a finite ``dt`` in
every case: CFSM cannot part agents that start overlapping or coincident (their
spacing is negative, so their speed is 0), ORCA's half-planes are linearised,
and the obstacles' projection may push an agent into a neighbour. This pass
makes the constraint hold after every step, in the manner of position-based
dynamics (Müller, Heidelberger, Hennix & Ratcliff, *Position based dynamics*,
2007, §3.3, Jacobi form): every overlapping pair is pushed apart along its
centre line, each agent by half of the overlap (to ``RESOLVE_TARGET`` times the
contact distance; an agent moves at most its radius per pass), all agents
from the same snapshot, then agents are
projected out of obstacles (per-agent clearance); repeated until no pair
overlaps or ``iterations`` passes were made (the rest is resolved in the next
steps: a jam of many coincident agents unfolds over a few steps).
Coincident agents part along the hashed antisymmetric direction of
:func:`sim.avoidance.neighbors.coincident_dir`.

Only positions move; velocities stay the model's (so a deep initial overlap
does not turn into a speed). If overlaps remain after the passes (a crowd
pressed against walls, where the obstacle projection undoes the pushes, can
converge slowly), the last resort is a velocity clamp: every agent still
overlapping by more than ``RESOLVE_FREEZE`` returns to its start-of-step
position (and the caller zeroes its velocity), repeated until none does. The
start-of-step state had no overlap (induction from the first steps), so this
always ends overlap-free unless the scene started with overlaps that the
passes have not yet removed. Each agent writes only its own row and sums its
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
from sim.obstacles import _clear_bound, _sdf_point, polygon_boxes

#: overlapping pairs are pushed to this multiple of r_i + r_j (a hair beyond contact,
#: so that rounding and the obstacle projection do not re-create an overlap)
RESOLVE_TARGET = 1.0 + 1e-4
#: obstacle projection passes per resolve iteration (corners between two obstacles)
RESOLVE_OBSTACLE_PASSES = 4
#: after the passes, agents still overlapping by more than this fraction of r_i + r_j go back to
#: their start-of-step position (a velocity clamp) ...
RESOLVE_FREEZE = 1e-3
#: ... in at most this many rounds (each round reverts every agent still overlapping)
RESOLVE_FREEZE_ROUNDS = 16
#: resolve's own grid (cell 2 r_max, 0.4 m for 0.2 m bodies: 6.25 cells per agent at 1 per m^2) stays
#: dense up to this many cells per agent (sim.grid's default, 4, would hash it: 20x slower passes,
#: every 3 x 3 neighbourhood a cache miss); 8 cells = 32 bytes per agent, built only when pairs overlap
RESOLVE_DENSE_FACTOR = 8


@njit(cache=True, parallel=True)
def _push_kernel(S, order, cx, cz, start, gx, gz, dense, mask, target, disp, worst, only, use_only):
    """disp[i] = Jacobi push of agent i; worst[i] = largest overlap 1 - d/l of i. With ``use_only``,
    agents with only[i] == 0 are skipped (they have no neighbour within reach: zero push)."""
    n = S.shape[0]
    for k in prange(n):
        i = order[k]
        if use_only and only[i] == 0:
            disp[i, 0] = 0.0
            disp[i, 1] = 0.0
            worst[i] = 0.0
            continue
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
        mm = math.sqrt(mx * mx + mz * mz)
        if mm > ri:  # at most one radius per pass: a pile unfolds over passes, nobody is thrown away
            mx *= ri / mm
            mz *= ri / mm
        disp[i, 0] = mx
        disp[i, 1] = mz
        worst[i] = w


@njit(cache=True, parallel=True)
def _apply_kernel(pos, disp, clearance, circles, verts, pstart, pbound, pbox, has_obs, passes):
    for i in prange(pos.shape[0]):
        px, pz = pos[i, 0] + disp[i, 0], pos[i, 2] + disp[i, 1]
        # (agents whose lower bound of the obstacle distance exceeds their clearance need no projection)
        if has_obs and _clear_bound(px, pz, circles, pbox) <= clearance[i]:
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


@njit(cache=True)
def max_move(position, prev):
    """Largest XZ distance between ``position`` and ``prev`` (n, 3) (serial, exact)."""
    m = 0.0
    for i in range(position.shape[0]):
        dx, dz = position[i, 0] - prev[i, 0], position[i, 2] - prev[i, 2]
        d = dx * dx + dz * dz
        if d > m:
            m = d
    return math.sqrt(m)


def resolve(position, radius, clearance=None, obstacles=None, iterations: int = 16, grid=None, prev=None,
            frozen=None, near=None, near_d=0.0):
    """Push overlapping agents apart in place (module docstring).

    Parameters
    ----------
    position : (n, 3) float64, modified in place (x, z)
    radius : (n,) float64 body radii
    clearance : (n,) float64 distances kept from obstacles (default: radius)
    obstacles : sim.obstacles.ObstacleSet or None
    iterations : int >= 0, largest number of passes
    grid, prev : optional grid built on positions ``prev`` (n, 3) (the model's, at the start of the step):
        the first pass reuses it when its cell is at least 2 r_max RESOLVE_TARGET plus twice the largest
        move since ``prev`` (every overlapping pair is then within the 3 x 3 cells of the old grid), which
        spares a grid build in the usual step without overlaps; ``prev`` is also where agents still
        overlapping after the passes return to (the velocity clamp)
    frozen : (n,) bool output or None: set True for agents returned to ``prev``
    near, near_d : the model's flags (agents with a neighbour closer than r_i + r_j + near_d at ``prev``):
        when every agent moved at most near_d / 2 since ``prev``, only flagged agents can overlap, and the
        first pass visits only them

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
    pbox = polygon_boxes(verts, pstart)
    clearance = radius if clearance is None else clearance
    rmax = float(radius.max())
    if not rmax > 0:
        return 0, 0.0
    S = np.empty((n, 3), np.float64)
    disp = np.empty((n, 2), np.float64)
    worst = np.empty(n, np.float64)
    w = 0.0
    cell = 2.0 * rmax * RESOLVE_TARGET
    moved = float(max_move(position, prev)) if prev is not None and prev.shape == position.shape else np.inf
    reuse = grid is not None and grid.order.shape[0] == n and grid.cell >= cell + 2.0 * moved
    flags = (reuse and near is not None and near.shape == (n,) and grid.cell >= 2.0 * rmax + near_d
             and 2.0 * moved <= near_d)
    dummy = np.zeros(1, np.uint8)
    own = None  # resolve's own grid (the caller's is only read)
    for it in range(iterations):
        if not (it == 0 and reuse):
            grid = own = build_grid(position, cell, out=own, dense_factor=RESOLVE_DENSE_FACTOR)
        gather(position, radius, grid.order, S)
        first = it == 0 and flags
        _push_kernel(S, grid.order, grid.cx, grid.cz, grid.start, grid.dims[0], grid.dims[1], grid.dense, grid.mask,
                     RESOLVE_TARGET, disp, worst, near if first else dummy, first)
        w = float(worst.max())
        if w <= 0.0:
            return it, 0.0
        _apply_kernel(position, disp, clearance, circles, verts, pstart, pbound, pbox, has_obs,
                      RESOLVE_OBSTACLE_PASSES)
    if prev is None or prev.shape != position.shape:
        return iterations, w
    for _ in range(RESOLVE_FREEZE_ROUNDS):
        grid = own = build_grid(position, cell, out=own, dense_factor=RESOLVE_DENSE_FACTOR)
        gather(position, radius, grid.order, S)
        _push_kernel(S, grid.order, grid.cx, grid.cz, grid.start, grid.dims[0], grid.dims[1], grid.dense, grid.mask,
                     RESOLVE_TARGET, disp, worst, dummy, False)
        bad = worst > RESOLVE_FREEZE
        w = float(worst.max())
        if not bad.any():
            break
        position[bad, 0] = prev[bad, 0]
        position[bad, 2] = prev[bad, 2]
        if frozen is not None:
            frozen |= bad
    return iterations, w

