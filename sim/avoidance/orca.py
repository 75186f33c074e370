"""Optimal reciprocal collision avoidance (``model = "orca"`` of effect ``avoidance``).

van den Berg, Guy, Lin & Manocha, *Reciprocal n-body collision avoidance*,
Robotics Research (ISRR 2009), Springer 2011: §5.1-5.2 (the ORCA half-plane
of a pair), §5.3 (the 2-D linear program and the 3-D fallback when the
half-planes have no common point), in the form of the authors' RVO2 library.
Per agent ``i`` with start-of-step velocity ``v_i``, preferred velocity
``w_i`` and speed limit ``V_i`` (``max_speed``, or ``|w_i|``):

- neighbours: the ``max_neighbors`` nearest agents within
  ``neighbor_distance`` (ties by the grid's fixed visiting order);
- per neighbour ``j`` (relative position ``p = p_j - p_i``, relative
  velocity ``v = v_i - v_j``, combined radius ``l = r_i + r_j``): the
  smallest change ``u`` that takes ``v`` out of the velocity obstacle truncated
  at ``time_horizon`` (the cut-off disc or the nearer leg), or, when already
  overlapping, out of the disc at ``1 / dt``; the half-plane through
  ``v_i + u / 2`` with normal ``u`` (each agent takes half: reciprocity);
- per static obstacle within reach (circles of the ``obstacles`` effect, and
  each edge of its boxes and polygons): full responsibility, horizon
  ``time_horizon_obstacles``. A circle is a static agent of its radius. An
  edge whose nearest point to ``p_i`` is interior bounds the speed towards its
  supporting line, ``v . n >= -(d - r_i) / tau`` (a half-plane; ``n`` the
  outward normal, ``d`` the distance); an edge whose nearest point is an end
  point is a static agent of radius 0 at that vertex. Departure from RVO2,
  which builds obstacle cones from polygon vertices with convexity flags: the
  per-edge half-planes are conservative for convex corners and need no
  polygon orientation; the obstacles' hard projection catches the rest;
- the new velocity: the point of the half-planes' intersection inside the
  speed disc nearest to ``w_i`` (incremental 2-D LP, constraints in the fixed
  order obstacles first, then neighbours by distance - RVO2 does not shuffle
  either, so the randomised LP's expected bound is traded for determinism);
  if infeasible, the 3-D LP of §5.3 minimises the largest violation of the
  agent half-planes while keeping the obstacle ones. As in the RVO2 examples,
  the preferred velocity is perturbed by ``ORCA_PERTURB`` (hashed direction,
  deterministic) so perfectly symmetric scenes (the crossing) do not deadlock.

One parallel pass over agents (blocks of agents share a scratch buffer, so no
allocation per agent), each agent writing only its own velocity:
deterministic for any thread count.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.avoidance.neighbors import bucket, coincident_dir, gather
from sim.grid import Grid, build_grid

#: determinant below which two ORCA lines count as parallel (RVO_EPSILON of RVO2)
ORCA_EPS = 1e-9
#: agents per block of the parallel loop (one scratch buffer per block)
ORCA_BLOCK = 256
#: the preferred velocity is perturbed by this much (m/s), in a direction hashed from the agent and the step,
#: as the RVO2 examples do "to avoid deadlocks due to perfect symmetry" (e.g. the crossing scene)
ORCA_PERTURB = 1e-3
#: static obstacles farther than this many seconds of travel at the speed limit (plus the radius) are skipped
ORCA_OBSTACLE_REACH = 1.0


@njit(cache=True, inline="always")
def _det(ax, az, bx, bz):
    return ax * bz - az * bx


@njit(cache=True)
def _lp1(L, no, radius, ox, oz, dir_opt, res):
    """Optimum on line ``no`` subject to lines 0..no-1 and the speed disc (RVO2 linearProgram1)."""
    px, pz, dx, dz = L[no, 0], L[no, 1], L[no, 2], L[no, 3]
    dot = px * dx + pz * dz
    disc = dot * dot + radius * radius - (px * px + pz * pz)
    if disc < 0.0:
        return False
    sq = math.sqrt(disc)
    t_left, t_right = -dot - sq, -dot + sq
    for i in range(no):
        den = _det(dx, dz, L[i, 2], L[i, 3])
        num = _det(L[i, 2], L[i, 3], px - L[i, 0], pz - L[i, 1])
        if abs(den) <= ORCA_EPS:
            if num < 0.0:
                return False
            continue
        t = num / den
        if den >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return False
    if dir_opt:
        if ox * dx + oz * dz > 0.0:
            res[0], res[1] = px + t_right * dx, pz + t_right * dz
        else:
            res[0], res[1] = px + t_left * dx, pz + t_left * dz
    else:
        t = dx * (ox - px) + dz * (oz - pz)
        t = min(max(t, t_left), t_right)
        res[0], res[1] = px + t * dx, pz + t * dz
    return True


@njit(cache=True)
def _lp2(L, nl, radius, ox, oz, dir_opt, res):
    """Incremental 2-D LP over lines 0..nl-1 (RVO2 linearProgram2); returns the
    index of the first line that made it infeasible, or nl."""
    if dir_opt:
        res[0], res[1] = ox * radius, oz * radius
    elif ox * ox + oz * oz > radius * radius:
        s = math.sqrt(ox * ox + oz * oz)
        res[0], res[1] = ox / s * radius, oz / s * radius
    else:
        res[0], res[1] = ox, oz
    for i in range(nl):
        if _det(L[i, 2], L[i, 3], L[i, 0] - res[0], L[i, 1] - res[1]) > 0.0:
            tx, tz = res[0], res[1]
            if not _lp1(L, i, radius, ox, oz, dir_opt, res):
                res[0], res[1] = tx, tz
                return i
    return nl


@njit(cache=True)
def _lp3(L, nl, n_obst, begin, radius, res, proj):
    """3-D fallback (RVO2 linearProgram3): minimise the largest violation of
    the agent lines from ``begin`` on, keeping the obstacle lines."""
    dist = 0.0
    for i in range(begin, nl):
        if _det(L[i, 2], L[i, 3], L[i, 0] - res[0], L[i, 1] - res[1]) > dist:
            m = 0
            for j in range(n_obst):
                proj[m, 0], proj[m, 1], proj[m, 2], proj[m, 3] = L[j, 0], L[j, 1], L[j, 2], L[j, 3]
                m += 1
            for j in range(n_obst, i):
                det = _det(L[i, 2], L[i, 3], L[j, 2], L[j, 3])
                if abs(det) <= ORCA_EPS:
                    if L[i, 2] * L[j, 2] + L[i, 3] * L[j, 3] > 0.0:
                        continue
                    qx, qz = 0.5 * (L[i, 0] + L[j, 0]), 0.5 * (L[i, 1] + L[j, 1])
                else:
                    t = _det(L[j, 2], L[j, 3], L[i, 0] - L[j, 0], L[i, 1] - L[j, 1]) / det
                    qx, qz = L[i, 0] + t * L[i, 2], L[i, 1] + t * L[i, 3]
                ddx, ddz = L[j, 2] - L[i, 2], L[j, 3] - L[i, 3]
                s = math.sqrt(ddx * ddx + ddz * ddz)
                if s > 0.0:
                    ddx, ddz = ddx / s, ddz / s
                proj[m, 0], proj[m, 1], proj[m, 2], proj[m, 3] = qx, qz, ddx, ddz
                m += 1
            tx, tz = res[0], res[1]
            if _lp2(proj, m, radius, -L[i, 3], L[i, 2], True, res) < m:
                res[0], res[1] = tx, tz  # numerically failed: keep the previous result
            dist = _det(L[i, 2], L[i, 3], L[i, 0] - res[0], L[i, 1] - res[1])


@njit(cache=True, inline="always")
def _agent_line(L, m, px, pz, vx, vz, l, inv_tau, inv_dt, share, i, j):
    """ORCA line of relative position (px, pz), relative velocity (vx, vz),
    combined radius l; ``share`` 0.5 (agents) or 1 (static obstacles). The
    line's point is stored relative to the agent's velocity (added by the caller)."""
    d2 = px * px + pz * pz
    l2 = l * l
    if d2 > l2:
        wx, wz = vx - inv_tau * px, vz - inv_tau * pz
        w2 = wx * wx + wz * wz
        dot1 = wx * px + wz * pz
        if dot1 < 0.0 and dot1 * dot1 > l2 * w2:
            wl = math.sqrt(w2)
            ux_, uz_ = wx / wl, wz / wl
            dx, dz = uz_, -ux_
            ux, uz = (l * inv_tau - wl) * ux_, (l * inv_tau - wl) * uz_
        else:
            leg = math.sqrt(d2 - l2)
            if _det(px, pz, wx, wz) > 0.0:
                dx, dz = (px * leg - pz * l) / d2, (px * l + pz * leg) / d2
            else:
                dx, dz = -(px * leg + pz * l) / d2, -(-px * l + pz * leg) / d2
            dot2 = vx * dx + vz * dz
            ux, uz = dot2 * dx - vx, dot2 * dz - vz
    else:
        wx, wz = vx - inv_dt * px, vz - inv_dt * pz
        wl = math.sqrt(wx * wx + wz * wz)
        if wl > 0.0:
            ux_, uz_ = wx / wl, wz / wl
        else:  # coincident and at rest relative to each other: part along the hashed direction
            hx, hz = coincident_dir(i, j)
            ux_, uz_ = -hx, -hz
        dx, dz = uz_, -ux_
        ux, uz = (l * inv_dt - wl) * ux_, (l * inv_dt - wl) * uz_
    L[m, 0], L[m, 1], L[m, 2], L[m, 3] = share * ux, share * uz, dx, dz


@njit(cache=True, parallel=True)
def _orca_kernel(S, order, cx, cz, start, gx, gz, dense, mask, vstart, vpref, circles, verts, pstart, pbound,
                 tau, tau_o, nd, max_nb, vmax_param, dt, max_lines, near_d, salt, out, near):
    n = S.shape[0]
    nblocks = (n + ORCA_BLOCK - 1) // ORCA_BLOCK
    inv_tau, inv_tau_o, inv_dt = 1.0 / tau, 1.0 / tau_o, 1.0 / dt
    nd2 = nd * nd
    for blk in prange(nblocks):
        L = np.empty((max_lines, 4))
        proj = np.empty((max_lines, 4))
        nb_d = np.empty(max_nb)
        nb_m = np.empty(max_nb, np.int64)
        res = np.empty(2)
        for k in range(blk * ORCA_BLOCK, min(n, (blk + 1) * ORCA_BLOCK)):
            i = order[k]
            px, pz, ri = S[k, 0], S[k, 1], S[k, 2]
            vix, viz = vstart[i, 0], vstart[i, 1]
            ox, oz = vpref[i, 0], vpref[i, 1]
            vmax = vmax_param if vmax_param > 0.0 else math.sqrt(ox * ox + oz * oz)
            if ox * ox + oz * oz > 0.0:
                hx, hz = coincident_dir(i, i + 1 + salt)
                ox += ORCA_PERTURB * hx
                oz += ORCA_PERTURB * hz
            m = 0
            # static obstacles first (they stay hard in the 3-D fallback)
            reach = ri + ORCA_OBSTACLE_REACH * vmax * tau_o + 1e-9
            for c in range(circles.shape[0]):
                rx, rz = circles[c, 0] - px, circles[c, 1] - pz
                if math.sqrt(rx * rx + rz * rz) - circles[c, 2] < reach and m < max_lines:
                    _agent_line(L, m, rx, rz, vix, viz, ri + circles[c, 2], inv_tau_o, inv_dt, 1.0, i, -1)
                    L[m, 0] += vix
                    L[m, 1] += viz
                    m += 1
            for q in range(pbound.shape[0]):
                bx, bz = px - pbound[q, 0], pz - pbound[q, 1]
                if math.sqrt(bx * bx + bz * bz) - pbound[q, 2] > reach:
                    continue
                s, e = pstart[q], pstart[q + 1]
                for a in range(s, e):
                    b = a + 1 if a + 1 < e else s
                    ax, az = verts[a, 0], verts[a, 1]
                    ux, uz = verts[b, 0] - ax, verts[b, 1] - az
                    ll = ux * ux + uz * uz
                    t = ((px - ax) * ux + (pz - az) * uz) / ll if ll > 0.0 else 0.0
                    t = min(max(t, 0.0), 1.0)
                    qx, qz = ax + t * ux, az + t * uz
                    rx, rz = qx - px, qz - pz
                    d = math.sqrt(rx * rx + rz * rz)
                    if d >= reach or m >= max_lines:
                        continue
                    if t > 0.0 and t < 1.0 and d > 0.0:
                        nx, nz = -rx / d, -rz / d  # outward: from the edge towards the agent
                        c0 = -(d - ri) * inv_tau_o if d > ri else (ri - d) * inv_dt
                        # valid side {v : v . n >= c0} lies left of direction (n_z, -n_x)
                        L[m, 0], L[m, 1], L[m, 2], L[m, 3] = c0 * nx, c0 * nz, nz, -nx
                    else:
                        _agent_line(L, m, rx, rz, vix, viz, ri, inv_tau_o, inv_dt, 1.0, i, -1)
                        L[m, 0] += vix
                        L[m, 1] += viz
                    m += 1
            n_obst = m
            # the max_nb nearest neighbours within nd, by insertion (ties: visiting order)
            cnt = 0
            nr = 0
            ix, iz = np.int64(cx[i]), np.int64(cz[i])
            for o in range(9):
                key = bucket(o, ix, iz, gx, gz, dense, mask)
                if key < 0:
                    continue
                for mm in range(start[key], start[key + 1]):
                    if mm == k:
                        continue
                    dx, dz = S[mm, 0] - px, S[mm, 1] - pz
                    d2 = dx * dx + dz * dz
                    ln = ri + S[mm, 2] + near_d
                    if d2 < ln * ln:
                        nr = 1
                    if d2 >= nd2:
                        continue
                    if cnt == max_nb and d2 >= nb_d[cnt - 1]:
                        continue
                    p = cnt if cnt < max_nb else max_nb - 1
                    while p > 0 and nb_d[p - 1] > d2:
                        if p < max_nb:
                            nb_d[p] = nb_d[p - 1]
                            nb_m[p] = nb_m[p - 1]
                        p -= 1
                    nb_d[p] = d2
                    nb_m[p] = mm
                    if cnt < max_nb:
                        cnt += 1
            for q in range(cnt):
                mm = nb_m[q]
                j = order[mm]
                if m >= max_lines:
                    break
                _agent_line(L, m, S[mm, 0] - px, S[mm, 1] - pz, vix - vstart[j, 0], viz - vstart[j, 1],
                            ri + S[mm, 2], inv_tau, inv_dt, 0.5, i, j)
                L[m, 0] += vix
                L[m, 1] += viz
                m += 1
            fail = _lp2(L, m, vmax, ox, oz, False, res)
            if fail < m:
                _lp3(L, m, n_obst, fail, vmax, res, proj)
            s2 = math.sqrt(res[0] * res[0] + res[1] * res[1])
            f = vmax / s2 if s2 > vmax else 1.0  # rounding of line intersections on the speed circle
            out[i, 0] = res[0] * f
            out[i, 1] = res[1] * f
            near[i] = nr


def orca_velocities(position, radius, vstart, vpref, time_horizon=2.0, time_horizon_obstacles=1.0,
                    neighbor_distance=5.0, max_neighbors=10, max_speed=0.0, dt=0.05, obstacles=None,
                    grid: Grid | None = None, scratch=None, near=None, near_d=0.0, salt=0):
    """New velocities of every agent by ORCA.

    Parameters
    ----------
    position : (n, 3) float64 start-of-step positions; radius : (n,) float64
    vstart : (n, 2) float64 start-of-step velocities; vpref : (n, 2) float64 preferred velocities
    time_horizon, time_horizon_obstacles : seconds; neighbor_distance : metres; max_neighbors : int
    max_speed : m/s, 0 = |vpref| per agent; dt : the step, seconds
    obstacles : sim.obstacles.ObstacleSet or None; grid, scratch : reused buffers
    near : (n,) uint8 output or None, as :func:`sim.avoidance.cfsm.cfsm_velocities` (``near_d`` metres)
    salt : int, the step number (varies the symmetry-breaking perturbation, ORCA_PERTURB)

    Returns
    -------
    out : (n, 2) float64 velocities; grid : Grid; scratch : (n, 3) float64
    """
    from sim.avoidance.cfsm import obstacle_arrays

    n = position.shape[0]
    out = np.zeros((n, 2), np.float64)
    grid = build_grid(position, float(neighbor_distance), out=grid)
    if scratch is None or scratch.shape != (n, 3):
        scratch = np.empty((n, 3), np.float64)
    if n == 0:
        return out, grid, scratch
    gather(position, radius, grid.order, scratch)
    circles, verts, pstart, pbound = obstacle_arrays(obstacles)
    max_lines = int(max_neighbors) + circles.shape[0] + verts.shape[0] + 1
    _orca_kernel(scratch, grid.order, grid.cx, grid.cz, grid.start, grid.dims[0], grid.dims[1], grid.dense,
                 grid.mask, vstart, vpref, circles, verts, pstart, pbound, float(time_horizon),
                 float(time_horizon_obstacles), float(neighbor_distance), int(max_neighbors), float(max_speed),
                 float(dt), max_lines, float(near_d), int(salt), out,
                 near if near is not None and near.shape == (n,) else np.empty(n, np.uint8))
    return out, grid, scratch
