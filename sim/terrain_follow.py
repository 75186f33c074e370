"""Effect ``terrain_follow``: agents stand on the terrain.

Sets ``position.y = terrain.height(x, z) + offset`` for every agent after
everything that moves agents on the XZ plane (boids, goals, obstacles) and
nothing else (heading and velocity stay planar). The terrain is
``world.resources["terrain"]`` (a :class:`sim.terrain.Terrain`), which the
scene loader builds from the ``[terrain]`` table before installing effects.
"""
from __future__ import annotations

from sim.params import Param, ParamError

PARAMS: dict[str, Param] = {
    "offset": Param("float", 0.0, min=-100.0, max=100.0, doc="height of the agents' origin above ground, metres"),
}


def install(world, cfg: dict) -> None:
    """Add step ``terrain_follow`` (after boids, goals, obstacles.project; before animation)."""
    if world.resources.get("terrain") is None:
        raise ParamError("effects.terrain_follow", "needs a [terrain] table in the scene")
    offset = float(cfg.get("offset", 0.0))

    def step(w, dt):
        st = w.state
        if st.n:
            st.position[:, 1] = w.resources["terrain"].height(st.position[:, 0], st.position[:, 2]) + offset

    world.schedule.add_step("terrain_follow", step, after=("boids", "goals", "obstacles.project"),
                            before=("animation",))
