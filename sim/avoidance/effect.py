"""Effect ``avoidance``: parameters, body radii, the steps of the schedule.

The step order, the models and the hard no-overlap pass are described in
:mod:`sim.avoidance` (package docstring); docs/scenes.md lists every key.

Body radius of agent ``i`` (metres): the effect's ``radius`` when > 0 (the
same for every agent, not scaled), else its character's radius times the
agent's ``CrowdState.scale``. A character's radius is the ``[[characters]]
radius`` key (the engine publishes them as ``world.resources
["character_radius"]``, a list with None where unset), else its footprint:
half the larger horizontal (x or z) extent of its rest-pose bounds (0.25 m for
the generated humanoid, whose shoulders span 0.50 m).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.config import AVOIDANCE_DEFAULT_RADIUS, AVOIDANCE_SPEED_EPS
from sim.params import Param

MODELS = ("cfsm", "orca")

PARAMS: dict[str, Param] = {
    "model": Param("str", "cfsm", choices=MODELS,
                   doc="collision-free speed model (Tordeux et al. 2016, as JuPedSim) or ORCA (van den Berg et al. "
                       "2011)"),
    "radius": Param("float", 0.0, min=0.0, max=100.0,
                    doc="body radius of every agent, metres; 0 = per character ([[characters]] radius, else "
                        "footprint) times the agent's scale"),
    "resolve_iterations": Param("int", 50, min=0, max=1000,
                                doc="passes of the hard no-overlap projection per step; 0 = off"),
    # cfsm (JuPedSim names and defaults)
    "time_gap": Param("float", 1.0, min=0.1, max=10.0, doc="cfsm: T, seconds"),
    "v0": Param("float", 0.0, min=0.0, max=10.0,
                doc="cfsm: free speed, m/s; 0 = the speed of the preferred velocity"),
    "strength_neighbor_repulsion": Param("float", 8.0, min=0.0, max=1000.0, doc="cfsm: a"),
    "range_neighbor_repulsion": Param("float", 0.1, min=1e-3, max=10.0, doc="cfsm: D, metres"),
    "strength_geometry_repulsion": Param("float", 5.0, min=0.0, max=1000.0, doc="cfsm: b"),
    "range_geometry_repulsion": Param("float", 0.02, min=1e-4, max=10.0, doc="cfsm: D_w, metres"),
    "side_bias": Param("float", 0.5, min=0.0, max=10.0,
                       doc="cfsm: counter-flow neighbours ahead also push to the right by this share of their "
                           "repulsion (breaks head-on deadlocks; 0 = JuPedSim's model)"),
    "cutoff": Param("float", 0.0, min=0.0, max=100.0,
                    doc="cfsm: neighbour range, metres; 0 = 2 r_max + max(v0 T, 14 D) (JuPedSim: 3)"),
    # orca (RVO2 names)
    "time_horizon": Param("float", 2.0, min=0.01, max=60.0, doc="orca: tau for agents, seconds"),
    "time_horizon_obstacles": Param("float", 1.0, min=0.01, max=60.0, doc="orca: tau for obstacles, seconds"),
    "neighbor_distance": Param("float", 5.0, min=0.01, max=100.0, doc="orca: neighbour range, metres"),
    "max_neighbors": Param("int", 10, min=1, max=64, doc="orca: nearest neighbours used"),
    "max_speed": Param("float", 0.0, min=0.0, max=100.0,
                       doc="orca: speed limit, m/s; 0 = the speed of the preferred velocity"),
}


def footprint_radius(character) -> float:
    """Half the larger horizontal extent of the character's rest bounds (metres)."""
    try:
        lo, hi = character.rest_bounds()
    except Exception:  # noqa: BLE001 - a character without a mesh
        return AVOIDANCE_DEFAULT_RADIUS
    r = 0.5 * float(max(hi[0] - lo[0], hi[2] - lo[2]))
    return r if math.isfinite(r) and r > 0 else AVOIDANCE_DEFAULT_RADIUS


def character_radii(world) -> np.ndarray:
    """(C,) float64 radius of every character at scale 1 (module docstring)."""
    given = list(world.resources.get("character_radius") or [])
    out = []
    for ci, ch in enumerate(world.characters):
        r = given[ci] if ci < len(given) else None
        out.append(float(r) if r is not None else footprint_radius(ch))
    return np.array(out, np.float64)


def body_radii(world, cfg: dict, table: np.ndarray | None = None) -> np.ndarray:
    """(n,) float64 body radius of every agent (module docstring)."""
    st = world.state
    table = character_radii(world) if table is None and not float(cfg.get("radius", 0.0)) > 0 else table
    return radii_of(cfg, table, st.character, st.scale)


def radii_of(cfg: dict, table: np.ndarray | None, character: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(k,) float64 body radii of agents with these ``character`` indices and ``scale``s (:func:`body_radii`)."""
    r = float(cfg.get("radius", 0.0))
    if r > 0:
        return np.full(character.shape[0], r, np.float64)
    ch = np.asarray(character).astype(np.int64)
    ok = (ch >= 0) & (ch < table.shape[0])
    base = np.where(ok, table[np.where(ok, ch, 0)] if table.size else AVOIDANCE_DEFAULT_RADIUS,
                    AVOIDANCE_DEFAULT_RADIUS)
    return base * np.asarray(scale).astype(np.float64)


@njit(cache=True, parallel=True)
def finalize_kernel(pos, vel, heading, anim_rate, base_rate, prev, vpref, v, dt):
    """position = start + v dt; velocity = v; heading turned by the angle from
    the preferred to the new velocity; anim_rate = base_rate |v| / |vpref|."""
    for i in prange(pos.shape[0]):
        vx, vz = v[i, 0], v[i, 1]
        wx, wz = vpref[i, 0], vpref[i, 1]
        pos[i, 0] = prev[i, 0] + vx * dt
        pos[i, 2] = prev[i, 2] + vz * dt
        vel[i, 0] = vx
        vel[i, 2] = vz
        sw = math.sqrt(wx * wx + wz * wz)
        base_rate[i] = anim_rate[i]
        if sw > AVOIDANCE_SPEED_EPS:
            sv = math.sqrt(vx * vx + vz * vz)
            anim_rate[i] = np.float32(anim_rate[i] * (sv / sw))
            if sv > AVOIDANCE_SPEED_EPS:
                heading[i] = _turn(heading[i], vx, vz, wx, wz)


@njit(cache=True, inline="always")
def _turn(h, vx, vz, wx, wz):
    """h turned by the angle from w to v (yaw convention atan2(x, z)), wrapped to (-pi, pi]: one atan2 of
    the cross and dot products instead of wrap(atan2(v) - atan2(w)) (the same angle, to rounding)."""
    a = h + math.atan2(vx * wz - vz * wx, vx * wx + vz * wz)
    if a > math.pi:
        a -= 2.0 * math.pi
    elif a <= -math.pi:
        a += 2.0 * math.pi
    return a


def finalize_numpy(pos, vel, heading, anim_rate, base_rate, prev, vpref, v, dt):
    """Plain numpy reference of :func:`finalize_kernel` (the heading by the difference of the two yaws)."""
    vx, vz, wx, wz = v[:, 0], v[:, 1], vpref[:, 0], vpref[:, 1]
    pos[:, 0] = prev[:, 0] + vx * dt
    pos[:, 2] = prev[:, 2] + vz * dt
    vel[:, 0] = vx
    vel[:, 2] = vz
    base_rate[:] = anim_rate
    sw, sv = np.hypot(wx, wz), np.hypot(vx, vz)
    on = sw > AVOIDANCE_SPEED_EPS
    anim_rate[on] = (anim_rate[on] * (sv[on] / sw[on])).astype(np.float32)
    turn = on & (sv > AVOIDANCE_SPEED_EPS)
    d = np.arctan2(vx[turn], vz[turn]) - np.arctan2(wx[turn], wz[turn])
    h = heading[turn] + np.arctan2(np.sin(d), np.cos(d))
    heading[turn] = np.arctan2(np.sin(h), np.cos(h))


class Avoidance:
    """State of the installed effect (``world.resources["avoidance"]``).

    prev : (n, 3) float64 positions at the start of the step
    vstart : (n, 2) float64 velocities at the start of the step (orca)
    radius : (n,) float64 body radii; base_rate : (n,) float32 animation rate before the speed scaling
    last : dict of the last step's figures (passes and remaining overlap of the resolve)
    """

    def __init__(self, cfg: dict, world):
        self.cfg = {k: p.default for k, p in PARAMS.items()}
        self.cfg.update(cfg)
        self.model = self.cfg["model"]
        self.table = character_radii(world)
        self.n = -1
        self.prev = self.vstart = self.radius = self.base_rate = None
        self.grid = self.scratch = self.near = None
        self.near_d = 0.0
        self.last = {"resolve_passes": 0, "resolve_overlap": 0.0, "frozen": 0}

    def sync(self, world) -> None:
        st = world.state
        if st.n != self.n:
            self.n = st.n
            self.radius = body_radii(world, self.cfg, self.table)
            self.prev = np.empty((st.n, 3), np.float64)
            self.vstart = np.empty((st.n, 2), np.float64)
            self.base_rate = None
            self.grid = self.scratch = None

    def remap_agents(self, src: np.ndarray, state) -> None:
        """Agents left or entered (``sim.population``): keep the survivors' radii and animation base rates;
        entered agents get theirs (radius from character and scale, base rate = their current rate)."""
        from sim.population import remap_rows

        new = np.asarray(src) < 0
        if self.radius is not None:
            r = remap_rows(self.radius, src)
            r[new] = radii_of(self.cfg, self.table, state.character[new], state.scale[new])
            self.radius = r
        if self.base_rate is not None:
            b = remap_rows(self.base_rate, src)
            b[new] = state.anim_rate[new]
            self.base_rate = b
        self.prev = remap_rows(self.prev, src)
        self.vstart = remap_rows(self.vstart, src)
        self.n = state.n if self.radius is not None else -1
        self.near = None
        self.grid = self.scratch = None

    def record(self, world, dt) -> None:
        st = world.state
        self.sync(world)
        np.copyto(self.prev, st.position)
        if self.model == "orca":
            self.vstart[:, 0] = st.velocity[:, 0]
            self.vstart[:, 1] = st.velocity[:, 2]
        if self.base_rate is not None and self.base_rate.shape == st.anim_rate.shape:
            st.anim_rate[:] = self.base_rate  # undo last step's speed scaling before the movers run
        self.recorded = True

    def velocities(self, world, vpref):
        c = self.cfg
        st = world.state
        obs = world.resources.get("obstacles")
        from sim.avoidance.cfsm import max_speed

        # the fastest any agent may move in this step: pairs farther apart than r_i + r_j + 2 vmax dt
        # at the start cannot overlap after it (the resolve then checks only flagged agents)
        vmax = max(float(max_speed(vpref)), c["v0"] if self.model == "cfsm" else c["max_speed"])
        self.near_d = 2.0 * vmax * self._dt * (1.0 + 1e-9) + 1e-12
        if self.near is None or self.near.shape != (st.n,):
            self.near = np.empty(st.n, np.uint8)
        if self.model == "cfsm":
            from sim.avoidance.cfsm import cfsm_velocities

            v, self.grid, self.scratch = cfsm_velocities(
                self.prev, self.radius, vpref, st.heading, c["strength_neighbor_repulsion"],
                c["range_neighbor_repulsion"], c["strength_geometry_repulsion"], c["range_geometry_repulsion"],
                c["time_gap"], c["cutoff"], c["v0"], c["side_bias"], obs, self.grid, self.scratch, self.near,
                self.near_d)
            return v
        from sim.avoidance.orca import orca_velocities

        v, self.grid, self.scratch = orca_velocities(
            self.prev, self.radius, self.vstart, vpref, c["time_horizon"], c["time_horizon_obstacles"],
            c["neighbor_distance"], c["max_neighbors"], c["max_speed"], self._dt, obs, self.grid, self.scratch,
            self.near, self.near_d, salt=world.frame)
        return v

    def step(self, world, dt) -> None:
        st = world.state
        if st.n == 0 or not getattr(self, "recorded", False) or self.prev.shape[0] != st.n:
            return
        self.recorded = False
        self._dt = float(dt)
        vpref = np.empty((st.n, 2), np.float64)
        vpref[:, 0] = (st.position[:, 0] - self.prev[:, 0]) / dt
        vpref[:, 1] = (st.position[:, 2] - self.prev[:, 2]) / dt
        v = self.velocities(world, vpref)
        if self.base_rate is None or self.base_rate.shape != st.anim_rate.shape:
            self.base_rate = np.empty_like(st.anim_rate)
        finalize_kernel(st.position, st.velocity, st.heading, st.anim_rate, self.base_rate, self.prev, vpref, v,
                        float(dt))

    def resolve(self, world, dt) -> None:
        st = world.state
        it = int(self.cfg["resolve_iterations"])
        if st.n < 2 or it == 0 or self.radius is None or self.radius.shape[0] != st.n:
            return
        from sim.avoidance.resolve import resolve

        obs = world.resources.get("obstacles")
        clearance = np.maximum(self.radius, float(world.resources.get("obstacles.agent_radius", 0.0)))
        frozen = np.zeros(st.n, bool)
        passes, worst = resolve(st.position, self.radius, clearance, obs, it, grid=self.grid, prev=self.prev,
                                frozen=frozen, near=self.near, near_d=self.near_d)
        if frozen.any():
            st.velocity[frozen, 0] = 0.0
            st.velocity[frozen, 2] = 0.0
        self.last = {"resolve_passes": passes, "resolve_overlap": worst, "frozen": int(frozen.sum())}


def install(world, cfg: dict) -> None:
    """Effect ``avoidance``: ``world.resources["avoidance"]`` (:class:`Avoidance`) and the steps
    ``avoidance.record`` (before goals, obstacles.steer, boids), ``avoidance`` (after goals and boids, before
    obstacles.project) and ``avoidance.resolve`` (after obstacles.project, before terrain_follow and animation)."""
    eff = Avoidance(cfg, world)
    world.resources["avoidance"] = eff
    world.schedule.add_step("avoidance.record", eff.record, before=("goals", "obstacles.steer", "boids"))
    world.schedule.add_step("avoidance", eff.step, after=("goals", "boids", "avoidance.record"),
                            before=("obstacles.project", "terrain_follow", "animation"))
    world.schedule.add_step("avoidance.resolve", eff.resolve, after=("avoidance", "obstacles.project"),
                            before=("terrain_follow", "animation"))
