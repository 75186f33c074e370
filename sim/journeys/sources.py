"""Sources: agents entering at a rate through a spawn area (a polygon or a line).

Arrivals: ``process = "uniform"`` puts arrival k at ``start + k / rate`` (so the count before time t is
``ceil((t - start) rate)``); an arrival in a step's interval [t0, t0 + dt) enters at its end; ``"poisson"`` draws exponential gaps of mean ``1 / rate`` from the source's
own generator (scene seed, source index), so a run is deterministic for a seed. ``stop`` ends the arrivals,
``total`` caps them, ``capacity`` caps the agents of the source alive at once.

Placement: an arrival enters only where there is room: a point drawn uniformly in the spawn area at least
the sum of the two body radii from every agent (and the radius from every obstacle); up to
:data:`SPAWN_TRIES` points per arrival and step. An arrival that finds no room (or is over ``capacity``)
waits and tries again the next step, first come first placed, so the entered count follows the rate as soon
as there is room again (``backlog`` in the run's summary says how many waited at the end).
"""
from __future__ import annotations

import math

import numpy as np

from sim.journeys.geometry import sample_polygon

#: candidate points drawn per waiting arrival and step
SPAWN_TRIES = 24
#: extra gap kept between a new agent and its neighbours, metres
SPAWN_GAP = 1e-3
#: salt of the sources' random streams (the scene seed is the root)
SOURCE_SALT = 0x50C


class Source:
    """Arrival process and spawn area of one ``[[sources]]`` table (module docstring)."""

    def __init__(self, cfg: dict, index: int, seed: int):
        self.cfg = cfg
        self.name = cfg["name"]
        self.index = index
        self.rng = np.random.default_rng([int(seed), SOURCE_SALT, int(index)])
        self.rate = float(cfg["rate"])
        self.poisson = cfg.get("process", "uniform") == "poisson"
        self.start = float(cfg.get("start", 0.0))
        self.stop = cfg.get("stop")
        self.total = cfg.get("total")
        self.capacity = cfg.get("capacity")
        self.polygon = None if cfg.get("polygon") is None else np.asarray(cfg["polygon"], np.float64).reshape(-1, 2)
        self.line = None if cfg.get("line") is None else np.asarray(cfg["line"], np.float64).reshape(2, 2)
        self.arrived = 0  # arrivals so far (placed or waiting)
        self.entered = 0  # placed
        self.next_t = self.start + (self._gap() if self.poisson else 0.0)

    def _gap(self) -> float:
        return float(self.rng.exponential(1.0 / self.rate))

    @property
    def waiting(self) -> int:
        """Arrivals not yet placed."""
        return self.arrived - self.entered

    def arrive(self, t: float) -> int:
        """Count the arrivals before time ``t`` (a step from t0 to t takes those in [t0, t), placed at t: every
        agent enters between 0 and one step late, uniformly so); returns how many are waiting to be placed."""
        while self.next_t < t - 1e-9 and (self.stop is None or self.next_t <= float(self.stop) + 1e-12) \
                and (self.total is None or self.arrived < int(self.total)):
            self.arrived += 1
            k = self.arrived if not self.poisson else None
            self.next_t = self.start + k / self.rate if k is not None else self.next_t + self._gap()
        return self.waiting

    def candidates(self, k: int) -> np.ndarray:
        """(k, 2) points drawn uniformly in the spawn area."""
        if self.polygon is not None:
            return sample_polygon(self.polygon, self.rng, k)
        a, b = self.line
        return a + self.rng.random(k)[:, None] * (b - a)

    def place(self, want: int, near_xz: np.ndarray, near_r: np.ndarray, r_new: float, clear=None) -> np.ndarray:
        """Up to ``want`` positions (m, 2) with room: at least ``r_new + r_j`` from the agents ``near_xz``
        (radii ``near_r``) and from the ones placed before; ``clear(xz) -> (k,) bool`` says where a body of
        radius ``r_new`` is clear of obstacles (None: everywhere). The agents are looked up in a k-d tree
        (``scipy.spatial.cKDTree``), so a crowded spawn area costs O(log n) per candidate."""
        from scipy.spatial import cKDTree

        xz, rr = np.asarray(near_xz, np.float64).reshape(-1, 2), np.asarray(near_r, np.float64).reshape(-1)
        tree = cKDTree(xz) if xz.shape[0] else None
        reach = r_new + (float(rr.max()) if rr.size else 0.0) + SPAWN_GAP
        out = []
        for _ in range(want):
            c = self.candidates(SPAWN_TRIES)
            if c.shape[0] == 0:
                break
            ok = np.ones(c.shape[0], bool) if clear is None else np.asarray(clear(c), bool)
            if tree is not None:
                for t, hits in enumerate(tree.query_ball_point(c, reach)):
                    if ok[t] and hits:
                        h = np.asarray(hits)
                        d2 = (xz[h, 0] - c[t, 0]) ** 2 + (xz[h, 1] - c[t, 1]) ** 2
                        ok[t] = bool(np.all(d2 >= (rr[h] + r_new + SPAWN_GAP) ** 2))
            for p in out:  # the ones placed in this call
                ok &= (c[:, 0] - p[0]) ** 2 + (c[:, 1] - p[1]) ** 2 >= (2.0 * r_new + SPAWN_GAP) ** 2
            hit = np.flatnonzero(ok)
            if hit.size == 0:
                break  # no room now: this arrival and the ones behind it wait for the next step
            out.append(c[hit[0]])
        return np.asarray(out, np.float64).reshape(-1, 2)

    def bounds(self, margin: float) -> tuple:
        """(lo (2,), hi (2,)) of the spawn area grown by ``margin``."""
        pts = self.polygon if self.polygon is not None else self.line
        return pts.min(0) - margin, pts.max(0) + margin

    def expected(self, t: float) -> float:
        """Arrivals the rate promises before time ``t`` (``total`` not applied): for uniform arrivals the count
        of ``start + k / rate`` before ``t`` and not after ``stop``, for Poisson ones rate x open time."""
        if t <= self.start:
            return 0.0
        if self.poisson:
            return ((min(t, float(self.stop)) if self.stop is not None else t) - self.start) * self.rate
        n = math.ceil((t - self.start) * self.rate - 1e-9)
        if self.stop is not None:
            n = min(n, math.floor((float(self.stop) - self.start) * self.rate + 1e-9) + 1)
        return float(n)
