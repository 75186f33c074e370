"""Uniform neighbour grid on the XZ plane, built by counting sort.

Wand & Straßer 2002, §5.2: "A spatial grid data structure is used to
efficiently retrieve the local neighbors of each object". Cells are squares of
side ``cell`` (the interaction radius), so every neighbour within ``cell`` of an
agent lies in the 3 x 3 cells around its own.

Cell coordinates are taken relative to the flock's bounding-box minimum
(``ix = floor((x - xmin) / cell)``), so a flock 1e6 m from the origin gets the
same cells as the same flock at the origin. When the bounding box would need
far more cells than agents (a few agents very far apart), cell keys are hashed
into a table of ``2^k >= 2 n`` buckets; candidates from colliding cells are
rejected by the distance test, and a bucket reached from two of the 3 x 3 cells
is visited once.

The sort is stable: within a cell, agents appear in increasing index order, so
every neighbour query visits candidates in a fixed order (determinism).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from sim.config import GRID_DENSE_FACTOR, GRID_HASH_X, GRID_HASH_Z, GRID_MAX_CELLS


@dataclass
class Grid:
    """A built neighbour grid.

    cell : float, cell side (metres)
    origin : (2,) float64, bounding-box minimum (x, z) the cells are relative to
    dims : (gx, gz) cells of the bounding box
    dense : bool, True when keys are ``iz * gx + ix``, False when hashed
    mask : int, hash table size - 1 (hashed mode)
    cx, cz : (n,) int32, cell coordinates of every agent
    key : (n,) int32, bucket of every agent
    start : (buckets + 1,) int32, agents of bucket b are ``order[start[b]:start[b+1]]``
    order : (n,) int32, agents sorted by bucket, stable
    """

    cell: float
    origin: np.ndarray
    dims: tuple
    dense: bool
    mask: int
    cx: np.ndarray
    cz: np.ndarray
    key: np.ndarray
    start: np.ndarray
    order: np.ndarray

    @property
    def n_buckets(self) -> int:
        return int(self.start.shape[0] - 1)

    def nbytes(self) -> int:
        return int(self.cx.nbytes + self.cz.nbytes + self.key.nbytes + self.start.nbytes + self.order.nbytes)


@njit(cache=True, parallel=True)
def _extent_kernel(position):  # pragma: no cover - compiled
    """(x min, x max, z min, z max, NaN count) of ``position`` (n, 3) in one parallel pass."""
    x0, x1, z0, z1 = np.inf, -np.inf, np.inf, -np.inf
    nan = 0
    for i in prange(position.shape[0]):
        x, z = position[i, 0], position[i, 2]
        if x != x or z != z:
            nan += 1
        x0 = min(x0, x)
        x1 = max(x1, x)
        z0 = min(z0, z)
        z1 = max(z1, z)
    return x0, x1, z0, z1, nan


#: from this many agents on, the extent is one parallel pass (:func:`_extent_kernel`) instead of four numpy
#: reductions over strided columns (a million agents: ~5 -> ~1 ms a step)
EXTENT_KERNEL_MIN = 200_000


def _extent(position: np.ndarray) -> tuple:
    """(x min, z min, x max, z max) as numpy's min and max give them (NaN when a coordinate is NaN)."""
    if position.shape[0] >= EXTENT_KERNEL_MIN and position.dtype == np.float64 and position.flags.c_contiguous:
        x0, x1, z0, z1, nan = _extent_kernel(position)
        if nan == 0:
            return float(x0), float(z0), float(x1), float(z1)
    x, z = position[:, 0], position[:, 2]
    return float(x.min()), float(z.min()), float(x.max()), float(z.max())


def layout(position: np.ndarray, cell: float, dense_factor: float = GRID_DENSE_FACTOR):
    """Bounding box, grid dims and key mode for ``position`` (n, 3) float64; dense while the
    bounding box has at most ``dense_factor`` cells per agent.

    Returns (origin (2,) float64, gx, gz, dense, mask, n_buckets).
    """
    n = position.shape[0]
    if n == 0:
        return np.zeros(2), 1, 1, True, 0, 1
    xmin, zmin, xmax, zmax = _extent(position)
    # capped so cell indices stay int32; agents beyond share the border cells
    # (still correct: the distance test decides, only the cost grows)
    gx = int(min((xmax - xmin) // cell, GRID_MAX_CELLS - 1)) + 1
    gz = int(min((zmax - zmin) // cell, GRID_MAX_CELLS - 1)) + 1
    if gx * gz <= max(dense_factor * n, 64):
        return np.array([xmin, zmin]), gx, gz, True, 0, gx * gz
    m = 1
    while m < 2 * n:
        m *= 2
    return np.array([xmin, zmin]), gx, gz, False, m - 1, m


@njit(cache=True, inline="always")
def cell_key(ix, iz, gx, dense, mask):
    """Bucket of cell (ix, iz): ``iz * gx + ix`` (dense) or a hash (int64)."""
    if dense:
        return iz * gx + ix
    return ((ix * GRID_HASH_X) ^ (iz * GRID_HASH_Z)) & mask


@njit(cache=True, inline="always")
def _cell_of(position, i, inv_cell, ox, oz, gx, gz, dense, mask, cx, cz, key):  # pragma: no cover - compiled
    fx = min(max(np.floor((position[i, 0] - ox) * inv_cell), 0.0), gx - 1.0)
    fz = min(max(np.floor((position[i, 2] - oz) * inv_cell), 0.0), gz - 1.0)
    ix = int(fx)
    iz = int(fz)
    cx[i] = ix
    cz[i] = iz
    key[i] = cell_key(np.int64(ix), np.int64(iz), np.int64(gx), dense, np.int64(mask))


@njit(cache=True, parallel=True)
def _cells_kernel(position, inv_cell, ox, oz, gx, gz, dense, mask, cx, cz, key):  # pragma: no cover - compiled
    """Every agent's cell and bucket, in parallel (each writes its own row)."""
    for i in prange(position.shape[0]):
        _cell_of(position, i, inv_cell, ox, oz, gx, gz, dense, mask, cx, cz, key)


#: from this many agents on, the cells are computed in parallel (:func:`_cells_kernel`) before the serial
#: counting sort
CELLS_KERNEL_MIN = 200_000


@njit(cache=True)
def _build(position, inv_cell, ox, oz, gx, gz, dense, mask, n_buckets, cx, cz, key, start, order, cells_done):
    n = position.shape[0]
    if not cells_done:
        for i in range(n):
            _cell_of(position, i, inv_cell, ox, oz, gx, gz, dense, mask, cx, cz, key)
    for b in range(n_buckets + 1):
        start[b] = 0
    for i in range(n):
        start[key[i] + 1] += 1
    for b in range(n_buckets):
        start[b + 1] += start[b]
    # stable scatter: reuse cx-independent cursor (start[b] advanced, then restored)
    for i in range(n):
        b = key[i]
        order[start[b]] = i
        start[b] += 1
    for b in range(n_buckets, 0, -1):
        start[b] = start[b - 1]
    start[0] = 0


def build_grid(position: np.ndarray, cell: float, out: Grid | None = None,
               dense_factor: float = GRID_DENSE_FACTOR) -> Grid:
    """Build the grid of ``position`` (n, 3) float64 with cells of side ``cell`` > 0.

    ``out`` (a previous Grid) lets its arrays be reused when sizes match; ``dense_factor``: see
    :func:`layout` (a caller whose cell is small against the spacing raises it: a dense grid's
    neighbour cells are adjacent in memory, a hashed one's are not).
    """
    if not cell > 0:
        raise ValueError(f"grid cell must be > 0, got {cell!r}")
    n = position.shape[0]
    origin, gx, gz, dense, mask, nb = layout(position, cell, dense_factor)
    if out is not None and out.cx.shape[0] == n and out.start.shape[0] == nb + 1:
        cx, cz, key, start, order = out.cx, out.cz, out.key, out.start, out.order
    else:
        cx, cz, key = np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32)
        start, order = np.empty(nb + 1, np.int32), np.empty(n, np.int32)
    done = n >= CELLS_KERNEL_MIN
    if done:
        _cells_kernel(position, 1.0 / cell, origin[0], origin[1], gx, gz, dense, mask, cx, cz, key)
    _build(position, 1.0 / cell, origin[0], origin[1], gx, gz, dense, mask, nb, cx, cz, key, start, order, done)
    return Grid(float(cell), origin, (gx, gz), dense, mask, cx, cz, key, start, order)


def build_grid_numpy(position: np.ndarray, cell: float, dense_factor: float = GRID_DENSE_FACTOR) -> Grid:
    """Plain numpy reference of :func:`build_grid` (same arrays)."""
    n = position.shape[0]
    origin, gx, gz, dense, mask, nb = layout(position, cell, dense_factor)
    cx = np.clip(np.floor((position[:, 0] - origin[0]) * (1.0 / cell)), 0, gx - 1).astype(np.int64)
    cz = np.clip(np.floor((position[:, 2] - origin[1]) * (1.0 / cell)), 0, gz - 1).astype(np.int64)
    key = keys_numpy(cx, cz, gx, dense, mask)
    order = np.argsort(key, kind="stable").astype(np.int32)
    start = np.zeros(nb + 1, np.int64)
    np.cumsum(np.bincount(key, minlength=nb), out=start[1:])
    return Grid(float(cell), origin, (gx, gz), dense, mask, cx.astype(np.int32), cz.astype(np.int32),
                key.astype(np.int32), start.astype(np.int32), order)


def keys_numpy(cx, cz, gx, dense, mask):
    """Vectorised :func:`cell_key` (int64 arrays)."""
    cx = np.asarray(cx, np.int64)
    cz = np.asarray(cz, np.int64)
    if dense:
        return cz * gx + cx
    return ((cx * GRID_HASH_X) ^ (cz * GRID_HASH_Z)) & mask
