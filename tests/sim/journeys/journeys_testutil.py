"""Helpers of the journeys tests: worlds built from scene text (no renderer), stepping with checks."""
from __future__ import annotations

from pathlib import Path

import numpy as np

HEADER = """\
name = "j"
seed = {seed}
dt = {dt}
frames = 10

[[characters]]
name = "p"
generator = "humanoid"
triangles = 600
radius = 0.25

[[effects]]
name = "animation"
"""


def world_from_text(text: str, seed: int = 1, dt: float = 0.1, path: str = "scene.toml"):
    """(scene, world) of ``HEADER + text`` (validated by crowd.scene, built by crowd.engine.plan)."""
    import tomllib

    from crowd.engine import plan
    from crowd.population import check_journeys
    from crowd.scene import parse_scene
    from sim.world import World

    doc = tomllib.loads(HEADER.format(seed=seed, dt=dt) + text)
    sc = parse_scene(doc, Path(path))
    p = plan(sc)
    w = World(state=p.state, characters=p.characters, seed=sc.seed)
    w.resources["character_radius"] = [c.radius for c in sc.characters]
    for e in sc.effects:
        w.install(e.name, e.params)
    check_journeys(sc, w)
    return sc, w


def run(w, frames: int, dt: float, each=None):
    """Step ``frames`` frames; ``each(w, counts)`` after every frame with the journeys' frame counts."""
    j = w.resources["journeys"]
    for _ in range(frames):
        w.step(dt)
        w.state.check_finite()
        c = j.take_frame_counts()
        if each is not None:
            each(w, c)


def placement(rows=2, cols=2, origin=(-5.0, 0.0), spacing=1.0, clip="walk") -> str:
    return f"""
[[placement]]
kind = "grid"
character = "p"
clip = "{clip}"
rows = {rows}
cols = {cols}
spacing = [{spacing}, {spacing}]
origin = [{origin[0]}, 0.0, {origin[1]}]
"""


def min_gap(w) -> float:
    """Smallest centre distance minus the two body radii over all pairs (inf for < 2 agents)."""
    p = w.state.position[:, [0, 2]]
    if p.shape[0] < 2:
        return np.inf
    d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
    np.fill_diagonal(d, np.inf)
    return float(d.min()) - 0.5
