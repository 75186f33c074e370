"""Effect ``journeys``: stages, journeys and sources stepped on the crowd (package docstring).

Steps of the schedule (``sim.systems``):

1. ``journeys.leave`` (first, on a frame's first sub-step): agents that reached an exit
   :data:`EXIT_LINGER_FRAMES` + 1 frames ago leave the simulation (``sim.population.apply``); until then they
   walk on through the exit at their velocity (drawn and written: PedPy needs a trajectory to go on after a
   crossing to count it).
2. ``journeys.steer`` (with ``goals``' place: after the ``*.record`` steps, before ``obstacles.steer``,
   ``boids``, ``avoidance``): the desired velocity of every agent (``sim.journeys.steer``); without boids
   the agents move kinematically at it (avoidance then corrects the move), with boids it becomes an
   acceleration ``weight (v_desired - v) / GOALS_TAU`` as ``goals`` does.
3. ``journeys.update`` (after everything that moves agents, before ``terrain_follow`` and ``animation``):
   arrivals at stages, waiting and service times, queues moving up, agents reaching exits (marked; drawn
   and written at the exit in this frame, removed before the next), and sources' arrivals entering.
"""
from __future__ import annotations

import numpy as np

from sim.config import GOALS_TAU
from sim.journeys.geometry import Shapes, reached_exit
from sim.journeys.sources import Source
from sim.journeys.stages import (EXIT, QUEUE, WAIT, WAYPOINT, build_journeys, build_stages, choose, sample_time,
                                 uniforms)
from sim.journeys.steer import (HOLD, IDLE, LEAVING, PENDING, WALK, StraightRouter, desired_kernel, move_kernel,
                                nearest_points)
from sim.params import Param

PARAMS: dict[str, Param] = {
    "speed": Param("float", 1.34, min=0.0, max=100.0, doc="desired walking speed of journeys without their own, m/s"),
    "slot_radius": Param("float", 0.25, min=1e-3, max=10.0,
                         doc="a waiting slot or queue place is reached within this distance, metres"),
    "slow_radius": Param("float", 1.0, min=1e-3, max=100.0,
                         doc="agents slow down linearly within this distance of where they stop, metres"),
    "approach": Param("float", 1.0, min=1e-3, max=100.0,
                      doc="within this distance of the target agents walk straight at it (through a door), "
                          "farther they follow the router, metres"),
    "body_radius": Param("float", 0.0, min=0.0, max=10.0,
                         doc="body radius kept from door jambs and between waiting agents, metres; 0 = the "
                             "largest character radius ([[characters]] radius, else footprint)"),
    "weight": Param("float", 1.0, min=0.0, max=100.0, doc="weight of the steering acceleration (with boids)"),
}

# salts of the seeded draws
_CHOICE, _WAIT_TIME = 0x0C, 0x7E

# per-agent arrays: name -> (dtype, fill of an entered agent)
_AGENT_ARRAYS = {"journey": (np.int32, -1), "step": (np.int32, 0), "stage": (np.int32, -1),
                 "phase": (np.int8, IDLE), "slot": (np.int32, -1), "ticket": (np.int64, -1),
                 "release": (np.float64, np.inf), "transitions": (np.int32, 0), "tshape": (np.int64, -1),
                 "stop_at": (np.float64, -1.0), "speed": (np.float64, 0.0), "source": (np.int32, -1),
                 "leave_frame": (np.int64, -1), "goal": (np.int64, -1), "near": (np.int8, 0)}
#: frames an agent stays after reaching an exit (walking on through it): PedPy sees a move cross a line only
#: when the trajectory goes on after it (its adaptive border window is 0 at a trajectory's last frame)
EXIT_LINGER_FRAMES = 1


class Journeys:
    """State of the installed effect (``world.resources["journeys"]``): the stage and journey tables,
    the per-agent progress (``_AGENT_ARRAYS``), the sources and the counts of who entered and left."""

    def __init__(self, cfg: dict, world):
        self.cfg = {k: p.default for k, p in PARAMS.items()}
        self.cfg.update(cfg)
        self.seed = int(world.seed)
        self.body_radius = self._body_radius(world)
        self.shapes = Shapes()
        self.stages = build_stages(cfg.get("stages", []), self.shapes, self.body_radius)
        self.journeys = build_journeys(cfg.get("journeys", []), float(self.cfg["speed"]))
        self.sources = [Source(_resolve_clip(s, i, world.characters), i, world.seed)
                        for i, s in enumerate(cfg.get("sources", []))]
        self.shape_arrays = self.shapes.arrays()
        self.router = None  # the routing effect's router, or the straight one (resolved at the first step)
        if world.resources.get("routing") is not None:  # installed first: its goals (fields) are built now
            self.use_router(world.resources["routing"])
        self.kind = np.array([s.kind for s in self.stages], np.int64)
        self.point = np.array([s.point if s.point is not None else (np.nan, np.nan) for s in self.stages],
                              np.float64).reshape(-1, 2)
        self.radius = np.array([s.radius for s in self.stages], np.float64)
        self.exit_polygon = np.array([s.shape if s.kind == EXIT and s.polygon is not None else -1
                                      for s in self.stages], np.int64)
        self.exit_line = np.array([s.line.ravel() if s.kind == EXIT and s.line is not None else (np.nan,) * 4
                                   for s in self.stages], np.float64).reshape(-1, 4)
        self.next_ticket = 0
        self._leave_frame = -1
        self._prev = np.zeros((0, 2))
        self.exited_by_stage = np.zeros(len(self.stages), np.int64)
        self.entered_by_source = np.zeros(len(self.sources), np.int64)
        self.frame_entered = self.frame_exited = self.frame_left = 0
        n = world.state.n
        for name, (dt, fill) in _AGENT_ARRAYS.items():
            setattr(self, name, np.full(n, fill, dt))
        groups = getattr(world.state, "groups", None) or [(0, n)]
        for j, jr in enumerate(self.journeys):
            idx = np.concatenate([np.arange(first, first + count) for p, (first, count) in enumerate(groups)
                                  if p in jr.placements] or [np.zeros(0, np.int64)]).astype(np.int64)
            self.journey[idx] = j
            self.speed[idx] = jr.speed
            self._enter_entry(world.state, idx, 0.0)

    def _body_radius(self, world) -> float:
        if float(self.cfg["body_radius"]) > 0:
            return float(self.cfg["body_radius"])
        from sim.avoidance.effect import character_radii

        table = character_radii(world)
        return float(table.max()) if table.size else 0.25

    def use_router(self, router) -> None:
        """Steer with ``router`` (module ``sim.journeys.steer``): the stages' shapes become its goals (one per
        stage; an agent bound for a slot is routed to its stage's ``slot_routes`` shape)."""
        self.router = router
        self.route_of = np.arange(len(self.shapes), dtype=np.int64)  # target shape -> the shape routed to
        if not isinstance(router, StraightRouter):  # straight lines cost nothing per goal: straight at the slot
            for stg in self.stages:
                self.route_of[stg.slot_shapes] = stg.slot_routes
        self.goal_of_shape = np.full(len(self.shapes), -1, np.int64)
        for k in np.unique(self.route_of):
            self.goal_of_shape[k] = router.goal(self.router_shape(int(k)))

    def goals_of(self, tshape: np.ndarray) -> np.ndarray:
        """The router's goal of every agent's target shape (-1: none)."""
        return np.where(tshape >= 0, self.goal_of_shape[self.route_of[np.maximum(tshape, 0)]], -1)

    def router_shape(self, k: int) -> tuple:
        """Shape ``k`` as the router takes it: ("point", (x, z)), ("polygon", [(x, z), ...]), ("line", (a, b))."""
        kind, pts = self.shapes.shape(k)
        pts = [tuple(map(float, p)) for p in pts]
        return (kind, pts[0]) if kind == "point" else (kind, pts)

    # -- population -----------------------------------------------------------------------------------------------
    def remap_agents(self, src: np.ndarray, state) -> None:
        from sim.population import remap_rows

        for name, (_, fill) in _AGENT_ARRAYS.items():
            setattr(self, name, remap_rows(getattr(self, name), src, fill))
        self._prev = np.zeros((0, 2))

    def take_frame_counts(self) -> dict:
        """{"entered": agents that entered, "exited": agents that reached an exit, "left": agents removed} since
        the last call."""
        out = {"entered": self.frame_entered, "exited": self.frame_exited, "left": self.frame_left}
        self.frame_entered = self.frame_exited = self.frame_left = 0
        return out

    def summary(self) -> dict:
        """Totals of the run so far (summary.json ``journeys``)."""
        return {"entered": int(self.entered_by_source.sum()), "exited": int(self.exited_by_stage.sum()),
                "exits": {s.name: int(self.exited_by_stage[i]) for i, s in enumerate(self.stages) if s.kind == EXIT},
                "sources": {s.name: {"entered": int(s.entered), "waiting": int(s.waiting),
                                     "rate": s.rate, "process": "poisson" if s.poisson else "uniform"}
                            for s in self.sources}}

    # -- stage transitions ----------------------------------------------------------------------------------------
    def _enter_entry(self, st, idx: np.ndarray, t: float) -> None:
        """Agents ``idx`` begin the entry ``step`` of their journey (a choice is drawn here)."""
        if idx.size == 0:
            return
        stage = np.empty(idx.size, np.int64)
        for j in np.unique(self.journey[idx]):
            sel = np.flatnonzero(self.journey[idx] == j)
            steps = self.step[idx[sel]]
            for e in np.unique(steps):
                part = sel[steps == e]
                entry = self.journeys[j].entries[int(e)]
                if entry[0].size == 1:
                    stage[part] = entry[0][0]
                else:
                    u = uniforms(self.seed, _CHOICE, st.ids[idx[part]], self.transitions[idx[part]])[:, 0]
                    stage[part] = choose(entry, u)
        self.transitions[idx] += 1
        for s in np.unique(stage):
            self._begin(st, idx[stage == s], int(s), t)

    def _begin(self, st, idx: np.ndarray, s: int, t: float) -> None:
        stg = self.stages[s]
        self.stage[idx] = s
        self.phase[idx] = WALK
        self.slot[idx] = -1
        self.release[idx] = np.inf
        self.tshape[idx] = stg.shape
        self.stop_at[idx] = -1.0
        if stg.kind == WAYPOINT:
            last = np.array([not self.journeys[j].loop and k == len(self.journeys[j].entries) - 1
                             for j, k in zip(self.journey[idx], self.step[idx])], bool)
            self.stop_at[idx[last]] = 0.0
        elif stg.kind == WAIT:
            self.phase[idx] = PENDING
            self.stop_at[idx] = stg.hold_distance
            self.ticket[idx] = self.next_ticket + np.arange(idx.size)
            self.next_ticket += idx.size
            self._claim_slots(st, s)
        elif stg.kind == QUEUE:
            self.ticket[idx] = -1  # joins at the end of the line (_queue)
            self._queue(st, s, t)

    def _advance(self, st, idx: np.ndarray, t: float) -> None:
        """Agents ``idx`` are done with their stage: on to the next entry, round again (loop), or idle."""
        if idx.size == 0:
            return
        self.step[idx] += 1
        self.slot[idx] = -1
        n_entries = np.array([len(j.entries) for j in self.journeys], np.int64)[self.journey[idx]]
        loops = np.array([j.loop for j in self.journeys], bool)[self.journey[idx]]
        end = self.step[idx] >= n_entries
        self.step[idx[end & loops]] = 0
        done = idx[end & ~loops]
        self.phase[done] = IDLE
        self.tshape[done] = -1
        self._enter_entry(st, idx[~(end & ~loops)], t)

    def _claim_slots(self, st, s: int) -> None:
        """Pending agents of waiting area ``s`` take free slots, first come first served, each the free slot
        nearest to it."""
        stg = self.stages[s]
        at = self.stage == s
        pend = np.flatnonzero(at & (self.phase == PENDING))
        if pend.size == 0:
            return
        taken = np.zeros(stg.slots.shape[0], bool)
        held = self.slot[at & (self.slot >= 0)]
        taken[held] = True
        for i in pend[np.argsort(self.ticket[pend], kind="stable")]:
            free = np.flatnonzero(~taken)
            if free.size == 0:
                break
            d2 = ((stg.slots[free] - st.position[i, [0, 2]]) ** 2).sum(1)
            k = int(free[np.argmin(d2)])
            taken[k] = True
            self.slot[i] = k
            self.phase[i] = WALK
            self.tshape[i] = stg.slot_shapes[k]
            self.stop_at[i] = 0.0

    def _queue(self, st, s: int, t: float) -> None:
        """Queue ``s``: agents walk to the end of the line and join it there (their ticket: the order they
        reached the end, nearest first within a step), so the line fills from the head without anyone walking
        through it; rank r stands at place r (past the last place, ``spacing`` apart short of it); the head is
        served once it stands at place 0."""
        stg = self.stages[s]
        m = stg.slots.shape[0]
        at = self.stage == s
        joined = np.flatnonzero(at & (self.ticket >= 0) & ((self.phase == WALK) | (self.phase == HOLD)))
        k = joined.size
        appr = np.flatnonzero(at & (self.ticket < 0) & (self.phase == WALK))
        if appr.size:  # who reached the end joins
            end = stg.slots[min(k, m - 1)]
            d = np.hypot(st.position[appr, 0] - end[0], st.position[appr, 2] - end[1]) - max(0, k - (m - 1)) * stg.spacing
            reach = max(float(self.cfg["slot_radius"]), 0.5 * stg.spacing)
            near = np.flatnonzero(d <= reach)
            if near.size:
                new = appr[near[np.argsort(d[near], kind="stable")]]
                self.ticket[new] = self.next_ticket + np.arange(new.size)
                self.next_ticket += new.size
                joined = np.flatnonzero(at & (self.ticket >= 0) & ((self.phase == WALK) | (self.phase == HOLD)))
                k = joined.size
                appr = np.setdiff1d(appr, new)
        if appr.size:  # the others walk to the end of the line
            self.slot[appr] = -1
            self.tshape[appr] = stg.slot_shapes[min(k, m - 1)]
            self.stop_at[appr] = max(0, k - (m - 1)) * stg.spacing
        if k == 0:
            return
        mem = joined[np.argsort(self.ticket[joined], kind="stable")]
        rank = np.arange(k)
        place = np.minimum(rank, m - 1)
        self.slot[mem] = place
        self.tshape[mem] = stg.slot_shapes[place]
        self.stop_at[mem] = np.maximum(rank - (m - 1), 0) * stg.spacing
        head = mem[0]
        if self.phase[head] == WALK:
            d = np.hypot(*(st.position[head, [0, 2]] - stg.slots[0]))
            if d <= float(self.cfg["slot_radius"]):
                self.phase[head] = HOLD
                u = uniforms(self.seed, _WAIT_TIME, st.ids[[head]], self.transitions[[head]], 2)
                self.release[head] = t + float(sample_time(stg.time, u)[0])

    def _release_time(self, st, idx: np.ndarray, stg, t: float) -> np.ndarray:
        u = uniforms(self.seed, _WAIT_TIME, st.ids[idx], self.transitions[idx], 2)
        r = t + sample_time(stg.time, u)
        if stg.release_at.size:
            k = np.searchsorted(stg.release_at, r - 1e-9)
            r = np.where(k < stg.release_at.size, stg.release_at[np.minimum(k, stg.release_at.size - 1)], np.inf)
        return r

    # -- steps --------------------------------------------------------------------------------------------------------
    def leave(self, w, dt) -> None:
        if w.frame == self._leave_frame:
            return
        self._leave_frame = w.frame
        gone = (self.phase == LEAVING) & (self.leave_frame <= w.frame)
        if gone.any():
            from sim.population import apply

            self.frame_left += int(np.count_nonzero(gone))
            apply(w, np.flatnonzero(~gone))

    def steer(self, w, dt) -> None:
        st = w.state
        if st.n == 0:
            return
        self._prev = st.position[:, [0, 2]].copy()
        if self.router is None:
            self.use_router(w.resources.get("routing") or StraightRouter())
        goal = np.where(self.phase <= PENDING, self.goals_of(self.tshape), -1)
        self.near[goal != self.goal] = 0  # a new goal: routed until near it
        self.goal = goal
        rdir = np.zeros((st.n, 2))
        rdist = np.full(st.n, np.inf)
        self.router.directions(st.position, goal, rdir, dist=rdist)
        kind, start, verts = self.shape_arrays
        vd = np.zeros((st.n, 2))
        c = self.cfg
        desired_kernel(st.position, self.phase, self.tshape, self.stop_at, self.speed, rdir, rdist, self.near, kind,
                       start, verts, float(c["approach"]), float(c["slow_radius"]), vd)
        active = self.journey >= 0
        leaving = self.phase == LEAVING
        if leaving.any():  # on through the exit
            vd[leaving] = st.velocity[leaving][:, [0, 2]]
        if "boids" in w.effects:
            from sim.boids import external_accel

            acc = external_accel(w)
            k = float(c["weight"]) / GOALS_TAU
            acc[active, 0] += k * (vd[active, 0] - st.velocity[active, 0])
            acc[active, 2] += k * (vd[active, 1] - st.velocity[active, 2])
        else:
            move_kernel(st.position, st.velocity, st.heading, active, vd, float(dt))

    def update(self, w, dt) -> None:
        st = w.state
        t = w.time + dt
        if st.n and self.journey.size == st.n:
            self._arrivals(st, t, w.frame)
        self._spawn(w, t)

    def _arrivals(self, st, t: float, frame: int) -> None:
        walk = self.phase == WALK
        kind = np.where(self.stage >= 0, self.kind[np.maximum(self.stage, 0)], -1)
        pos = st.position
        # exits: inside the polygon, or the move crossed the door
        ex = np.flatnonzero(walk & (kind == EXIT))
        if ex.size:
            hit = np.zeros(ex.size, np.bool_)
            prev = self._prev if self._prev.shape[0] == st.n else pos[:, [0, 2]]
            reached_exit(ex, self.stage, self.exit_polygon, self.exit_line, *self.shape_arrays,
                         np.ascontiguousarray(prev), pos, hit)
            gone = ex[hit]
            self.phase[gone] = LEAVING
            self.tshape[gone] = -1
            self.leave_frame[gone] = frame + 1 + EXIT_LINGER_FRAMES
            np.add.at(self.exited_by_stage, self.stage[gone], 1)
            self.frame_exited += int(gone.size)
        # releases: waiting and service times over
        rel = np.flatnonzero((self.phase == HOLD) & (self.release <= t + 1e-12))
        self._advance(st, rel, t)
        freed = {int(s) for s in self.stage[rel]} if rel.size else set()
        # waypoints reached
        kind = np.where(self.stage >= 0, self.kind[np.maximum(self.stage, 0)], -1)
        wp = np.flatnonzero((self.phase == WALK) & (kind == WAYPOINT))
        if wp.size:
            pts = self.point[self.stage[wp]]
            rad = self.radius[self.stage[wp]]
            d = np.hypot(pos[wp, 0] - pts[:, 0], pos[wp, 2] - pts[:, 1])
            if not isinstance(self.router, StraightRouter):  # the route's length: not through a thin wall
                rd = np.full(wp.size, np.inf)
                self.router.directions(pos[wp], self.goals_of(self.tshape[wp]), np.zeros((wp.size, 2)), dist=rd)
                d = np.maximum(d, rd)
            reached = d <= rad
            last = reached & (self.stop_at[wp] >= 0)
            self.phase[wp[last]] = IDLE
            self.tshape[wp[last]] = -1
            self._advance(st, wp[reached & ~last], t)
        # waiting areas: arrivals at slots, then free slots to the agents holding outside
        kind = np.where(self.stage >= 0, self.kind[np.maximum(self.stage, 0)], -1)
        r_slot = float(self.cfg["slot_radius"])
        for s, stg in enumerate(self.stages):
            if stg.kind == WAIT:
                at = np.flatnonzero((self.stage == s) & (self.phase == WALK) & (self.slot >= 0))
                if at.size:
                    d = np.hypot(*(pos[at][:, [0, 2]] - stg.slots[self.slot[at]]).T)
                    arrived = at[d <= r_slot]
                    if arrived.size:
                        self.phase[arrived] = HOLD
                        self.release[arrived] = self._release_time(st, arrived, stg, t)
                if s in freed or np.any((self.stage == s) & (self.phase == PENDING)):
                    self._claim_slots(st, s)
            elif stg.kind == QUEUE:
                self._queue(st, s, t)

    def _spawn(self, w, t: float) -> None:
        if not self.sources:
            return
        from sim.population import apply
        from sim.state import CrowdState

        for src in self.sources:
            want = src.arrive(t)
            if src.capacity is not None:
                alive = int(np.count_nonzero(self.source == src.index))
                want = min(want, max(0, int(src.capacity) - alive))
            if want <= 0:
                continue
            st = w.state
            c = src.cfg
            r_new = self._radius_of(w, np.array([c["character"]]), np.array([c["scale"]], np.float32))[0]
            lo, hi = src.bounds(2.0 * r_new + 2.0 * self.body_radius + 1.0)
            xz = st.position[:, [0, 2]]
            near = np.flatnonzero(np.all((xz >= lo) & (xz <= hi), axis=1))
            xy = src.place(want, xz[near], self._radius_of(w, st.character[near], st.scale[near]), r_new,
                           self._clearance(w, r_new, int(c["journey"])))
            k = xy.shape[0]
            if k == 0:
                continue
            new = CrowdState.empty(k)
            new.position[:, 0], new.position[:, 2] = xy[:, 0], xy[:, 1]
            new.character[:] = int(c["character"])
            new.clip[:] = int(c.get("clip_index", 0))
            new.scale[:] = np.float32(c["scale"])
            new.anim_time[:] = src.rng.random(k) * float(c.get("clip_duration", 1.0))
            n0 = st.n
            apply(w, None, new)
            idx = np.arange(n0, n0 + k)
            jr = int(c["journey"])
            self.journey[idx] = jr
            self.speed[idx] = self.journeys[jr].speed
            self.source[idx] = src.index
            self.step[idx] = 0
            self._enter_entry(w.state, idx, t)
            self._face_target(w.state, idx, c.get("heading"))
            src.entered += k
            self.entered_by_source[src.index] += k
            self.frame_entered += k

    def _face_target(self, st, idx: np.ndarray, heading) -> None:
        if heading is not None:
            st.heading[idx] = np.radians(float(heading))
            return
        qx, qz, _ = nearest_points(self.shape_arrays, self.tshape[idx], st.position[idx])
        dx, dz = qx - st.position[idx, 0], qz - st.position[idx, 2]
        ok = dx * dx + dz * dz > 1e-18
        st.heading[idx[ok]] = np.arctan2(dx[ok], dz[ok])

    def _radius_of(self, w, character, scale) -> np.ndarray:
        from sim.avoidance.effect import character_radii, radii_of

        av = w.resources.get("avoidance")
        if av is not None:
            return radii_of(av.cfg, av.table, np.asarray(character), np.asarray(scale))
        if not hasattr(self, "_table"):
            self._table = character_radii(w)
        return radii_of({}, self._table, np.asarray(character), np.asarray(scale))

    def _clearance(self, w, r_new: float, journey: int):
        """Where a new body of radius ``r_new`` may stand: clear of the obstacles and, with routing, where the
        route to its journey's first stage starts (inside the walkable area); None: anywhere."""
        tests = []
        obs = w.resources.get("obstacles")
        if obs is not None and obs.count:
            r = max(r_new, float(w.resources.get("obstacles.agent_radius", 0.0)))
            tests.append(lambda c: obs.sdf(c[:, 0], c[:, 1])[0] >= r)
        if self.router is not None and not isinstance(self.router, StraightRouter):
            first = self.stages[int(self.journeys[journey].entries[0][0][0])]
            gid = int(self.goals_of(np.array([first.shape]))[0])
            tests.append(lambda c: np.asarray(self.router.reachable(gid, c), bool))
        if not tests:
            return None
        return lambda c: np.logical_and.reduce([t(c) for t in tests])


def _resolve_clip(cfg: dict, i: int, characters) -> dict:
    """``cfg`` of source ``i`` with ``clip_index`` and ``clip_duration`` of its character's clip (ParamError
    naming ``sources[i].clip`` for a clip the character does not have)."""
    from sim.params import ParamError

    ch = characters[int(cfg["character"])]
    names = ch.clip_names()
    if not names:
        raise ParamError(f"sources[{i}].character", f"character {ch.name!r} has no animation clip")
    clip = cfg.get("clip")
    if clip is not None and clip not in names:
        raise ParamError(f"sources[{i}].clip", f"unknown clip {clip!r} of character {ch.name!r}; "
                         f"accepted: {', '.join(map(repr, names))}")
    k = names.index(clip) if clip is not None else 0
    return {**cfg, "clip_index": k, "clip_duration": float(ch.clip(k).duration)}


def install(world, cfg: dict) -> None:
    """Effect ``journeys``: ``world.resources["journeys"]`` (:class:`Journeys`) and its three steps."""
    eff = Journeys(cfg, world)
    world.resources["journeys"] = eff
    world.schedule.add_step("journeys.leave", eff.leave,
                            before=("avoidance.record", "obstacles.record", "journeys.steer", "boids"))
    world.schedule.add_step("journeys.steer", eff.steer, after=("avoidance.record", "obstacles.record"),
                            before=("obstacles.steer", "boids", "avoidance", "obstacles.project", "animation",
                                    "terrain_follow"))
    world.schedule.add_step("journeys.update", eff.update,
                            after=("journeys.steer", "boids", "avoidance", "obstacles.project", "avoidance.resolve"),
                            before=("terrain_follow", "animation"))
