"""Trajectory output (``[output] trajectories = true``): every agent's position after every frame, as text
that PedPy reads directly (``pedpy.load_trajectory_from_txt``, the PedestrianDynamicsData-archive format).

File ``trajectories.txt`` in the run's output directory (written into the run's temporary directory and renamed
into place with the run's other outputs, :func:`crowd.output.atomic_dir`)::

    # crowd-sandbox trajectories: scene NAME, N agents, dt S s x K substep(s)
    # framerate: 30.0
    # axes: PedPy x = sandbox x, PedPy y = sandbox z (floor), PedPy z = sandbox y (height); Y-up sandbox
    # id frame x/m y/m z/m
    0 0 1.2500 -3.0000 0.0000
    ...

One line per agent alive and frame: agent id (``CrowdState.ids``: its index at the start; agents that enter
during the run -- sources -- get fresh ids, agents that left -- exits -- have no more lines), frame (0 = the state after the first
frame's step; one line per agent per *frame*, not per sub-step), then the position in metres. The sandbox is Y-up
with the floor in (x, z); PedPy works in the (x, y) plane, so the columns are written in PedPy's order: sandbox
x, sandbox z, sandbox y. ``framerate`` is 1 / dt (frames per simulated second). Positions are written with 4
decimals (0.1 mm) whatever their magnitude.

Streamed: each frame is formatted and appended as it is simulated, so a long run holds one frame in memory.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

#: file name of the trajectories in a run's output directory
TRAJECTORY_FILE = "trajectories.txt"
#: decimals written per coordinate (metres)
TRAJECTORY_DECIMALS = 4


def header(scene_name: str, n: int, dt: float, substeps: int, changing: bool = False) -> str:
    """The comment header (PedPy reads ``framerate`` and the unit from ``x/m``); ``changing``: agents leave and
    enter (the count is the one at the start)."""
    name = "".join(c if c.isprintable() else "?" for c in str(scene_name))
    count = f"{n} agents at the start (agents leave and enter)" if changing else f"{n} agents"
    return (f"# crowd-sandbox trajectories: scene {name}, {count}, dt {dt:g} s x {substeps} substep(s)\n"
            f"# framerate: {1.0 / dt!r}\n"
            "# axes: PedPy x = sandbox x, PedPy y = sandbox z (floor), PedPy z = sandbox y (height); Y-up sandbox\n"
            "# id frame x/m y/m z/m\n")


def format_frame(frame: int, position: np.ndarray, ids: np.ndarray | None = None) -> str:
    """Lines ``id frame x z y`` (PedPy's x y z) of one frame.

    Parameters
    ----------
    frame : int
    position : (n, 3) float64, sandbox (x, y, z)
    ids : (n,) int, default 0 .. n-1
    """
    n = int(position.shape[0])
    if n == 0:
        return ""
    ids = np.arange(n) if ids is None else np.asarray(ids)
    cols = np.empty((n, 5), np.float64)
    cols[:, 0] = ids
    cols[:, 1] = frame
    cols[:, 2] = position[:, 0]
    cols[:, 3] = position[:, 2]
    cols[:, 4] = position[:, 1]
    d = TRAJECTORY_DECIMALS
    # one C-level % over the whole frame: ~10x faster than np.savetxt's per-row formatting
    return (f"%d %d %.{d}f %.{d}f %.{d}f\n" * n) % tuple(cols.ravel().tolist())


class TrajectoryWriter:
    """Appends frames to ``path`` (a file in the run's temporary directory).

    Use as a context manager; :meth:`write` after every frame's step.
    """

    def __init__(self, path: str | Path, scene_name: str, n: int, dt: float, substeps: int = 1,
                 changing: bool = False):
        self.path = Path(path)
        self._f = open(self.path, "w", encoding="utf-8", newline="\n")
        self._f.write(header(scene_name, n, dt, substeps, changing))
        self.frames = 0

    def write(self, frame: int, position: np.ndarray, ids: np.ndarray | None = None) -> None:
        """Lines of one frame: ``position`` (n, 3) of the agents alive, ``ids`` their stable ids (default
        0 .. n-1)."""
        self._f.write(format_frame(frame, position, ids))
        self.frames += 1

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read_trajectories(path: str | Path) -> tuple:
    """Read a trajectories.txt back (tests, benchmarks): (frame_rate, (rows, 5) float64 id frame x y z in PedPy's
    axes)."""
    rate = None
    with open(path, encoding="utf-8") as f:
        for line in f:
            if not line.startswith("#"):
                break
            if line.startswith("# framerate:"):
                rate = float(line.split(":", 1)[1])
    data = np.loadtxt(path, comments="#", ndmin=2)
    return rate, data.reshape(-1, 5)
