"""Plain numpy / Python references of the avoidance kernels (used by the tests).

Each function computes what its numba kernel computes, the obvious way: all
pairs instead of the grid, numpy broadcasting instead of loops where it can,
plain Python for the linear programs of ORCA. Sums run in a different order
than in the kernels, so results agree to rounding (the tests use 1e-9), not
bit for bit.
"""
from __future__ import annotations

import math

import numpy as np

from sim.avoidance.cfsm import CFSM_RANGE_FACTOR, CFSM_SPEED_EPS
from sim.config import BOIDS_COINCIDENT_A, BOIDS_COINCIDENT_B


def _coincident(i, j):
    lo, hi = np.minimum(i, j), np.maximum(i, j)
    t = (lo * BOIDS_COINCIDENT_A + hi * BOIDS_COINCIDENT_B) % 1.0
    sg = np.where(i < j, 1.0, -1.0)
    return sg * np.cos(2 * np.pi * t), sg * np.sin(2 * np.pi * t)


def _edges(obs):
    """(E, 4) polygon edges (ax, az, bx, bz) and (C, 3) circles of an ObstacleSet (or empty)."""
    if obs is None or obs.count == 0:
        return np.zeros((0, 4)), np.zeros((0, 3))
    e = []
    for k in range(obs.pstart.shape[0] - 1):
        p = obs.verts[obs.pstart[k]:obs.pstart[k + 1]]
        q = np.roll(p, -1, 0)
        e.append(np.concatenate([p, q], 1))
    return (np.concatenate(e, 0) if e else np.zeros((0, 4))), obs.circles


def blocked_numpy(p, q, obs) -> np.ndarray:
    """(m,) bool: segment p[k]-q[k] (each (m, 2)) crosses an obstacle (circle or polygon edge)."""
    edges, circles = _edges(obs)
    m = p.shape[0]
    out = np.zeros(m, bool)
    u = q - p
    ll = (u ** 2).sum(1)
    for cx, cz, r in circles:
        t = np.clip(np.where(ll > 0, ((cx - p[:, 0]) * u[:, 0] + (cz - p[:, 1]) * u[:, 1]) / np.where(ll > 0, ll, 1), 0),
                    0, 1)
        e = p + t[:, None] * u - np.array([cx, cz])
        out |= (e ** 2).sum(1) < r * r
    for ax, az, bx, bz in edges:
        cr = lambda x1, z1, x2, z2: x1 * z2 - z1 * x2  # noqa: E731
        d1 = cr(u[:, 0], u[:, 1], ax - p[:, 0], az - p[:, 1])
        d2 = cr(u[:, 0], u[:, 1], bx - p[:, 0], bz - p[:, 1])
        vx, vz = bx - ax, bz - az
        d3 = cr(vx, vz, p[:, 0] - ax, p[:, 1] - az)
        d4 = cr(vx, vz, q[:, 0] - ax, q[:, 1] - az)
        out |= (d1 * d2 < 0) & (d3 * d4 < 0)
    return out


def cfsm_numpy(position, radius, vpref, heading, a=8.0, D=0.1, b=5.0, Dw=0.02, T=1.0, cutoff=3.0, v0=0.0,
               side=0.0, obstacles=None):
    """Reference of :func:`sim.avoidance.cfsm.cfsm_velocities` (all pairs; ``cutoff`` > 0 required)."""
    n = position.shape[0]
    xz = position[:, [0, 2]]
    sp = np.hypot(vpref[:, 0], vpref[:, 1])
    moving = sp > CFSM_SPEED_EPS
    e = np.where(moving[:, None], vpref / np.where(moving, sp, 1.0)[:, None], 0.0)
    v0s = np.where(v0 > 0, v0, sp)
    i, j = np.nonzero(~np.eye(n, dtype=bool))
    d = xz[j] - xz[i]
    dist = np.hypot(d[:, 0], d[:, 1])
    use = dist < cutoff
    if obstacles is not None and obstacles.count:
        use &= ~blocked_numpy(xz[i], xz[j], obstacles)
    i, j, d, dist = i[use], j[use], d[use], dist[use]
    l = radius[i] + radius[j]
    f = a * np.exp(np.minimum((l - dist) / D, 50.0))
    hx, hz = _coincident(i, j)
    ux = np.where(dist > 0, d[:, 0] / np.where(dist > 0, dist, 1), hx)
    uz = np.where(dist > 0, d[:, 1] / np.where(dist > 0, dist, 1), hz)
    rx, rz = -f * ux, -f * uz
    counter = (dist > 0) & ((e[i] * d).sum(1) > 0) & ((e[i] * e[j]).sum(1) < 0)
    rx += np.where(counter, -side * f * e[i, 1], 0.0)
    rz += np.where(counter, side * f * e[i, 0], 0.0)
    Rx = np.bincount(i, rx, n)
    Rz = np.bincount(i, rz, n)
    if obstacles is not None and obstacles.count:
        edges, circles = _edges(obstacles)
        reach = radius + CFSM_RANGE_FACTOR * 2.0 * Dw + 1e-9
        for cx, cz, r in circles:
            px, pz = xz[:, 0] - cx, xz[:, 1] - cz
            rc = np.hypot(px, pz)
            dd = rc - r
            on = (dd < reach) & (rc > 0)
            ff = np.where(on, b * np.exp(np.minimum((radius - dd) / Dw, 50.0)), 0.0)
            Rx += ff * px / np.where(rc > 0, rc, 1)
            Rz += ff * pz / np.where(rc > 0, rc, 1)
        for ax, az, bx, bz in edges:
            ux_, uz_ = bx - ax, bz - az
            ll = ux_ * ux_ + uz_ * uz_
            t = np.clip(((xz[:, 0] - ax) * ux_ + (xz[:, 1] - az) * uz_) / ll if ll > 0 else 0.0, 0, 1)
            ex, ez = ax + t * ux_ - xz[:, 0], az + t * uz_ - xz[:, 1]
            dd = np.hypot(ex, ez)
            on = (dd < reach) & (dd > 0)
            ff = np.where(on, b * np.exp(np.minimum((radius - dd) / Dw, 50.0)), 0.0)
            Rx -= ff * ex / np.where(dd > 0, dd, 1)
            Rz -= ff * ez / np.where(dd > 0, dd, 1)
    Ux, Uz = e[:, 0] + Rx, e[:, 1] + Rz
    un = np.hypot(Ux, Uz)
    Ux = np.where(un > 0, Ux / np.where(un > 0, un, 1), np.sin(heading))
    Uz = np.where(un > 0, Uz / np.where(un > 0, un, 1), np.cos(heading))
    front = (Ux[i] * d[:, 0] + Uz[i] * d[:, 1]) >= 0
    corridor = np.abs(Ux[i] * d[:, 1] - Uz[i] * d[:, 0]) <= l
    gap = np.where(front & corridor, dist - l, 1e300)
    s = np.full(n, 1e300)
    np.minimum.at(s, i, gap)
    v = np.minimum(np.maximum(s / T, 0.0), v0s)
    v = np.where(moving, v, 0.0)
    return np.stack([Ux * v, Uz * v], 1)


def resolve_numpy(position, radius, clearance=None, obstacles=None, iterations=16, target=1.0 + 1e-4):
    """Reference of :func:`sim.avoidance.resolve.resolve` (all pairs; in place)."""
    from sim.obstacles import sdf_numpy

    n = position.shape[0]
    clearance = radius if clearance is None else clearance
    w = 0.0
    for it in range(iterations):
        xz = position[:, [0, 2]]
        i, j = np.nonzero(~np.eye(n, dtype=bool))
        d = xz[j] - xz[i]
        dist = np.hypot(d[:, 0], d[:, 1])
        l = radius[i] + radius[j]
        on = dist < l * target
        i, j, d, dist, l = i[on], j[on], d[on], dist[on], l[on]
        worst = np.zeros(n)
        np.maximum.at(worst, i, 1.0 - dist / l)
        w = float(worst.max()) if n else 0.0
        if w <= 0.0:
            return it, 0.0
        push = 0.5 * (l * target - dist)
        hx, hz = _coincident(i, j)
        ux = np.where(dist > 0, d[:, 0] / np.where(dist > 0, dist, 1), hx)
        uz = np.where(dist > 0, d[:, 1] / np.where(dist > 0, dist, 1), hz)
        mx, mz = np.bincount(i, -push * ux, n), np.bincount(i, -push * uz, n)
        mm = np.hypot(mx, mz)
        f = np.where(mm > radius, radius / np.where(mm > 0, mm, 1), 1.0)
        px = position[:, 0] + mx * f
        pz = position[:, 2] + mz * f
        if obstacles is not None and obstacles.count:
            for _ in range(4):
                dd, nx, nz = sdf_numpy(obstacles, px, pz)
                pen = clearance - dd
                px, pz = np.where(pen > 0, px + nx * pen, px), np.where(pen > 0, pz + nz * pen, pz)
        position[:, 0], position[:, 2] = px, pz
    return iterations, w


# ------------------------------------------------------------------ ORCA, plain Python
def _det(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _lp1(lines, no, radius, opt, dir_opt):
    (px, pz), (dx, dz) = lines[no]
    dot = px * dx + pz * dz
    disc = dot * dot + radius * radius - (px * px + pz * pz)
    if disc < 0:
        return None
    sq = math.sqrt(disc)
    tl, tr = -dot - sq, -dot + sq
    for i in range(no):
        den = _det((dx, dz), lines[i][1])
        num = _det(lines[i][1], (px - lines[i][0][0], pz - lines[i][0][1]))
        if abs(den) <= 1e-9:
            if num < 0:
                return None
            continue
        t = num / den
        if den >= 0:
            tr = min(tr, t)
        else:
            tl = max(tl, t)
        if tl > tr:
            return None
    if dir_opt:
        t = tr if opt[0] * dx + opt[1] * dz > 0 else tl
    else:
        t = min(max(dx * (opt[0] - px) + dz * (opt[1] - pz), tl), tr)
    return (px + t * dx, pz + t * dz)


def _lp2(lines, radius, opt, dir_opt):
    if dir_opt:
        res = (opt[0] * radius, opt[1] * radius)
    elif opt[0] ** 2 + opt[1] ** 2 > radius * radius:
        s = math.hypot(*opt)
        res = (opt[0] / s * radius, opt[1] / s * radius)
    else:
        res = tuple(opt)
    for i, ((px, pz), dr) in enumerate(lines):
        if _det(dr, (px - res[0], pz - res[1])) > 0:
            r = _lp1(lines, i, radius, opt, dir_opt)
            if r is None:
                return i, res
            res = r
    return len(lines), res


def _lp3(lines, n_obst, begin, radius, res):
    dist = 0.0
    for i in range(begin, len(lines)):
        (pix, piz), di = lines[i]
        if _det(di, (pix - res[0], piz - res[1])) > dist:
            proj = list(lines[:n_obst])
            for j in range(n_obst, i):
                (pjx, pjz), dj = lines[j]
                det = _det(di, dj)
                if abs(det) <= 1e-9:
                    if di[0] * dj[0] + di[1] * dj[1] > 0:
                        continue
                    q = (0.5 * (pix + pjx), 0.5 * (piz + pjz))
                else:
                    t = _det(dj, (pix - pjx, piz - pjz)) / det
                    q = (pix + t * di[0], piz + t * di[1])
                dd = (dj[0] - di[0], dj[1] - di[1])
                s = math.hypot(*dd)
                if s > 0:
                    dd = (dd[0] / s, dd[1] / s)
                proj.append((q, dd))
            k, r = _lp2(proj, radius, (-di[1], di[0]), True)
            if k >= len(proj):
                res = r
            dist = _det(di, (pix - res[0], piz - res[1]))
    return res


def _line(p, v, l, inv_tau, inv_dt, share, i, j):
    px, pz = p
    vx, vz = v
    d2, l2 = px * px + pz * pz, l * l
    if d2 > l2:
        wx, wz = vx - inv_tau * px, vz - inv_tau * pz
        w2 = wx * wx + wz * wz
        dot1 = wx * px + wz * pz
        if dot1 < 0 and dot1 * dot1 > l2 * w2:
            wl = math.sqrt(w2)
            ux_, uz_ = wx / wl, wz / wl
            dr = (uz_, -ux_)
            u = ((l * inv_tau - wl) * ux_, (l * inv_tau - wl) * uz_)
        else:
            leg = math.sqrt(d2 - l2)
            if _det((px, pz), (wx, wz)) > 0:
                dr = ((px * leg - pz * l) / d2, (px * l + pz * leg) / d2)
            else:
                dr = (-(px * leg + pz * l) / d2, -(-px * l + pz * leg) / d2)
            dot2 = vx * dr[0] + vz * dr[1]
            u = (dot2 * dr[0] - vx, dot2 * dr[1] - vz)
    else:
        wx, wz = vx - inv_dt * px, vz - inv_dt * pz
        wl = math.hypot(wx, wz)
        if wl > 0:
            ux_, uz_ = wx / wl, wz / wl
        else:
            hx, hz = _coincident(np.array(i), np.array(j))
            ux_, uz_ = -float(hx), -float(hz)
        dr = (uz_, -ux_)
        u = ((l * inv_dt - wl) * ux_, (l * inv_dt - wl) * uz_)
    return (share * u[0], share * u[1]), dr


def orca_numpy(position, radius, vstart, vpref, time_horizon=2.0, time_horizon_obstacles=1.0,
               neighbor_distance=5.0, max_neighbors=10, max_speed=0.0, dt=0.05, obstacles=None, salt=0):
    """Reference of :func:`sim.avoidance.orca.orca_velocities` (one agent at a time, plain Python)."""
    from sim.avoidance.orca import ORCA_OBSTACLE_REACH, ORCA_PERTURB

    n = position.shape[0]
    xz = position[:, [0, 2]]
    out = np.zeros((n, 2))
    edges, circles = _edges(obstacles)
    for i in range(n):
        p, v, w = xz[i], vstart[i], vpref[i]
        ri = radius[i]
        vmax = max_speed if max_speed > 0 else math.hypot(*w)
        if w[0] ** 2 + w[1] ** 2 > 0:
            hx, hz = _coincident(np.array(i), np.array(i + 1 + salt))
            w = (w[0] + ORCA_PERTURB * float(hx), w[1] + ORCA_PERTURB * float(hz))
        lines = []
        reach = ri + ORCA_OBSTACLE_REACH * vmax * time_horizon_obstacles + 1e-9
        for cx, cz, r in circles:
            rel = (cx - p[0], cz - p[1])
            if math.hypot(*rel) - r < reach:
                u, dr = _line(rel, v, ri + r, 1 / time_horizon_obstacles, 1 / dt, 1.0, i, -1)
                lines.append(((v[0] + u[0], v[1] + u[1]), dr))
        if obstacles is not None and obstacles.count:
            for k in range(obstacles.pbound.shape[0]):
                bx, bz, br = obstacles.pbound[k]
                if math.hypot(p[0] - bx, p[1] - bz) - br > reach:
                    continue
                poly = obstacles.verts[obstacles.pstart[k]:obstacles.pstart[k + 1]]
                for a in range(len(poly)):
                    A, B = poly[a], poly[(a + 1) % len(poly)]
                    U = B - A
                    ll = float(U @ U)
                    t = min(max(float((p - A) @ U) / ll if ll > 0 else 0.0, 0.0), 1.0)
                    q = A + t * U
                    rel = (q[0] - p[0], q[1] - p[1])
                    d = math.hypot(*rel)
                    if d >= reach:
                        continue
                    if 0 < t < 1 and d > 0:
                        nx, nz = -rel[0] / d, -rel[1] / d
                        c0 = -(d - ri) / time_horizon_obstacles if d > ri else (ri - d) / dt
                        lines.append(((c0 * nx, c0 * nz), (nz, -nx)))
                    else:
                        u, dr = _line(rel, v, ri, 1 / time_horizon_obstacles, 1 / dt, 1.0, i, -1)
                        lines.append(((v[0] + u[0], v[1] + u[1]), dr))
        n_obst = len(lines)
        d2 = ((xz - p) ** 2).sum(1)
        d2[i] = np.inf
        cand = np.nonzero(d2 < neighbor_distance ** 2)[0]
        cand = cand[np.argsort(d2[cand], kind="stable")][:max_neighbors]
        for j in cand:
            u, dr = _line(tuple(xz[j] - p), tuple(v - vstart[j]), ri + radius[j], 1 / time_horizon, 1 / dt, 0.5, i, j)
            lines.append(((v[0] + u[0], v[1] + u[1]), dr))
        k, res = _lp2(lines, vmax, tuple(w), False)
        if k < len(lines):
            res = _lp3(lines, n_obst, k, vmax, res)
        s = math.hypot(*res)
        out[i] = np.array(res) * (vmax / s if s > vmax else 1.0)
    return out
