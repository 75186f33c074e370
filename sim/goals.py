"""Goal seeking: waypoint paths and attractors (effect ``goals``).

Wand & Straßer 2002, §5.2 drive their herd by force fields; goals are one more
field. Each agent follows one of ``paths`` (a list of [x, z] waypoints):
``assign = "cycle"`` gives agent i path ``i mod len(paths)``, ``"group"`` gives
the agents of placement group g path ``g mod len(paths)`` (groups as recorded by
:func:`sim.placement.concat_states`; one group if unknown), ``"character"``
gives path ``character mod len(paths)``. An agent starts at the nearest
waypoint of its path and moves to the next one when within
``arrive_radius``; at the end it loops (``loop = true``) or stops there.
``attractors`` pull every agent within their radius towards their centre.

Steering: ``a = weight * (v_desired - v) / GOALS_TAU`` with ``v_desired`` of
magnitude ``speed`` towards the current waypoint (slowing down inside
``arrive_radius`` at the final waypoint of an open path) plus, per attractor,
``strength * (1 - dist / radius)`` towards its centre. The sum is added to
``world.resources["boids.accel"]`` before the ``boids`` step, which applies the
speed, acceleration and turn limits.

Without the boids effect, the goals step moves agents kinematically: velocity
``v_desired`` (attractors ignored), position += v dt, heading = direction of v.

With the ``routing`` effect (:mod:`sim.routing`), every waypoint is a routing goal: ``v_desired`` points along
the shortest route through the walkable area to it (``Router.directions``) instead of straight at it, a waypoint
counts as reached within ``arrive_radius`` of route length (not through a wall), and the arrival slow-down at
the end of an open path uses the remaining route length.

All geometry uses float64 differences (robust far from the origin); the step
is vectorised numpy (O(n) per step, per-agent independent), except the
kinematic step (no boids), a numba kernel (:func:`_kinematic_kernel`) whose
numpy reference is :meth:`Goals.desired_velocity` plus the moves in
:func:`kinematic_numpy` (same arithmetic, per agent, in the same order).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.config import GOALS_TAU
from sim.params import Param, ParamError, validate

_ATTRACTOR = {"center": Param("vec2", doc="[x, z], metres"),
              "radius": Param("float", min=1e-6, doc="reach, metres"),
              "strength": Param("float", 1.0, min=0.0, doc="acceleration at the centre, m/s^2")}


class _Paths(Param):
    def check(self, key, value):
        if not isinstance(value, list):
            raise ParamError(key, f"expected a list of paths [[[x, z], ...], ...], got {value!r}")
        out = []
        for i, p in enumerate(value):
            if not isinstance(p, list) or not p:
                raise ParamError(f"{key}[{i}]", f"expected a non-empty list of [x, z] waypoints, got {p!r}")
            out.append([Param("vec2").check(f"{key}[{i}][{j}]", q) for j, q in enumerate(p)])
        return out


class _Attractors(Param):
    def check(self, key, value):
        if not isinstance(value, list):
            raise ParamError(key, f"expected a list of tables, got {value!r}")
        out = []
        for i, t in enumerate(value):
            if not isinstance(t, dict):
                raise ParamError(f"{key}[{i}]", f"expected a table, got {t!r}")
            out.append(validate(_ATTRACTOR, t, f"{key}[{i}]"))
        return out


PARAMS: dict[str, Param] = {
    "paths": _Paths("list", [], doc="waypoint paths, each [[x, z], ...], metres"),
    "assign": Param("str", "cycle", choices=("cycle", "group", "character"),
                    doc="which path an agent follows: agent index, placement group or character, "
                        "modulo the number of paths"),
    "loop": Param("bool", True, doc="loop back to the first waypoint at the end of a path"),
    "arrive_radius": Param("float", 2.0, min=1e-3, doc="waypoint reached within this distance, metres"),
    "speed": Param("float", 1.4, min=0.0, max=100.0, doc="desired speed towards the waypoint, m/s"),
    "weight": Param("float", 1.0, min=0.0, max=100.0, doc="weight of the path steering"),
    "attractors": _Attractors("list", [], doc="[{center = [x, z], radius = r, strength = a}, ...]"),
}


class Goals:
    """Per-agent waypoint progress (``world.resources["goals"]``).

    paths : (W, 2) float64 waypoints back to back; pstart : (P + 1,) int64
    path : (n,) int64, path of every agent (-1 = none)
    target : (n,) int64, index into ``paths`` of the current waypoint
    """

    def __init__(self, cfg: dict, state):
        self.cfg = cfg
        paths = cfg.get("paths", [])
        self.waypoints = np.array([q for p in paths for q in p], np.float64).reshape(-1, 2)
        self.pstart = np.zeros(len(paths) + 1, np.int64)
        if paths:
            self.pstart[1:] = np.cumsum([len(p) for p in paths])
        self.att = np.array([[a["center"][0], a["center"][1], a["radius"], a["strength"]]
                             for a in cfg.get("attractors", [])], np.float64).reshape(-1, 4)
        self.router = None
        self._vd = None
        self._assign(state)

    def bind_router(self, router, state=None) -> None:
        """Route to the waypoints through the walkable area (effect ``routing``): one goal per waypoint. With the
        ``state``, every agent must have a route to its first waypoint (:meth:`_check_routes`)."""
        self.router = router
        self.wgoal = np.array([router.goal(("point", (float(x), float(z))), key=f"goals.paths: waypoint {k}")
                               for k, (x, z) in enumerate(self.waypoints)], np.int64)
        self._check_routes(state)

    def _check_routes(self, state) -> None:
        """ParamError naming the path and waypoint when a waypoint cannot be reached from the one before it, or
        naming the agent when its first waypoint cannot be reached from where it stands: before the run."""
        from sim.params import ParamError

        r = self.router
        for p in range(self.pstart.shape[0] - 1):
            w = self.waypoints[self.pstart[p]:self.pstart[p + 1]]
            loop = bool(self.cfg.get("loop", True)) and w.shape[0] > 1
            for k in range(1, w.shape[0] + (1 if loop else 0)):
                a, b = w[k - 1], w[k % w.shape[0]]
                if not r.reachable(int(self.wgoal[self.pstart[p] + k % w.shape[0]]), [a])[0]:
                    raise ParamError(f"paths[{p}][{k % w.shape[0]}]", f"waypoint ({b[0]:g}, {b[1]:g}) cannot be "
                                     f"reached from the waypoint before it ({a[0]:g}, {a[1]:g}): no route through "
                                     "the walkable area")
        if state is None or state.n != self.n:
            return
        st_pos = state.position[:, [0, 2]]
        has = np.nonzero(self.path >= 0)[0]
        for gid in np.unique(self.wgoal[self.target[has]]):
            sel = has[self.wgoal[self.target[has]] == gid]
            ok = r.reachable(int(gid), st_pos[sel])
            if not ok.all():
                i = int(sel[np.argmin(ok)])
                x, z = self.waypoints[self.target[i]]
                groups = getattr(state, "groups", None) or []
                group = next((g for g, (first, count) in enumerate(groups) if first <= i < first + count), 0)
                raise ParamError(f"placement[{group}]", f"agent {i} at ({st_pos[i, 0]:.6g}, {st_pos[i, 1]:.6g}) "
                                 f"cannot reach its waypoint ({x:g}, {z:g}) (goals path {int(self.path[i])}): no "
                                 f"route through the walkable area" + (f" (and {int((~ok).sum()) - 1} more)"
                                                                        if (~ok).sum() > 1 else ""))

    def _routed(self, st, has, ar):
        """(dirs (n, 2), dist (n,)) of the routed agents towards their current waypoints (advancing reached
        ones); agents without a path get 0 and inf (numpy: the reference of the routed step)."""
        n = st.n
        dirs, dist = np.empty((n, 2)), np.empty(n)
        gid = np.where(has, self.wgoal[self.target], -1)
        self.router.directions(st.position, gid, dirs, dist)
        reached = has & (dist < ar)
        if reached.any():
            idx = np.nonzero(reached)[0]
            t = self.target[idx] + 1
            end = self.pstart[self.path[idx] + 1]
            first = self.pstart[self.path[idx]]
            t = np.where(t >= end, first if self.cfg.get("loop", True) else end - 1, t)
            self.target[idx] = t
            d2, s2 = np.empty((idx.size, 2)), np.empty(idx.size)
            self.router.directions(st.position[idx], self.wgoal[t], d2, s2)
            dirs[idx], dist[idx] = d2, s2
        return dirs, dist

    def routed_velocity_numpy(self, st) -> np.ndarray:
        """Plain numpy reference of the routed desired velocity (``sim.routing.follow.follow_kernel``)."""
        cfg = self.cfg
        ar, speed, loop = float(cfg.get("arrive_radius", 2.0)), float(cfg.get("speed", 1.4)), cfg.get("loop", True)
        out = np.zeros((st.n, 2))
        has = self.path >= 0
        if not has.any():
            return out
        dirs, dist = self._routed(st, has, ar)
        s = np.where(has, speed, 0.0)
        if not loop:  # arrive: slow down along the last metres of the route to the last waypoint
            last = has & (self.target == self.pstart[np.maximum(self.path, 0) + 1] - 1)
            s = np.where(last, speed * np.minimum(1.0, np.where(np.isfinite(dist), dist, ar) / ar), s)
        out[:, 0] = dirs[:, 0] * s
        out[:, 1] = dirs[:, 1] * s
        return out

    def routed_step(self, st, integrate: bool, dt: float) -> np.ndarray:
        """The routed desired velocities (numba, one pass; :meth:`routed_velocity_numpy` is the reference);
        ``integrate``: also the kinematic move (the goals step without boids)."""
        if st.n != self.n:
            self._assign(st)
        c = self.cfg
        if self._vd is None or self._vd.shape[0] != st.n:
            self._vd = np.empty((st.n, 2))
        return self.router.follow(st, self.path, self.target, self.pstart, self.wgoal, bool(c.get("loop", True)),
                                  float(c.get("arrive_radius", 2.0)), float(c.get("speed", 1.4)), integrate, dt,
                                  self._vd)

    def _assign(self, st):
        n, npaths = st.n, self.pstart.shape[0] - 1
        self.n = n

        if npaths == 0:
            self.path = -np.ones(n, np.int64)
            self.target = np.zeros(n, np.int64)
            return
        how = self.cfg.get("assign", "cycle")
        if how == "cycle":
            base = np.arange(n)
        elif how == "character":
            base = st.character.astype(np.int64)
        else:
            base = np.zeros(n, np.int64)
            for g, (first, count) in enumerate(getattr(st, "groups", None) or []):
                base[first:first + count] = g
        self.path = base % npaths
        self.target = np.zeros(n, np.int64)
        for k in range(npaths):  # nearest waypoint of the agent's path
            sel = np.nonzero(self.path == k)[0]
            w = self.waypoints[self.pstart[k]:self.pstart[k + 1]]
            if sel.size == 0:
                continue
            d2 = (st.position[sel, 0, None] - w[None, :, 0]) ** 2 + (st.position[sel, 2, None] - w[None, :, 1]) ** 2
            self.target[sel] = self.pstart[k] + np.argmin(d2, 1)

    def desired_velocity(self, st) -> np.ndarray:
        """Advance reached waypoints; return (n, 2) desired (vx, vz)."""
        if st.n != self.n:
            self._assign(st)
        out = np.zeros((st.n, 2))
        has = self.path >= 0
        if not has.any():
            return out
        cfg = self.cfg
        ar, speed, loop = float(cfg.get("arrive_radius", 2.0)), float(cfg.get("speed", 1.4)), cfg.get("loop", True)
        if self.router is not None:
            return self.routed_step(st, False, 0.0).copy()
        idx = np.nonzero(has)[0]
        t = self.target[idx]
        end = self.pstart[self.path[idx] + 1]
        first = self.pstart[self.path[idx]]
        dx = self.waypoints[t, 0] - st.position[idx, 0]
        dz = self.waypoints[t, 1] - st.position[idx, 2]
        reached = dx * dx + dz * dz < ar * ar
        nxt = t + 1
        nxt = np.where(nxt >= end, first if loop else end - 1, nxt)
        t = np.where(reached, nxt, t)
        self.target[idx] = t
        dx = self.waypoints[t, 0] - st.position[idx, 0]
        dz = self.waypoints[t, 1] - st.position[idx, 2]
        dist = np.hypot(dx, dz)
        s = np.full(idx.size, speed)
        if not loop:  # arrive: slow down at the last waypoint
            last = t == end - 1
            s = np.where(last, speed * np.minimum(1.0, dist / ar), s)
        ok = dist > 1e-9
        f = np.where(ok, s / np.where(ok, dist, 1.0), 0.0)
        out[idx, 0] = dx * f
        out[idx, 1] = dz * f
        return out

    def attraction(self, st) -> np.ndarray:
        """(n, 2) attractor accelerations."""
        acc = np.zeros((st.n, 2))
        for cx, cz, r, s in self.att:
            dx, dz = cx - st.position[:, 0], cz - st.position[:, 2]
            d = np.hypot(dx, dz)
            on = (d < r) & (d > 1e-9)
            f = np.where(on, s * (1.0 - d / r) / np.where(on, d, 1.0), 0.0)
            acc[:, 0] += dx * f
            acc[:, 1] += dz * f
        return acc


@njit(cache=True, parallel=True)
def _kinematic_kernel(position, velocity, heading, path, target, pstart, waypoints, ar, speed, loop, dt):
    """Kinematic goals step of every agent with a path: advance a reached waypoint, velocity = desired
    velocity (:meth:`Goals.desired_velocity`), position += v dt, heading = direction of v."""
    for i in prange(position.shape[0]):
        k = path[i]
        if k < 0:
            continue
        t = target[i]
        first, end = pstart[k], pstart[k + 1]
        dx = waypoints[t, 0] - position[i, 0]
        dz = waypoints[t, 1] - position[i, 2]
        if dx * dx + dz * dz < ar * ar:
            t = t + 1
            if t >= end:
                t = first if loop else end - 1
            target[i] = t
            dx = waypoints[t, 0] - position[i, 0]
            dz = waypoints[t, 1] - position[i, 2]
        dist = math.hypot(dx, dz)
        s = speed
        if not loop and t == end - 1:
            s = speed * min(1.0, dist / ar)
        f = s / dist if dist > 1e-9 else 0.0
        vx, vz = dx * f, dz * f
        velocity[i, 0] = vx
        velocity[i, 1] = 0.0
        velocity[i, 2] = vz
        position[i, 0] += vx * dt
        position[i, 2] += vz * dt
        if math.hypot(vx, vz) > 1e-9:
            heading[i] = math.atan2(vx, vz)


def kinematic_numpy(goals: Goals, st, dt: float) -> None:
    """Plain numpy reference of :func:`_kinematic_kernel` (the goals step without boids), and with a router of
    ``sim.routing.follow.follow_kernel``."""
    if st.n != goals.n:
        goals._assign(st)
    vd = goals.routed_velocity_numpy(st) if goals.router is not None else goals.desired_velocity(st)
    has = goals.path >= 0
    st.velocity[has, 0] = vd[has, 0]
    st.velocity[has, 1] = 0.0
    st.velocity[has, 2] = vd[has, 1]
    st.position[has, 0] += vd[has, 0] * dt
    st.position[has, 2] += vd[has, 1] * dt
    mv = has & (np.hypot(vd[:, 0], vd[:, 1]) > 1e-9)
    st.heading[mv] = np.arctan2(vd[mv, 0], vd[mv, 1])


def kinematic_step(goals: Goals, st, dt: float) -> None:
    """The goals step without boids (numba; :func:`kinematic_numpy` is its reference)."""
    if st.n != goals.n:
        goals._assign(st)
    if goals.pstart.shape[0] < 2:
        return
    if goals.router is not None:
        goals.routed_step(st, True, dt)
        return
    c = goals.cfg
    _kinematic_kernel(st.position, st.velocity, st.heading, goals.path, goals.target, goals.pstart, goals.waypoints,
                      float(c.get("arrive_radius", 2.0)), float(c.get("speed", 1.4)), bool(c.get("loop", True)),
                      float(dt))


def install(world, cfg: dict) -> None:
    """Effect ``goals``: ``world.resources["goals"]`` and step ``goals`` (before boids)."""
    goals = Goals(cfg, world.state)
    world.resources["goals"] = goals
    if "routing" in world.resources:  # effect routing: route to the waypoints (installed first in scenes)
        goals.bind_router(world.resources["routing"], world.state)
    else:
        world.resources.setdefault("routing.clients", []).append(lambda r: goals.bind_router(r, world.state))
    weight = float(cfg.get("weight", 1.0))

    def step(w, dt):
        st = w.state
        if st.n == 0:
            return
        if "boids" in w.effects:
            vd = goals.desired_velocity(st)
            from sim.boids import external_accel

            acc = external_accel(w)
            has = goals.path >= 0
            acc[:, 0] += np.where(has, weight * (vd[:, 0] - st.velocity[:, 0]) / GOALS_TAU, 0.0)
            acc[:, 2] += np.where(has, weight * (vd[:, 1] - st.velocity[:, 2]) / GOALS_TAU, 0.0)
            if goals.att.size:
                a = goals.attraction(st)
                acc[:, 0] += a[:, 0]
                acc[:, 2] += a[:, 1]
        else:
            kinematic_step(goals, st, dt)

    world.schedule.add_step("goals", step, before=("boids", "animation"))
