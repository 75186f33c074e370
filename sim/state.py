"""CrowdState: the per-agent structure of arrays shared by all systems."""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numba import njit, prange

#: arrays of at least this many values are checked by the parallel kernel (below, numpy's isfinite: a parallel
#: region's wake-up costs more than the scan)
FINITE_KERNEL_MIN = 200_000


@njit(cache=True, parallel=True)
def _non_finite(a):  # pragma: no cover - compiled
    """How many values of the 1-D array ``a`` are NaN or Inf (one pass, no temporary)."""
    bad = 0
    for i in prange(a.shape[0]):
        if not np.isfinite(a[i]):
            bad += 1
    return bad


def all_finite(a: np.ndarray) -> bool:
    """Whether every value of the float array ``a`` is finite: ``np.isfinite(a).all()`` without its (n,) bool
    temporary, in parallel for large arrays (a million agents' state: 7.5 -> ~2 ms a step)."""
    flat = np.ravel(a)
    if flat.size < FINITE_KERNEL_MIN:
        return bool(np.isfinite(flat).all())
    return _non_finite(flat) == 0


@dataclass
class CrowdState:
    """One array per attribute, agent index on the first axis; dtypes fixed.

    position : (n, 3) float64, world metres (float64: crowds far from the origin)
    velocity : (n, 3) float64, m/s
    heading : (n,) float64, yaw in radians about +Y; 0 faces +Z
    scale : (n,) float32, uniform scale of the character
    character : (n,) int32, index into the engine's character list
    clip : (n,) int16, clip index within that character
    anim_time : (n,) float64, seconds into the clip (wrapped by the animation system)
    anim_rate : (n,) float32, playback rate multiplier (1 = authored speed)

    Agents that leave and enter (``sim.population``): the arrays hold only the agents alive, so ``n`` may
    change between steps, and :attr:`ids` names each agent for good (its index at the start; entered agents
    get fresh ids, never reused). A state whose count never changed stores no ids (they are ``arange(n)``).
    """

    position: np.ndarray
    velocity: np.ndarray
    heading: np.ndarray
    scale: np.ndarray
    character: np.ndarray
    clip: np.ndarray
    anim_time: np.ndarray
    anim_rate: np.ndarray

    def __post_init__(self):
        self._ids = None  # (n,) int64 stable agent ids once the count changed (sim.population), else None
        self._next_id = None  # the next entered agent's id once the count changed, else None (= n)

    @property
    def ids(self) -> np.ndarray:
        """(n,) int64 stable agent ids: 0 .. n-1 until agents leave or enter (``sim.population``)."""
        return np.arange(self.n, dtype=np.int64) if self._ids is None else self._ids

    @property
    def next_id(self) -> int:
        """The id the next entered agent gets (one more than the largest id ever given)."""
        return self.n if self._next_id is None else int(self._next_id)

    @classmethod
    def empty(cls, n: int) -> "CrowdState":
        return cls(
            position=np.zeros((n, 3), np.float64),
            velocity=np.zeros((n, 3), np.float64),
            heading=np.zeros(n, np.float64),
            scale=np.ones(n, np.float32),
            character=np.zeros(n, np.int32),
            clip=np.zeros(n, np.int16),
            anim_time=np.zeros(n, np.float64),
            anim_rate=np.ones(n, np.float32),
        )

    @property
    def n(self) -> int:
        return int(self.position.shape[0])

    def arrays(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays().values())

    def digest(self) -> str:
        """sha256 over all arrays' bytes (determinism checks)."""
        import hashlib

        h = hashlib.sha256()
        for name, a in self.arrays().items():
            h.update(name.encode())
            h.update(np.ascontiguousarray(a).tobytes())
        if self._ids is not None:  # agents left or entered: who is where is part of the state
            h.update(b"ids")
            h.update(np.ascontiguousarray(self._ids).tobytes())
        return h.hexdigest()

    def check_finite(self) -> None:
        """Raise FloatingPointError naming the first array holding NaN/Inf."""
        for name, a in self.arrays().items():
            if a.dtype.kind == "f" and not all_finite(a):
                raise FloatingPointError(f"CrowdState.{name} holds NaN or Inf")
