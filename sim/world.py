"""World: everything the systems step — state, characters, schedule, resources."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.state import CrowdState
from sim.systems import Schedule, effect_module


@dataclass
class World:
    """Simulation world.

    state : CrowdState
    characters : list of sim.character.Character (index = CrowdState.character)
    schedule : Schedule of installed steps
    resources : dict of named shared objects installed by effects
        (e.g. "terrain", "instancing", "boids.grid"). Other layers read them
        (the LOD layer reads "instancing" to build super-hierarchies).
    rng : numpy Generator seeded from the scene seed
    time : float, simulated seconds
    effects : list of installed effect names
    agents_changed : (n,) int64 or None: agents left or entered since the engine last looked
        (``sim.population``: each agent's index before, -1 = entered); None = no change
    """

    state: CrowdState
    characters: list
    seed: int = 0
    schedule: Schedule = field(default_factory=Schedule)
    resources: dict = field(default_factory=dict)
    time: float = 0.0
    frame: int = 0
    effects: list = field(default_factory=list)
    rng: np.random.Generator | None = None
    agents_changed: np.ndarray | None = None

    def __post_init__(self):
        if self.rng is None:
            self.rng = np.random.default_rng(self.seed)

    def install(self, name: str, cfg: dict) -> None:
        """Install effect ``name`` with validated ``cfg``; a duplicate is an error."""
        if name in self.effects:
            raise ValueError(f"effect {name!r} is listed twice")
        effect_module(name).install(self, cfg)
        self.effects.append(name)

    def step(self, dt: float, substeps: int = 1, timings: dict | None = None) -> None:
        h = dt / substeps
        for _ in range(substeps):
            self.schedule.run(self, h, timings)
            self.time += h
        self.frame += 1
