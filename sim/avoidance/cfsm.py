"""Collision-free speed model (``model = "cfsm"`` of effect ``avoidance``).

Tordeux, Chraibi & Seyfried, *Collision-free speed model for pedestrian
dynamics*, Traffic and Granular Flow '15 (2016), §2, in the form of JuPedSim's
``CollisionFreeSpeedModel`` (libsimulator/src/CollisionFreeSpeedModel.cpp), so
the same scenario with the same parameters gives the same dynamics. Per agent
``i`` with position ``p_i``, radius ``r_i`` and preferred velocity ``w_i``
(goals / boids / attractors; desired direction ``e_i = w_i / |w_i|``, free
speed ``v0_i = |w_i|`` or the effect's ``v0``), from the start-of-step
snapshot of every agent (a Jacobi update, as JuPedSim):

- neighbours: agents ``j`` with ``d_ij = |p_j - p_i| < cutoff`` whose line of
  sight from ``i`` crosses no obstacle;
- direction (§2, eq. 3-4): ``u_i = normalise(e_i + sum_j R_ij + sum_w R_iw)``
  with ``R_ij = -a exp((l_ij - d_ij) / D) (p_j - p_i) / d_ij``,
  ``l_ij = r_i + r_j`` (``a`` = strength_neighbor_repulsion, ``D`` =
  range_neighbor_repulsion) and, per obstacle boundary element (circle, or
  polygon edge) with closest point ``q`` at distance ``d_iw``,
  ``R_iw = -b exp((r_i - d_iw) / D_w) (q - p_i) / d_iw`` (``b``, ``D_w`` the
  geometry strength and range); a zero sum keeps the heading;
- speed (§2, eq. 2): ``v_i = min(v0_i, max(0, s_i / T))`` with the spacing
  ``s_i = min_j (d_ij - l_ij)`` over neighbours in front
  (``u_i . (p_j - p_i) >= 0``) and in the corridor of width ``l_ij``
  (``|u_i^perp . (p_j - p_i)| <= l_ij``); ``T`` = time_gap;
- ``p_i += v_i u_i dt``.

Departures, all documented in docs/scenes.md: the preferred velocity replaces
JuPedSim's route to a destination; the default cutoff is not JuPedSim's fixed
3 m but ``2 r_max + max(v0_max T, 14 D)``, beyond which a neighbour changes
neither the speed (its spacing exceeds ``v0 T``) nor the direction by more
than ``a e^-14`` (< 1e-5) - ``cutoff = 3`` reproduces JuPedSim literally;
obstacles are solid shapes (the ``obstacles`` effect) instead of an
accessible-area polygon; coincident agents repel along a hashed,
antisymmetric direction (JuPedSim: no term); ``side_bias`` ``k`` > 0 adds
``k |R_ij|`` to the right of ``e_i`` for every neighbour ahead whose desired
direction opposes ``e_i`` (``e_i . e_j < 0``): the symmetric head-on
deadlock of the pure model (both agents stop nose to nose) resolves by both
stepping right; it never acts in unidirectional flow, so corridor and
bottleneck runs are JuPedSim's model exactly.

Checked against JuPedSim 1.4.2 (tests/sim/avoidance/data/jupedsim_cfsm_open.npz): 150 agents in open
space, its defaults, ``cutoff = 3``, ``side_bias = 0``: the same positions to 1.3e-14 m after 100 steps
(1.5e-5 m with the auto cutoff). scenes/bottleneck.toml (80 agents, 1 m door) in both: evacuation 68.4 s
here, 70.5 s in JuPedSim; flow 1.235 and 1.220 persons/s.

Implementation: one grid (:mod:`sim.grid`, cell = cutoff) on the start
positions, a serial gather of (x, z, r) in grid order, one parallel pass over
agents that scans the 3 x 3 cells twice (repulsion, then spacing along the
final direction) and writes only its own velocity: float64 differences,
deterministic for any thread count. Per agent: 40 bytes of snapshot, 16 of
preferred velocity and 16 of output besides the grid (20 bytes).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.avoidance.neighbors import bucket, coincident_dir, sight_blocked, sight_may_block
from sim.grid import Grid, build_grid
from sim.obstacles import box_dist2, polygon_boxes

#: speeds below this (m/s) count as "no preferred motion": the agent stands
CFSM_SPEED_EPS = 1e-9
#: repulsion terms are negligible beyond exp(-CFSM_RANGE_FACTOR) (auto cutoff, wall reach)
CFSM_RANGE_FACTOR = 14.0
#: exponents are clamped here (deep overlaps: finite, still dominant)
CFSM_MAX_EXPONENT = 50.0
#: agents per block of the parallel loop (one neighbour buffer per block)
CFSM_BLOCK = 512
#: neighbours kept for the spacing per agent (beyond: the spacing scans the cells again)
CFSM_SPACING_CAP = 96

# parameter vector
_A, _D, _B, _DW, _T, _CUT, _V0, _SIDE = range(8)


def param_vector(a, D, b, Dw, T, cutoff, v0, side=0.0) -> np.ndarray:
    """(8,) float64: strengths, ranges, time gap, cutoff (resolved, > 0), v0 (0 = |w|), side bias."""
    return np.array([a, D, b, Dw, T, cutoff, v0, side], np.float64)


@njit(cache=True)
def gather_dir(position, radius, vpref, order, out):
    """out[k] = (x, z, r, ex, ez) of agent order[k]: position, radius and unit
    preferred direction (0 when standing). Serial (memory-bound)."""
    for k in range(order.shape[0]):
        i = order[k]
        out[k, 0] = position[i, 0]
        out[k, 1] = position[i, 2]
        out[k, 2] = radius[i]
        wx, wz = vpref[i, 0], vpref[i, 1]
        s = math.sqrt(wx * wx + wz * wz)
        if s > CFSM_SPEED_EPS:
            out[k, 3] = wx / s
            out[k, 4] = wz / s
        else:
            out[k, 3] = 0.0
            out[k, 4] = 0.0


def auto_cutoff(r_max: float, v0_max: float, D: float, T: float) -> float:
    """Cutoff beyond which neighbours are negligible (module docstring)."""
    return max(2.0 * r_max + max(v0_max * T, CFSM_RANGE_FACTOR * D), 1e-3)


@njit(cache=True)
def max_speed(vpref):
    """Largest |w| of (n, 2) preferred velocities (serial)."""
    m = 0.0
    for i in range(vpref.shape[0]):
        s = vpref[i, 0] * vpref[i, 0] + vpref[i, 1] * vpref[i, 1]
        if s > m:
            m = s
    return math.sqrt(m)


@njit(cache=True, inline="always")
def _wall_term(px, pz, ri, b, Dw, reach, circles, verts, pstart, pbound, pbox):
    """Sum of R_iw over obstacle boundary elements within ``reach`` (polygons whose bounding box is
    farther are skipped: none of their edges is within reach)."""
    wx, wz = 0.0, 0.0
    for c in range(circles.shape[0]):
        dx, dz = px - circles[c, 0], pz - circles[c, 1]
        rc = math.sqrt(dx * dx + dz * dz)
        d = rc - circles[c, 2]
        if d < reach and rc > 0.0:
            f = b * math.exp(min((ri - d) / Dw, 50.0))
            # e_iw = (q - p)/|q - p| = -(p - c)/rc outside the circle
            wx += f * dx / rc
            wz += f * dz / rc
    for k in range(pbound.shape[0]):
        dx, dz = px - pbound[k, 0], pz - pbound[k, 1]
        if math.sqrt(dx * dx + dz * dz) - pbound[k, 2] > reach or box_dist2(px, pz, pbox, k) >= reach * reach:
            continue
        s, e = pstart[k], pstart[k + 1]
        for a in range(s, e):
            q = a + 1 if a + 1 < e else s
            ax, az = verts[a, 0], verts[a, 1]
            ux, uz = verts[q, 0] - ax, verts[q, 1] - az
            ll = ux * ux + uz * uz
            t = ((px - ax) * ux + (pz - az) * uz) / ll if ll > 0.0 else 0.0
            t = min(max(t, 0.0), 1.0)
            ex, ez = ax + t * ux - px, az + t * uz - pz
            d = math.sqrt(ex * ex + ez * ez)
            if d < reach and d > 0.0:
                f = b * math.exp(min((ri - d) / Dw, 50.0))
                wx -= f * ex / d
                wz -= f * ez / d
    return wx, wz


@njit(cache=True, parallel=True)
def _cfsm_kernel(S, order, cx, cz, start, gx, gz, dense, mask, vpref, heading, circles, verts, pstart, pbound,
                 pbox, P, near_d, out, near):
    """out[i] = new velocity (vx, vz) of every agent (module docstring); near[i] = 1 when a neighbour is
    closer than r_i + r_j + near_d at the start (only such pairs can overlap after the step: the
    no-overlap pass checks only them).

    Agents run in blocks of CFSM_BLOCK sharing one buffer: the first scan (repulsion) keeps the
    neighbours that can limit the speed (d - l < v0 T; farther ones give s / T >= v0), so the spacing
    along the final direction is a loop over that short list; only when it overflows (extreme
    densities) is the 3 x 3 scan repeated. Same result either way."""
    n = S.shape[0]
    a, D, b, Dw, T, cut, v0p, side = P[_A], P[_D], P[_B], P[_DW], P[_T], P[_CUT], P[_V0], P[_SIDE]
    cut2 = cut * cut
    has_obs = circles.shape[0] + pbound.shape[0] > 0
    nblocks = (n + CFSM_BLOCK - 1) // CFSM_BLOCK
    for blk in prange(nblocks):
        buf = np.empty(CFSM_SPACING_CAP, np.int64)
        for k in range(blk * CFSM_BLOCK, min(n, (blk + 1) * CFSM_BLOCK)):
            i = order[k]
            px, pz, ri = S[k, 0], S[k, 1], S[k, 2]
            wx, wz = vpref[i, 0], vpref[i, 1]
            sp = math.sqrt(wx * wx + wz * wz)
            ix, iz = np.int64(cx[i]), np.int64(cz[i])
            if not sp > CFSM_SPEED_EPS:
                out[i, 0] = 0.0
                out[i, 1] = 0.0
                near[i] = _near_scan(S, k, px, pz, ri, ix, iz, start, gx, gz, dense, mask, near_d)
                continue
            ex, ez = wx / sp, wz / sp
            v0 = v0p if v0p > 0.0 else sp
            reach = v0 * T  # neighbours with d - l beyond this cannot limit the speed
            los = has_obs and sight_may_block(px, pz, cut, circles, verts, pstart, pbound, pbox)
            rx, rz = 0.0, 0.0
            nr = 0
            nb = 0
            for o in range(9):
                key = bucket(o, ix, iz, gx, gz, dense, mask)
                if key < 0:
                    continue
                for m in range(start[key], start[key + 1]):
                    if m == k:
                        continue
                    dx, dz = S[m, 0] - px, S[m, 1] - pz
                    d2 = dx * dx + dz * dz
                    if d2 >= cut2:
                        continue
                    l = ri + S[m, 2]
                    ln = l + near_d
                    if d2 < ln * ln:
                        nr = 1
                    if los and sight_blocked(px, pz, S[m, 0], S[m, 1], circles, verts, pstart, pbound, pbox):
                        continue
                    d = math.sqrt(d2)
                    if d - l < reach:
                        if nb < CFSM_SPACING_CAP:
                            buf[nb] = m
                        nb += 1
                    f = a * math.exp(min((l - d) / D, 50.0))
                    if d > 0.0:
                        rx -= f * dx / d
                        rz -= f * dz / d
                        if side > 0.0 and ex * dx + ez * dz > 0.0 and ex * S[m, 3] + ez * S[m, 4] < 0.0:
                            # counter-flow neighbour ahead: step to the right (-ez, ex) as well
                            rx -= side * f * ez
                            rz += side * f * ex
                    else:
                        hx, hz = coincident_dir(i, order[m])
                        rx -= f * hx
                        rz -= f * hz
            if has_obs:
                gwx, gwz = _wall_term(px, pz, ri, b, Dw, ri + CFSM_RANGE_FACTOR * 2.0 * Dw + 1e-9,
                                      circles, verts, pstart, pbound, pbox)
                rx += gwx
                rz += gwz
            ux, uz = ex + rx, ez + rz
            un = math.sqrt(ux * ux + uz * uz)
            if un > 0.0:
                ux, uz = ux / un, uz / un
            else:
                ux, uz = math.sin(heading[i]), math.cos(heading[i])
            s = 1e300
            if nb <= CFSM_SPACING_CAP:
                for q in range(nb):
                    m = buf[q]
                    g = _gap(S, m, px, pz, ri, ux, uz)
                    if g < s:
                        s = g
            else:
                for o in range(9):
                    key = bucket(o, ix, iz, gx, gz, dense, mask)
                    if key < 0:
                        continue
                    for m in range(start[key], start[key + 1]):
                        if m == k:
                            continue
                        dx, dz = S[m, 0] - px, S[m, 1] - pz
                        if dx * dx + dz * dz >= cut2:
                            continue
                        if los and sight_blocked(px, pz, S[m, 0], S[m, 1], circles, verts, pstart, pbound, pbox):
                            continue
                        g = _gap(S, m, px, pz, ri, ux, uz)
                        if g < s:
                            s = g
            v = min(max(s / T, 0.0), v0)
            out[i, 0] = ux * v
            out[i, 1] = uz * v
            near[i] = nr


@njit(cache=True, inline="always")
def _gap(S, m, px, pz, ri, ux, uz):
    """d - l of neighbour m when it is in front (u . d >= 0) and in the corridor (|u^perp . d| <= l), else 1e300."""
    dx, dz = S[m, 0] - px, S[m, 1] - pz
    if ux * dx + uz * dz < 0.0:
        return 1e300
    l = ri + S[m, 2]
    if abs(ux * dz - uz * dx) > l:
        return 1e300
    return math.sqrt(dx * dx + dz * dz) - l


@njit(cache=True)
def _near_scan(S, k, px, pz, ri, ix, iz, start, gx, gz, dense, mask, near_d):
    """1 when an agent of the 3 x 3 cells is closer than r_i + r_j + near_d."""
    for o in range(9):
        key = bucket(o, ix, iz, gx, gz, dense, mask)
        if key < 0:
            continue
        for m in range(start[key], start[key + 1]):
            if m == k:
                continue
            dx, dz = S[m, 0] - px, S[m, 1] - pz
            ln = ri + S[m, 2] + near_d
            if dx * dx + dz * dz < ln * ln:
                return 1
    return 0


_EMPTY3 = np.zeros((0, 3))
_EMPTY2 = np.zeros((0, 2))
_EMPTYI = np.zeros(1, np.int64)


def obstacle_arrays(obs):
    """(circles, verts, pstart, pbound) of an ObstacleSet, or empty arrays for None."""
    if obs is None or obs.count == 0:
        return _EMPTY3, _EMPTY2, _EMPTYI, _EMPTY3
    return obs.circles, obs.verts, obs.pstart, obs.pbound


def cfsm_velocities(position, radius, vpref, heading, a=8.0, D=0.1, b=5.0, Dw=0.02, T=1.0, cutoff=0.0, v0=0.0,
                    side=0.0, obstacles=None, grid: Grid | None = None, scratch=None, near=None, near_d=0.0):
    """New velocities of every agent by the collision-free speed model.

    Parameters
    ----------
    position : (n, 3) float64, start-of-step positions (x, z used)
    radius : (n,) float64, body radii, metres
    vpref : (n, 2) float64, preferred velocities (vx, vz)
    heading : (n,) float64, yaw (used when the direction sum vanishes)
    a, D, b, Dw, T : model parameters (module docstring)
    cutoff : neighbour range, metres; 0 = :func:`auto_cutoff`
    v0 : free speed, m/s; 0 = |vpref| per agent
    side : side bias (counter-flow neighbours ahead also push to the right; 0 = JuPedSim)
    obstacles : sim.obstacles.ObstacleSet or None
    grid, scratch : buffers of a previous call (reused when sizes match)
    near : (n,) uint8 output or None: 1 for agents with a neighbour closer than r_i + r_j + near_d
        (``near_d`` metres, at most cutoff - 2 r_max to be complete)

    Returns
    -------
    out : (n, 2) float64 velocities; grid : Grid; scratch : (n, 5) float64
    """
    n = position.shape[0]
    out = np.zeros((n, 2), np.float64)
    rmax = float(radius.max()) if n else 0.0
    vmax = float(v0) if v0 > 0 else (float(max_speed(vpref)) if n else 0.0)
    cut = float(cutoff) if cutoff > 0 else auto_cutoff(rmax, vmax, D, T)
    grid = build_grid(position, cut, out=grid)
    if scratch is None or scratch.shape != (n, 5):
        scratch = np.empty((n, 5), np.float64)
    if n == 0:
        return out, grid, scratch
    gather_dir(position, radius, vpref, grid.order, scratch)
    circles, verts, pstart, pbound = obstacle_arrays(obstacles)
    P = param_vector(a, D, b, Dw, T, cut, v0, side)
    nr = near if near is not None and near.shape == (n,) else np.empty(n, np.uint8)
    _cfsm_kernel(scratch, grid.order, grid.cx, grid.cz, grid.start, grid.dims[0], grid.dims[1], grid.dense,
                 grid.mask, vpref, heading, circles, verts, pstart, pbound, polygon_boxes(verts, pstart), P,
                 float(near_d), out, nr)
    return out, grid, scratch
