"""Fast marching on a regular grid: the distance (travel time) field of a goal.

Sethian, *A fast marching level set method for monotonically advancing fronts* (PNAS 1996), and *Level Set
Methods and Fast Marching Methods* (1999), §8.2 (the upwind first-order update) and §8.4 (the second-order
update): the Eikonal equation ``|grad T| = s`` (slowness ``s``; ``T`` = distance for ``s = 1``) is solved by
accepting grid nodes in increasing ``T`` (a Dijkstra-like front), each new value from the upwind quadratic

    sum over the axes d of  alpha_d (T - tau_d)^2 = (s h)^2

with, per axis, the smaller accepted neighbour ``T1``: ``alpha = 1, tau = T1`` (first order), or, when the next
node on that side is accepted too with ``T2 <= T1``, ``alpha = 9/4, tau = (4 T1 - T2) / 3`` (second order,
one-sided difference ``(3 T - 4 T1 + T2) / (2 h)``). When the quadratic has no root above both ``tau`` (the front
comes along one axis only) the one-axis update ``min_d (tau_d + s h / sqrt(alpha_d))`` is taken.

Grid: ``T`` and ``flag`` are flat arrays of ``nz * nx`` nodes, node ``(i, j)`` (x index i, z index j) at
``k = j * nx + i``. ``flag``: :data:`FAR` (not reached yet), :data:`TRIAL` (in the heap), :data:`KNOWN`
(accepted; the sources are passed in as KNOWN with their values), :data:`BLOCKED` (never touched: walls, the
clearance band in the first pass). The heap is an indexed binary min-heap (decrease-key, no duplicate entries):
two int32 arrays of ``nz * nx``, so the memory of a march is 13 bytes per node besides ``T``.

:func:`march` is the numba kernel, :func:`march_numpy` its plain Python reference (``heapq`` with lazy deletion,
the same update; values agree to rounding where no two trial values tie).
"""
from __future__ import annotations

import heapq
import math

import numpy as np
from numba import njit

FAR, TRIAL, KNOWN, BLOCKED = 0, 1, 2, 3


@njit(cache=True, inline="always")
def _axis(T, flag, k, step, idx, n_axis, order):
    """(alpha, tau) of one axis at node k (``idx`` its index along the axis of ``n_axis`` nodes, ``step`` the
    flat stride): the smaller accepted neighbour, second order when the node beyond it is accepted with a value
    not above it. alpha = 0: no accepted neighbour on this axis."""
    best, side = np.inf, 0
    if idx > 0 and flag[k - step] == KNOWN and T[k - step] < best:
        best, side = T[k - step], -1
    if idx < n_axis - 1 and flag[k + step] == KNOWN and T[k + step] < best:
        best, side = T[k + step], 1
    if side == 0:
        return 0.0, 0.0
    if order == 2 and 0 <= idx + 2 * side < n_axis:
        k2 = k + 2 * side * step
        if flag[k2] == KNOWN and T[k2] <= best:
            return 2.25, (4.0 * best - T[k2]) / 3.0
    return 1.0, best


@njit(cache=True)
def _update(T, flag, nx, nz, k, sh, order):
    """The upwind value of node k from its accepted neighbours (module docstring); inf when it has none."""
    i = k % nx
    j = k // nx
    ax, tx = _axis(T, flag, k, 1, i, nx, order)
    az, tz = _axis(T, flag, k, nx, j, nz, order)
    if ax == 0.0 and az == 0.0:
        return np.inf
    if ax == 0.0:
        return tz + sh / math.sqrt(az)
    if az == 0.0:
        return tx + sh / math.sqrt(ax)
    a = ax + az
    b = ax * tx + az * tz
    c = ax * tx * tx + az * tz * tz - sh * sh
    disc = b * b - a * c
    if disc >= 0.0:
        t = (b + math.sqrt(disc)) / a
        if t >= tx and t >= tz:
            return t
    return min(tx + sh / math.sqrt(ax), tz + sh / math.sqrt(az))


@njit(cache=True, inline="always")
def _sift_up(heap, hpos, T, p):
    node = heap[p]
    v = T[node]
    while p > 0:
        q = (p - 1) >> 1
        if T[heap[q]] <= v:
            break
        heap[p] = heap[q]
        hpos[heap[p]] = p
        p = q
    heap[p] = node
    hpos[node] = p


@njit(cache=True, inline="always")
def _sift_down(heap, hpos, T, p, size):
    node = heap[p]
    v = T[node]
    while True:
        c = 2 * p + 1
        if c >= size:
            break
        if c + 1 < size and T[heap[c + 1]] < T[heap[c]]:
            c += 1
        if T[heap[c]] >= v:
            break
        heap[p] = heap[c]
        hpos[heap[p]] = p
        p = c
    heap[p] = node
    hpos[node] = p


@njit(cache=True)
def _relax(T, flag, heap, hpos, size, nx, nz, k, sh, order):
    """Update the non-accepted neighbours of the just accepted node k; returns the new heap size."""
    i = k % nx
    j = k // nx
    for d in range(4):
        if d == 0:
            if i == 0:
                continue
            m = k - 1
        elif d == 1:
            if i == nx - 1:
                continue
            m = k + 1
        elif d == 2:
            if j == 0:
                continue
            m = k - nx
        else:
            if j == nz - 1:
                continue
            m = k + nx
        f = flag[m]
        if f == KNOWN or f == BLOCKED:
            continue
        t = _update(T, flag, nx, nz, m, sh, order)
        if f == FAR:
            T[m] = t
            flag[m] = TRIAL
            heap[size] = m
            _sift_up(heap, hpos, T, size)
            size += 1
        elif t < T[m]:
            T[m] = t
            _sift_up(heap, hpos, T, hpos[m])
    return size


@njit(cache=True)
def march(T, flag, nx, nz, h, slowness, order):
    """Fast marching from the KNOWN nodes over the FAR ones (module docstring), in place.

    T : (nz * nx,) float64, values of the KNOWN nodes (others are overwritten); flag : (nz * nx,) int8.
    h : grid spacing; slowness : s of |grad T| = s; order : 1 or 2. Returns the number of nodes accepted.
    Nodes the front never reaches keep flag FAR and T = inf.
    """
    n = T.shape[0]
    heap = np.empty(n, np.int32)
    hpos = np.full(n, -1, np.int32)
    for k in range(n):
        if flag[k] == FAR or flag[k] == TRIAL:
            flag[k] = FAR
            T[k] = np.inf
    sh = slowness * h
    size = 0
    for k in range(n):
        if flag[k] == KNOWN:
            size = _relax(T, flag, heap, hpos, size, nx, nz, k, sh, order)
    accepted = 0
    while size > 0:
        k = heap[0]
        size -= 1
        if size > 0:
            heap[0] = heap[size]
            hpos[heap[0]] = 0
            _sift_down(heap, hpos, T, 0, size)
        hpos[k] = -1
        flag[k] = KNOWN
        accepted += 1
        size = _relax(T, flag, heap, hpos, size, nx, nz, k, sh, order)
    return accepted


# ----------------------------------------------------------------------------------------------------- reference
def _update_numpy(T, flag, nx, nz, k, sh, order):
    i, j = k % nx, k // nx

    def axis(step, lo_ok, hi_ok, idx, n_axis):
        cands = []
        if lo_ok and flag[k - step] == KNOWN:
            cands.append((T[k - step], -1))
        if hi_ok and flag[k + step] == KNOWN:
            cands.append((T[k + step], 1))
        if not cands:
            return 0.0, 0.0
        best, side = min(cands)
        if order == 2 and 0 <= idx + 2 * side < n_axis:
            k2 = k + 2 * side * step
            if flag[k2] == KNOWN and T[k2] <= best:
                return 2.25, (4.0 * best - T[k2]) / 3.0
        return 1.0, best

    ax, tx = axis(1, i > 0, i < nx - 1, i, nx)
    az, tz = axis(nx, j > 0, j < nz - 1, j, nz)
    one = [t + sh / math.sqrt(a) for a, t in ((ax, tx), (az, tz)) if a > 0]
    if not one:
        return math.inf
    if ax > 0 and az > 0:
        a, b = ax + az, ax * tx + az * tz
        c = ax * tx * tx + az * tz * tz - sh * sh
        disc = b * b - a * c
        if disc >= 0:
            t = (b + math.sqrt(disc)) / a
            if t >= tx and t >= tz:
                return t
    return min(one)


def march_numpy(T, flag, nx, nz, h, slowness, order) -> int:
    """Plain Python reference of :func:`march` (``heapq``, lazy deletion), in place."""
    far = (flag == FAR) | (flag == TRIAL)
    flag[far] = FAR
    T[far] = np.inf
    sh = slowness * h
    heap = []

    def relax(k):
        i, j = k % nx, k // nx
        for ok, m in ((i > 0, k - 1), (i < nx - 1, k + 1), (j > 0, k - nx), (j < nz - 1, k + nx)):
            if not ok or flag[m] in (KNOWN, BLOCKED):
                continue
            t = _update_numpy(T, flag, nx, nz, m, sh, order)
            if t < T[m]:
                T[m] = t
                flag[m] = TRIAL
                heapq.heappush(heap, (t, m))

    for k in np.nonzero(flag == KNOWN)[0]:
        relax(int(k))
    accepted = 0
    while heap:
        t, k = heapq.heappop(heap)
        if flag[k] == KNOWN or t > T[k]:
            continue
        flag[k] = KNOWN
        accepted += 1
        relax(k)
    return accepted
