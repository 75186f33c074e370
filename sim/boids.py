"""Boids flocking on the XZ plane (effect ``boids``).

Wand & Straßer 2002, §5.2 (the horse herd): "a simplified version of the boids
model [Reynolds 1987] ... controlled by local force fields around each object
and each obstacle. A spatial grid data structure is used to efficiently
retrieve the local neighbors of each object to integrate the forces."

Per agent ``i`` and fixed step ``dt`` (one sub-step of ``World.step``):

1. Neighbours: the first ``max_neighbors`` agents ``j != i`` with
   ``|p_j - p_i| < radius``, visited in a fixed order (3 x 3 cells of
   :mod:`sim.grid`, x-offset major; within a cell by agent index); at most
   ``BOIDS_CANDIDATE_FACTOR * max_neighbors`` candidates are examined.
   All neighbour math uses float64 differences ``d = p_j - p_i``, so results
   do not depend on the distance of the flock from the origin.
2. Steering accelerations (m/s^2), summed:

   - separation ``w_separation * max_accel * sum_j -d/|d| (1 - |d|/rs)`` for
     ``|d| < rs = min(separation_radius, radius)``; coincident agents push
     apart along a direction hashed from the pair (antisymmetric, no NaN);
   - alignment ``w_alignment * (mean v_j - v_i) / BOIDS_ALIGN_TAU``;
   - cohesion ``w_cohesion * mean d / BOIDS_COHESION_TAU^2``;
   - avoidance: for approaching neighbours ahead, ``w_avoid * max_accel *
     min(1, sum (1 - |d|/radius))`` to the agent's right (breaks head-on
     symmetry: both agents of a head-on pair turn right and pass);
   - cruise ``w_cruise * (cruise_speed - |v|) * f / BOIDS_CRUISE_TAU`` along the
     forward direction ``f`` (velocity, or the heading when standing still);
   - bounds: inside the margin, ``w_bounds * max_accel * depth / margin``
     inwards per axis (outside the bounds depth > margin: agents return);
   - external: ``world.resources["boids.accel"]`` (n, 3), written by the goals
     and obstacles effects before this step, zeroed after.

3. Limits: ``|a| <= max_accel``; ``v' = v + a dt``; the turn from ``v`` to ``v'``
   is at most ``max_turn_rate * dt``; ``|v'| <= max_speed``. Then
   ``p' = p + v' dt`` (x, z only; y belongs to terrain_follow) and the heading
   moves towards ``atan2(v'_x, v'_z)`` by ``1 - exp(-dt / heading_smoothing)``
   of the wrapped difference (unchanged while standing still).

Implementation: the grid is built by a serial counting sort, a serial pass
copies (x, z, vx, vz) of every agent in grid order (neighbours become
contiguous in memory), then one parallel loop over agents (``prange``) steers
each agent from that snapshot and integrates its own row of the state. Each
agent writes only its own outputs and visits neighbours in a fixed order, so
results are bit-identical for any thread count. Velocities are planar
(``velocity.y = 0``). State used per agent: the CrowdState (78 bytes) plus
the grid (about 20 bytes) and the snapshot (32 bytes).

Animation coupling (documented choice): boids sets ``anim_rate = |v| /
clip.speed`` for clips with a natural ground speed, so one cycle of the clip
covers ``clip.speed * clip.duration`` metres (the stride) and feet do not
slide; the ``animation`` effect then advances ``anim_time += anim_rate * dt``.
Without the animation effect boids advances ``anim_time`` itself. ``walk_clip``
and ``run_clip`` are switched by speed (``run_speed`` with ``run_hysteresis``),
keeping the phase fraction.

Departure from the paper: besides the force fields, obstacles (sim.obstacles)
add a hard constraint, and the turn-rate / acceleration limits make the motion
plausible for legged characters.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.angles import atan2_fast
from sim.config import (
    BOIDS_ALIGN_TAU,
    BOIDS_CANDIDATE_FACTOR,
    BOIDS_COHESION_TAU,
    BOIDS_COINCIDENT_A,
    BOIDS_COINCIDENT_B,
    BOIDS_CRUISE_TAU,
    BOIDS_SPEED_EPS,
)
from sim.grid import Grid, build_grid, build_grid_numpy, cell_key, keys_numpy
from sim.params import Param, ParamError


class _Bounds(Param):
    def check(self, key, value):
        if not isinstance(value, list) or len(value) not in (0, 4):
            raise ParamError(key, f"expected [] (unbounded) or [xmin, zmin, xmax, zmax], got {value!r}")
        v = [Param("float").check(f"{key}[{i}]", x) for i, x in enumerate(value)]
        if v and not (v[0] < v[2] and v[1] < v[3]):
            raise ParamError(key, f"expected xmin < xmax and zmin < zmax, got {value!r}")
        return v


PARAMS: dict[str, Param] = {
    "radius": Param("float", 2.0, min=1e-3, max=1e4, doc="neighbour radius = grid cell side, metres"),
    "separation_radius": Param("float", 1.0, min=1e-3, max=1e4, doc="separation acts below this distance, metres"),
    "max_neighbors": Param("int", 32, min=1, max=1024,
                           doc="neighbours used per agent (the first found in grid order); at most "
                               "BOIDS_CANDIDATE_FACTOR (8) x this many candidates are examined, which bounds "
                               "the cost of very dense crowds (e.g. 10,000 agents in one cell)"),
    "w_separation": Param("float", 1.5, min=0.0, max=100.0, doc="separation weight"),
    "w_alignment": Param("float", 0.5, min=0.0, max=100.0, doc="alignment weight"),
    "w_cohesion": Param("float", 0.3, min=0.0, max=100.0, doc="cohesion weight"),
    "w_avoid": Param("float", 0.5, min=0.0, max=100.0, doc="sidestep weight for approaching neighbours ahead"),
    "w_cruise": Param("float", 1.0, min=0.0, max=100.0, doc="weight pulling the speed to cruise_speed"),
    "cruise_speed": Param("float", 1.4, min=0.0, max=100.0, doc="preferred ground speed, m/s"),
    "max_speed": Param("float", 2.0, min=1e-3, max=100.0, doc="speed limit, m/s"),
    "max_accel": Param("float", 4.0, min=1e-3, max=1000.0, doc="acceleration limit, m/s^2"),
    "max_turn_rate": Param("float", 180.0, min=1e-3, max=36000.0, doc="turn-rate limit of the velocity, deg/s"),
    "heading_smoothing": Param("float", 0.15, min=0.0, max=10.0,
                               doc="time constant of the heading following the velocity, s (0 = none)"),
    "bounds": _Bounds("list", [], doc="world bounds [xmin, zmin, xmax, zmax], metres; [] = unbounded"),
    "bounds_margin": Param("float", 5.0, min=1e-3, doc="soft steering zone inside the bounds, metres"),
    "w_bounds": Param("float", 2.0, min=0.0, max=100.0, doc="bounds steering weight"),
    "walk_clip": Param("str", "walk", doc="clip used below run_speed (if the character has it)"),
    "run_clip": Param("str", "run", doc="clip used above run_speed (if the character has it)"),
    "run_speed": Param("float", 2.5, min=0.0, doc="walk -> run switch speed, m/s"),
    "run_hysteresis": Param("float", 0.3, min=0.0, doc="run -> walk switches below run_speed - this, m/s"),
}

# indices into the float64 parameter vector passed to the kernels
_P_NAMES = ("radius", "rs", "w_separation", "w_alignment", "w_cohesion", "w_avoid", "w_cruise", "cruise_speed",
            "max_speed", "max_accel", "max_turn", "heading_smoothing", "bounded", "xmin", "zmin", "xmax", "zmax",
            "bounds_margin", "w_bounds")
_P = {k: i for i, k in enumerate(_P_NAMES)}


def param_vector(cfg: dict) -> np.ndarray:
    """The (len(_P_NAMES),) float64 vector of a validated cfg (defaults filled)."""
    c = {k: p.default for k, p in PARAMS.items()}
    c.update(cfg)
    b = c["bounds"] or [0.0, 0.0, 0.0, 0.0]
    v = dict(radius=c["radius"], rs=min(c["separation_radius"], c["radius"]), w_separation=c["w_separation"],
             w_alignment=c["w_alignment"], w_cohesion=c["w_cohesion"], w_avoid=c["w_avoid"], w_cruise=c["w_cruise"],
             cruise_speed=c["cruise_speed"], max_speed=c["max_speed"], max_accel=c["max_accel"],
             max_turn=math.radians(c["max_turn_rate"]), heading_smoothing=c["heading_smoothing"],
             bounded=1.0 if c["bounds"] else 0.0, xmin=b[0], zmin=b[1], xmax=b[2], zmax=b[3],
             bounds_margin=c["bounds_margin"], w_bounds=c["w_bounds"])
    return np.array([float(v[k]) for k in _P_NAMES], np.float64)


# ----------------------------------------------------------------- kernels
@njit(cache=True, inline="always")
def _wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


@njit(cache=True, inline="always")
def _bounds_axis(x, lo, hi, margin):
    """Inward push in [0, inf) along one axis: depth into the margin / margin."""
    if x < lo + margin:
        return (lo + margin - x) / margin
    if x > hi - margin:
        return -(x - (hi - margin)) / margin
    return 0.0


@njit(cache=True, inline="always")
def _limit(vx, vz, nvx, nvz, dt, max_speed, max_turn, cos_lim):
    """Turn-rate then speed limit of the new velocity (nvx, nvz).

    The turn exceeds ``lim = max_turn * dt`` iff ``cos(turn) < cos_lim``
    (``cos_lim = cos(lim)``, or -2 when lim >= pi): no trigonometry per agent
    unless the limit applies."""
    s0 = math.sqrt(vx * vx + vz * vz)
    s1 = math.sqrt(nvx * nvx + nvz * nvz)
    if s0 > BOIDS_SPEED_EPS and s1 > BOIDS_SPEED_EPS:
        if vx * nvx + vz * nvz < cos_lim * s0 * s1:
            lim = max_turn * dt
            a = lim if vx * nvz - vz * nvx > 0 else -lim
            c, s = math.cos(a), math.sin(a)
            ux, uz = vx / s0, vz / s0
            nvx = (c * ux - s * uz) * s1
            nvz = (s * ux + c * uz) * s1
    if s1 > max_speed:
        f = max_speed / s1
        nvx *= f
        nvz *= f
    return nvx, nvz


@njit(cache=True, inline="always")
def _wrap_pi(a):
    """Wrap a in (-3 pi, 3 pi) to [-pi, pi] without trigonometry."""
    if a > math.pi:
        a -= 2.0 * math.pi
    elif a < -math.pi:
        a += 2.0 * math.pi
    return a


@njit(cache=True, inline="always")
def _integrate(pos, vel, heading, i, vx, vz, dt, alpha):
    """p += v' dt (x, z); v = v'; heading follows v' by ``alpha`` of the turn."""
    vel[i, 0] = vx
    vel[i, 1] = 0.0
    vel[i, 2] = vz
    pos[i, 0] += vx * dt
    pos[i, 2] += vz * dt
    if vx * vx + vz * vz > BOIDS_SPEED_EPS * BOIDS_SPEED_EPS:
        h = heading[i]
        if h > math.pi or h < -math.pi:
            h = _wrap(h)
        heading[i] = _wrap_pi(h + alpha * _wrap_pi(atan2_fast(vx, vz) - h))


@njit(cache=True)
def _gather_kernel(pos, vel, order, sxz):
    """sxz[k] = (x, z, vx, vz) of agent order[k]: neighbours become contiguous.

    Serial on purpose: it is memory-bound, and every parallel region costs a
    thread wake-up (milliseconds on a loaded machine)."""
    for k in range(order.shape[0]):
        i = order[k]
        sxz[k, 0] = pos[i, 0]
        sxz[k, 1] = pos[i, 2]
        sxz[k, 2] = vel[i, 0]
        sxz[k, 3] = vel[i, 2]


@njit(cache=True, parallel=True)
def _steer_kernel(sxz, pos, vel, heading, ext, has_ext, order, cx, cz, start, gx, gz, dense, mask,
                  P, max_nb, max_cand, dt, alpha, cos_lim):
    """One step of every agent: steering from the grid-sorted snapshot
    (x, z, vx, vz) ``sxz`` of the previous state, limits, then integration of
    its own ``pos``, ``vel`` and ``heading`` row (nobody else reads them during
    the loop: neighbours are read from ``sxz``), so agents are independent and
    the result does not depend on the thread count (see module doc)."""
    n = sxz.shape[0]
    radius = P[0]
    r2 = radius * radius
    rs = P[1]
    inv_rs = 1.0 / rs
    inv_r = 1.0 / radius
    max_accel = P[9]
    for k in prange(n):
        i = order[k]
        px, pz = sxz[k, 0], sxz[k, 1]
        vx, vz = sxz[k, 2], sxz[k, 3]
        sp = math.sqrt(vx * vx + vz * vz)
        if sp > BOIDS_SPEED_EPS:
            fx, fz = vx / sp, vz / sp
        else:
            fx, fz = math.sin(heading[i]), math.cos(heading[i])
        sepx = 0.0
        sepz = 0.0
        avx = 0.0
        avz = 0.0
        cox = 0.0
        coz = 0.0
        avoid = 0.0
        cnt = 0
        seen = 0
        ix, iz = np.int64(cx[i]), np.int64(cz[i])
        done = False
        # the 3 x 3 cells row by row (z outer, x inner); a dense grid's row of three cells is one range of the
        # sorted agents, a hashed grid's cells are visited one by one
        for o in range(9 if not dense else 3):
            if done:
                break
            if dense:
                jz = iz + (o - 1)
                if jz < 0 or jz >= gz:
                    continue
                row = jz * gx
                m0 = start[row + max(ix - 1, 0)]
                m1 = start[row + min(ix + 1, gx - 1) + 1]
            else:
                jx, jz = ix + (o % 3 - 1), iz + (o // 3 - 1)
                key = cell_key(jx, jz, np.int64(gx), dense, np.int64(mask))
                dup = False
                for q in range(o):  # a bucket reached from two cells is visited once
                    if cell_key(ix + (q % 3 - 1), iz + (q // 3 - 1), np.int64(gx), dense, np.int64(mask)) == key:
                        dup = True
                        break
                if dup:
                    continue
                m0, m1 = start[key], start[key + 1]
            for m in range(m0, m1):
                if m == k:
                    continue
                seen += 1
                dx = sxz[m, 0] - px
                dz = sxz[m, 1] - pz
                d2 = dx * dx + dz * dz
                if d2 < r2:
                    d = math.sqrt(d2)
                    wvx, wvz = sxz[m, 2], sxz[m, 3]
                    cnt += 1
                    avx += wvx
                    avz += wvz
                    cox += dx
                    coz += dz
                    if d < rs:
                        w = 1.0 - d * inv_rs
                        if d > 0.0:
                            inv_d = 1.0 / d
                            sepx -= dx * inv_d * w
                            sepz -= dz * inv_d * w
                        else:
                            j = order[m]
                            lo, hi = min(i, j), max(i, j)
                            t = (lo * BOIDS_COINCIDENT_A + hi * BOIDS_COINCIDENT_B) % 1.0
                            sg = 1.0 if i < j else -1.0
                            sepx -= sg * math.cos(2.0 * math.pi * t) * w
                            sepz -= sg * math.sin(2.0 * math.pi * t) * w
                    if dx * fx + dz * fz > 0.0 and dx * (vx - wvx) + dz * (vz - wvz) > 0.0:
                        avoid += 1.0 - d * inv_r
                if cnt >= max_nb or seen >= max_cand:
                    done = True
                    break
        ax = P[2] * max_accel * sepx
        az = P[2] * max_accel * sepz
        if cnt > 0:
            inv = 1.0 / cnt
            ax += P[3] * (avx * inv - vx) / BOIDS_ALIGN_TAU
            az += P[3] * (avz * inv - vz) / BOIDS_ALIGN_TAU
            ax += P[4] * cox * inv / (BOIDS_COHESION_TAU * BOIDS_COHESION_TAU)
            az += P[4] * coz * inv / (BOIDS_COHESION_TAU * BOIDS_COHESION_TAU)
        if avoid > 0.0:
            s = P[5] * max_accel * min(avoid, 1.0)
            ax += -fz * s  # right of the forward direction (Y up, 0 faces +Z)
            az += fx * s
        c = P[6] * (P[7] - sp) / BOIDS_CRUISE_TAU
        ax += c * fx
        az += c * fz
        if P[12] > 0.0:
            ax += P[18] * max_accel * _bounds_axis(px, P[13], P[15], P[17])
            az += P[18] * max_accel * _bounds_axis(pz, P[14], P[16], P[17])
        if has_ext:
            ax += ext[i, 0]
            az += ext[i, 2]
        am = math.sqrt(ax * ax + az * az)
        if am > max_accel:
            ax *= max_accel / am
            az *= max_accel / am
        nvx, nvz = _limit(vx, vz, vx + ax * dt, vz + az * dt, dt, P[8], P[10], cos_lim)
        _integrate(pos, vel, heading, i, nvx, nvz, dt, alpha)


def heading_alpha(P, dt: float) -> float:
    """Fraction of the heading error removed in one step: 1 - exp(-dt / smoothing)."""
    sm = float(P[_P["heading_smoothing"]])
    return 1.0 - math.exp(-dt / sm) if sm > 0 else 1.0


def turn_cos(P, dt: float) -> float:
    """cos of the largest turn in one step, or -2 when it is >= pi (no limit)."""
    lim = float(P[_P["max_turn"]]) * dt
    return math.cos(lim) if lim < math.pi else -2.0


def _candidate_cap(max_neighbors: int) -> int:
    return int(BOIDS_CANDIDATE_FACTOR * max_neighbors)


def step_kernel(position, velocity, heading, P, max_neighbors, dt, ext=None, grid=None, scratch=None):
    """One boids step in place with the numba kernels.

    Parameters
    ----------
    position, velocity : (n, 3) float64, C-contiguous; heading : (n,) float64
    P : parameter vector (:func:`param_vector`)
    max_neighbors : int >= 1
    dt : float > 0, seconds
    ext : (n, 3) float64 external accelerations or None
    grid : previous Grid to reuse arrays, or None
    scratch : (n, 4) float64 buffer for the sorted snapshot, or None

    Returns
    -------
    Grid, scratch
    """
    n = position.shape[0]
    grid = build_grid(position, float(P[0]), out=grid)
    if scratch is None or scratch.shape != (n, 4):
        scratch = np.empty((n, 4), np.float64)
    if n == 0:
        return grid, scratch
    has_ext = ext is not None
    e = ext if has_ext else np.zeros((1, 3))
    _gather_kernel(position, velocity, grid.order, scratch)
    _steer_kernel(scratch, position, velocity, heading, e, has_ext, grid.order, grid.cx, grid.cz, grid.start,
                  grid.dims[0], grid.dims[1], grid.dense, grid.mask, P, int(max_neighbors),
                  _candidate_cap(max_neighbors), float(dt), heading_alpha(P, dt), turn_cos(P, dt))
    return grid, scratch


def step_numpy(position, velocity, heading, P, max_neighbors, dt, ext=None):
    """Plain vectorised numpy reference of :func:`step_kernel` (in place).

    Builds candidate pairs per 3 x 3 cell offset from the stable cell sort,
    orders them as the kernel visits them, applies the neighbour / candidate
    caps by rank and accumulates with ``np.bincount``.
    """
    n = position.shape[0]
    g = build_grid_numpy(position, float(P[0]))
    if n == 0:
        return g
    radius, rs, max_accel = P[0], P[1], P[9]
    order, start = g.order.astype(np.int64), g.start.astype(np.int64)
    cx, cz = g.cx.astype(np.int64), g.cz.astype(np.int64)
    gx, gz = g.dims
    ii, jj, oo = [], [], []
    keys_seen = []
    agents = np.arange(n)
    for oi, (b, a) in enumerate([(b, a) for b in (-1, 0, 1) for a in (-1, 0, 1)]):  # z outer, x inner
        jx, jz = cx + a, cz + b
        valid = np.ones(n, bool)
        if g.dense:
            valid = (jx >= 0) & (jz >= 0) & (jx < gx) & (jz < gz)
        key = np.where(valid, keys_numpy(np.where(valid, jx, 0), np.where(valid, jz, 0), gx, g.dense, g.mask), -1)
        for prev in keys_seen:
            valid &= key != prev
        keys_seen.append(key)
        s = np.where(valid, start[np.maximum(key, 0)], 0)
        e = np.where(valid, start[np.maximum(key, 0) + 1], 0)
        cnt = e - s
        rep_i = np.repeat(agents, cnt)
        offs = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        rep_j = order[np.repeat(s, cnt) + offs]
        keep = rep_j != rep_i
        ii.append(rep_i[keep])
        jj.append(rep_j[keep])
        oo.append(np.full(keep.sum(), oi))
    ii, jj = np.concatenate(ii), np.concatenate(jj)
    srt = np.argsort(ii, kind="stable")  # per agent: offset order, then cell order
    ii, jj = ii[srt], jj[srt]
    first = np.searchsorted(ii, agents)
    cand_rank = np.arange(ii.size) - first[ii]
    dx = position[jj, 0] - position[ii, 0]
    dz = position[jj, 2] - position[ii, 2]
    d2 = dx * dx + dz * dz
    inr = d2 < radius * radius
    # neighbour rank among accepted, candidates beyond the caps are dropped
    acc_rank = np.cumsum(inr) - 1
    acc_rank = acc_rank - np.concatenate([[0], np.cumsum(inr)])[first[ii]]
    cap_c = _candidate_cap(max_neighbors)
    # the kernel stops after the candidate where cnt reaches max_nb or seen reaches cap_c
    use = inr & (acc_rank < max_neighbors) & (cand_rank < cap_c)
    ii, jj, dx, dz, d2 = ii[use], jj[use], dx[use], dz[use], d2[use]
    d = np.sqrt(d2)
    vx, vz = velocity[:, 0].copy(), velocity[:, 2].copy()
    sp = np.sqrt(vx * vx + vz * vz)
    moving = sp > BOIDS_SPEED_EPS
    fx = np.where(moving, vx / np.where(moving, sp, 1.0), np.sin(heading))
    fz = np.where(moving, vz / np.where(moving, sp, 1.0), np.cos(heading))
    bc = lambda w: np.bincount(ii, weights=w, minlength=n)
    cnt = np.bincount(ii, minlength=n)
    sep = d < rs
    w = np.where(sep, 1.0 - d * (1.0 / rs), 0.0)
    pos_d = d > 0
    lo, hi = np.minimum(ii, jj), np.maximum(ii, jj)
    t = (lo * BOIDS_COINCIDENT_A + hi * BOIDS_COINCIDENT_B) % 1.0
    sg = np.where(ii < jj, 1.0, -1.0)
    inv_d = 1.0 / np.where(pos_d, d, 1.0)
    sdx = np.where(pos_d, dx * inv_d, sg * np.cos(2.0 * np.pi * t))
    sdz = np.where(pos_d, dz * inv_d, sg * np.sin(2.0 * np.pi * t))
    sepx, sepz = -bc(sdx * w), -bc(sdz * w)
    ahead = (dx * fx[ii] + dz * fz[ii] > 0) & (dx * (vx[ii] - vx[jj]) + dz * (vz[ii] - vz[jj]) > 0)
    avoid = bc(np.where(ahead, 1.0 - d * (1.0 / radius), 0.0))
    ax = P[2] * max_accel * sepx
    az = P[2] * max_accel * sepz
    has = cnt > 0
    inv = 1.0 / np.maximum(cnt, 1)
    ax += np.where(has, P[3] * (bc(vx[jj]) * inv - vx) / BOIDS_ALIGN_TAU, 0.0)
    az += np.where(has, P[3] * (bc(vz[jj]) * inv - vz) / BOIDS_ALIGN_TAU, 0.0)
    ax += np.where(has, P[4] * bc(dx) * inv / BOIDS_COHESION_TAU ** 2, 0.0)
    az += np.where(has, P[4] * bc(dz) * inv / BOIDS_COHESION_TAU ** 2, 0.0)
    s = P[5] * max_accel * np.minimum(avoid, 1.0)
    ax += np.where(avoid > 0, -fz * s, 0.0)
    az += np.where(avoid > 0, fx * s, 0.0)
    c = P[6] * (P[7] - sp) / BOIDS_CRUISE_TAU
    ax += c * fx
    az += c * fz
    if P[12] > 0:
        def axis(x, lo_, hi_, m):
            return np.where(x < lo_ + m, (lo_ + m - x) / m, np.where(x > hi_ - m, -(x - (hi_ - m)) / m, 0.0))
        ax += P[18] * max_accel * axis(position[:, 0], P[13], P[15], P[17])
        az += P[18] * max_accel * axis(position[:, 2], P[14], P[16], P[17])
    if ext is not None:
        ax += ext[:, 0]
        az += ext[:, 2]
    am = np.sqrt(ax * ax + az * az)
    f = np.where(am > max_accel, max_accel / np.where(am > 0, am, 1.0), 1.0)
    ax, az = ax * f, az * f
    nvx, nvz = vx + ax * dt, vz + az * dt
    s1 = np.sqrt(nvx * nvx + nvz * nvz)
    lim = P[10] * dt
    turn = (sp > BOIDS_SPEED_EPS) & (s1 > BOIDS_SPEED_EPS) & (vx * nvx + vz * nvz < turn_cos(P, dt) * sp * s1)
    a = np.where(vx * nvz - vz * nvx > 0, lim, -lim)
    ca, sa = np.cos(a), np.sin(a)
    ux, uz = vx / np.where(moving, sp, 1.0), vz / np.where(moving, sp, 1.0)
    nvx = np.where(turn, (ca * ux - sa * uz) * s1, nvx)
    nvz = np.where(turn, (sa * ux + ca * uz) * s1, nvz)
    s1 = np.sqrt(nvx * nvx + nvz * nvz)
    f = np.where(s1 > P[8], P[8] / np.where(s1 > 0, s1, 1.0), 1.0)
    nvx, nvz = nvx * f, nvz * f
    velocity[:, 0], velocity[:, 1], velocity[:, 2] = nvx, 0.0, nvz
    position[:, 0] += nvx * dt
    position[:, 2] += nvz * dt
    alpha = heading_alpha(P, dt)
    mv = nvx * nvx + nvz * nvz > BOIDS_SPEED_EPS ** 2

    def wrap(a):
        return np.where(a > np.pi, a - 2 * np.pi, np.where(a < -np.pi, a + 2 * np.pi, a))
    h = np.where(np.abs(heading) > np.pi, np.arctan2(np.sin(heading), np.cos(heading)), heading)
    heading[:] = np.where(mv, wrap(h + alpha * wrap(np.arctan2(nvx, nvz) - h)), heading)
    return g


# ----------------------------------------------------------------- effect
class _Boids:
    """State of the installed effect (``world.resources["boids"]``)."""

    def __init__(self, cfg: dict, world):
        self.cfg = cfg
        self.P = param_vector(cfg)
        self.max_neighbors = int(cfg.get("max_neighbors", 32))
        self.grid: Grid | None = None
        self.scratch = None
        self.clips = _ClipTable(world.characters, cfg)


class _ClipTable:
    """Per character: clip ground speeds / durations and walk/run clip indices."""

    def __init__(self, characters, cfg):
        nc = max(1, len(characters))
        names = [list(_clips_of(c).items()) for c in characters] or [[]]
        mc = max(1, max(len(x) for x in names))
        self.speed = np.zeros((nc, mc))
        self.duration = np.ones((nc, mc))
        self.walk = -np.ones(nc, np.int64)
        self.run = -np.ones(nc, np.int64)
        for ci, clips in enumerate(names):
            for k, (name, clip) in enumerate(clips):
                self.speed[ci, k] = float(getattr(clip, "speed", 0.0) or 0.0)
                dur = float(getattr(clip, "duration", 1.0) or 1.0)
                self.duration[ci, k] = dur if dur > 0 else 1.0
                if name == cfg.get("walk_clip", "walk"):
                    self.walk[ci] = k
                if name == cfg.get("run_clip", "run"):
                    self.run[ci] = k
        self.any_speed = bool((self.speed > 0).any())
        self.run_speed = float(cfg.get("run_speed", 2.5))
        self.hyst = float(cfg.get("run_hysteresis", 0.3))

    def reachable(self, character: int, clips: set) -> set:
        """The clip indices agents of ``character`` starting with ``clips`` can
        play under :meth:`update`: walk and run both once either is among them."""
        clips = set(clips)
        if 0 <= character < len(self.walk):
            walk, run = int(self.walk[character]), int(self.run[character])
            if walk >= 0 and run >= 0 and clips & {walk, run}:
                clips |= {walk, run}
        return clips

    def update(self, st, dt: float, advance_time: bool) -> None:
        """Walk/run switch (keeping phase fraction) and anim_rate = speed / clip.speed.

        Only agents playing the walk or run clip switch; agents whose character or
        clip index is outside the table, or whose clip has no ground speed, keep
        their clip and rate. Without the animation effect, the time advances here
        (wrapped modulo the clip duration). Numba kernel (:func:`_clip_kernel`, one
        parallel loop over agents); :meth:`update_numpy` is its reference."""
        if st.n == 0 or not (self.any_speed or (self.walk >= 0).any()):
            return
        clip = st.clip
        if clip.dtype != np.int64 and not (clip.dtype.kind == "i" and clip.flags.c_contiguous):
            clip = clip.astype(np.int64)
        _clip_kernel(np.ascontiguousarray(st.character), clip, st.velocity, st.anim_time, st.anim_rate,
                     self.speed, self.duration, self.walk, self.run, self.run_speed, self.hyst, float(dt),
                     bool(advance_time))
        if clip is not st.clip:
            st.clip[:] = clip

    def update_numpy(self, st, dt: float, advance_time: bool) -> None:
        """Vectorised numpy reference of :meth:`update` (same results)."""
        if st.n == 0 or not (self.any_speed or (self.walk >= 0).any()):
            return
        nc, mc = self.speed.shape
        ch = st.character.astype(np.int64)
        ok = (ch >= 0) & (ch < nc)
        ch = np.where(ok, ch, 0)
        sp = np.hypot(st.velocity[:, 0], st.velocity[:, 2])
        walk, run = self.walk[ch], self.run[ch]
        both = ok & (walk >= 0) & (run >= 0)
        if both.any():
            cur = st.clip.astype(np.int64)
            to_run = both & (cur == walk) & (sp > self.run_speed)
            to_walk = both & (cur == run) & (sp < self.run_speed - self.hyst)
            chg = to_run | to_walk
            if chg.any():
                new = np.where(to_run, run, walk)[chg]
                old = cur[chg]
                d0 = self.duration[ch[chg], old]
                d1 = self.duration[ch[chg], new]
                st.anim_time[chg] = np.mod(st.anim_time[chg], d0) / d0 * d1
                st.clip[chg] = new
        cl = st.clip.astype(np.int64)
        ok &= (cl >= 0) & (cl < mc)
        cl = np.where(ok, cl, 0)
        cs = np.where(ok, self.speed[ch, cl], 0.0)
        has = cs > 0
        rate = np.where(has, sp / np.where(has, cs, 1.0), st.anim_rate)
        st.anim_rate[:] = rate.astype(np.float32)
        if advance_time and has.any():
            d = self.duration[ch, cl]
            st.anim_time[:] = np.where(has, np.mod(st.anim_time + rate * dt, d), st.anim_time)


@njit(cache=True, parallel=True)
def _clip_kernel(character, clip, velocity, anim_time, anim_rate, speed, duration, walk, run, run_speed, hyst, dt,
                 advance):  # pragma: no cover - compiled
    """:meth:`_ClipTable.update` per agent (each writes only its own clip, time and rate)."""
    nc, mc = speed.shape
    for i in prange(character.shape[0]):
        ch = np.int64(character[i])
        ok = 0 <= ch < nc
        if not ok:
            ch = 0
        sp = np.hypot(velocity[i, 0], velocity[i, 2])
        w, r = walk[ch], run[ch]
        cur = np.int64(clip[i])
        if ok and w >= 0 and r >= 0:
            new = -1
            if cur == w and sp > run_speed:
                new = r
            elif cur == r and sp < run_speed - hyst:
                new = w
            if new >= 0:
                d0 = duration[ch, cur]
                d1 = duration[ch, new]
                anim_time[i] = np.mod(anim_time[i], d0) / d0 * d1
                clip[i] = new
        cl = np.int64(clip[i])
        if not (ok and 0 <= cl < mc):
            ok = False
            cl = 0
        cs = speed[ch, cl] if ok else 0.0
        if cs > 0:
            rate = sp / cs
            anim_rate[i] = np.float32(rate)
            if advance:
                anim_time[i] = np.mod(anim_time[i] + rate * dt, duration[ch, cl])
        else:
            anim_rate[i] = anim_rate[i]


def _clips_of(ch) -> dict:
    c = getattr(ch, "clips", None)
    if c is None:
        c = getattr(ch, "animations", None)
    return dict(c or {})


def install(world, cfg: dict) -> None:
    """Effect ``boids``: adds step ``"boids"`` (before ``"animation"``).

    Publishes ``world.resources["boids"]`` (the effect state; ``.grid`` is the
    last neighbour grid) and ``world.resources["boids.accel"]`` ((n, 3) float64
    external accelerations that other effects add to before the step).
    """
    eff = _Boids(cfg, world)
    world.resources["boids"] = eff
    world.resources["boids.accel"] = None  # allocated by effects that use it

    def step(w, dt):
        st = w.state
        ext = w.resources.get("boids.accel")
        if ext is not None and ext.shape != (st.n, 3):
            ext = None
        eff.grid, eff.scratch = step_kernel(st.position, st.velocity, st.heading, eff.P, eff.max_neighbors,
                                            dt, ext=ext, grid=eff.grid, scratch=eff.scratch)
        if ext is not None:
            ext[:] = 0.0
        eff.clips.update(st, dt, advance_time="animation" not in w.effects)

    world.schedule.add_step("boids", step, before=("animation",))


def external_accel(world) -> np.ndarray:
    """The (n, 3) float64 external-acceleration buffer of the boids effect,
    allocated on first use (used by goals and obstacles)."""
    n = world.state.n
    a = world.resources.get("boids.accel")
    if a is None or a.shape != (n, 3):
        a = np.zeros((n, 3), np.float64)
        world.resources["boids.accel"] = a
    return a
