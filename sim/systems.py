"""Registry of systems (effects) and the fixed-step schedule that runs them.

After Bevy's plugins: each effect is a module exposing

    PARAMS : dict[str, sim.params.Param]    # its scene-file parameters
    def install(world, cfg) -> None         # adds its steps to world.schedule

Effect modules are imported lazily by name, only when a scene lists them, so an
unlisted effect is never imported, compiled or stepped.
"""
from __future__ import annotations

import importlib
import time
from dataclasses import dataclass, field
from typing import Callable

# effect name -> module path. Order here is irrelevant; the schedule orders steps.
EFFECTS: dict[str, str] = {
    "animation": "sim.animation",
    "boids": "sim.boids",
    "obstacles": "sim.obstacles",
    "goals": "sim.goals",
    "terrain_follow": "sim.terrain_follow",
    "instancing": "sim.instancing",
    "avoidance": "sim.avoidance.effect",
    "journeys": "sim.journeys.effect",
    "routing": "sim.routing.effect",
}


class UnknownEffect(KeyError):
    pass


def effect_module(name: str):
    """Import and return the module of effect ``name`` (lazily)."""
    try:
        path = EFFECTS[name]
    except KeyError:
        raise UnknownEffect(name) from None
    return importlib.import_module(path)


@dataclass
class Step:
    name: str
    fn: Callable  # fn(world, dt) -> None
    after: tuple = ()
    before: tuple = ()


@dataclass
class Schedule:
    """Ordered steps run once per fixed dt. Steps are ordered by their
    ``after``/``before`` constraints, ties by insertion order (deterministic)."""

    steps: list = field(default_factory=list)
    _order: list | None = None

    def add_step(self, name: str, fn: Callable, *, after=(), before=()) -> None:
        if any(s.name == name for s in self.steps):
            raise ValueError(f"step {name!r} is already in the schedule")
        as_tuple = lambda x: (x,) if isinstance(x, str) else tuple(x)
        self.steps.append(Step(name, fn, as_tuple(after), as_tuple(before)))
        self._order = None

    def has(self, name: str) -> bool:
        return any(s.name == name for s in self.steps)

    def order(self) -> list:
        if self._order is None:
            names = [s.name for s in self.steps]
            deps = {s.name: {a for a in s.after if a in names} for s in self.steps}
            for s in self.steps:
                for b in s.before:
                    if b in deps:
                        deps[b].add(s.name)
            done, out = set(), []
            while len(out) < len(self.steps):
                progressed = False
                for s in self.steps:
                    if s.name not in done and deps[s.name] <= done:
                        out.append(s)
                        done.add(s.name)
                        progressed = True
                        break
                if not progressed:
                    raise ValueError("cyclic step ordering: " + ", ".join(n for n in names if n not in done))
            self._order = out
        return self._order

    def run(self, world, dt: float, timings: dict | None = None) -> None:
        """Run every step once; wall seconds per step are added to ``timings``."""
        for s in self.order():
            t0 = time.perf_counter()
            s.fn(world, dt)
            if timings is not None:
                timings[s.name] = timings.get(s.name, 0.0) + time.perf_counter() - t0
