"""Stratification of moving candidate samples (Wand & Straßer 2002, §3.4.2).

Given a dense candidate set whose points move linearly in time, choose for each
time interval a subset that still covers every candidate with spheres of
radius r/2 throughout the interval, using as few points as the greedy rule
allows.

Notes
-----
Wand & Straßer, *Multi-Resolution Rendering of Complex Animated Scenes*,
Eurographics 2002, §3.4.2 and Figure 5:

* Coverage: point i covers point j when ``|p_i - p_j| <= r/2``. For moving
  points that must hold at the start *and* the end of the interval; the
  distance of two linearly moving points is convex in time (one minimum, no
  interior maximum), so the two ends imply the whole interval.
* Greedy deletion in random order: a point is deleted if (a) it is covered by
  another point that is still present, and (b) it is not the only present
  point covering one of the previously deleted points. Rule (b) forbids
  cascaded deletion (Fig. 5b): at all times every deleted point keeps a
  present coverer, so at the end every candidate is kept or within r/2 of a
  kept point.
* Several time intervals per keyframe pair (default 3), each stratified
  separately with the same random order. An interval may stratify a subset of
  the candidates (``eligible``): the octree thins the shared candidate set to
  the coupon-collector density of each interval's own maximum areas
  (:func:`lod.points.sampling.interval_thinning`), as if every interval had
  drawn its candidates by §3.4.1; the rest of the set takes no part in that
  interval (neither kept nor needing cover).
* Neighbour queries use a regular grid with cell r/2 (the sphere radius, as in
  the paper). The paper builds one grid at each end of the interval and
  intersects the two neighbour sets; we build the grid at the interval's start
  and test the end distance of each start neighbour directly, which yields
  exactly the same pairs with one grid instead of two.
* The kernel does not count neighbours: each deleted point remembers one
  present coverer (a witness), and only the deleted points whose witness is
  about to go need a new one. The decisions are identical to the counting
  formulation (tested against ``stratify_numpy``), but the work drops from
  O(N * neighbours) (about 230 neighbours per candidate at the paper's
  candidate density) to a few early-exit scans per point.
* Parallelism: the (candidate set, interval) pairs are independent, so they
  run as work items on a thread pool (the kernel releases the GIL and holds
  no shared reference counts); the octree starts each node's items with
  :func:`stratify_async` while it prepares the next nodes. Each item's
  decisions only depend on its inputs, so the result does not depend on the
  thread count.

``stratify`` and ``stratify_async`` are the public entry
points (numba kernels); ``stratify_numpy`` is the O(N^2) reference the tests
compare against.
"""
from __future__ import annotations

import threading

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic


def interval_times(intervals: int) -> np.ndarray:
    """(intervals + 1,) float64 equally spaced interval boundaries in [0, 1]."""
    return np.linspace(0.0, 1.0, int(intervals) + 1)


def interval_of(u: float, intervals: int, bounds=None) -> int:
    """Index of the interval holding time u in [0, 1] (u = 1 is in the last).

    bounds : None (equal intervals) or the (intervals + 1,) increasing
        boundaries from :func:`choose_interval_times`.
    """
    if bounds is None:
        return int(min(max(int(np.floor(float(u) * intervals)), 0), intervals - 1))
    b = np.asarray(bounds, np.float64)
    return int(min(max(int(np.searchsorted(b[1:-1], float(u), side="right")), 0), intervals - 1))


#: candidate boundaries per keyframe pair of :func:`choose_interval_times`
#: (divisible by 1, 2, 3, 4, 6, 8, 12, 16, 24: equal splits are on the grid)
INTERVAL_GRID = 48
#: unequal intervals are used only when the cost model gains at least this fraction
INTERVAL_MIN_GAIN = 0.01


def interval_cost_table(v0: np.ndarray, v1: np.ndarray, grid: int = INTERVAL_GRID) -> np.ndarray:
    """(G + 1, G + 1) float64 cost model of the intervals [g_a, g_b] of the
    time grid g_k = k / G: length times the sum over the triangles of their
    largest sampled area in the interval (the kept points of an interval
    scale with the area they must cover at its binding end, §3.4.2); upper
    triangle filled, zeros elsewhere."""
    from lod.points.sampling import triangle_area_at

    G = int(grid)
    A = np.stack([triangle_area_at(v0, v1, k / G) for k in range(G + 1)])  # (G + 1, T)
    cost = np.zeros((G + 1, G + 1))
    for a in range(G):
        run = A[a].copy()
        for b in range(a + 1, G + 1):
            np.maximum(run, A[b], out=run)
            cost[a, b] = (b - a) / G * float(run.sum())
    return cost


def choose_interval_times(v0: np.ndarray, v1: np.ndarray, intervals: int, grid: int = INTERVAL_GRID,
                          min_gain: float = INTERVAL_MIN_GAIN) -> np.ndarray:
    """Interval boundaries for one keyframe pair (§3.4.2, §5.1 time discretization).

    The paper divides the time between two keyframes "in discrete time
    intervals (say 3 or 4)"; it does not ask for equal ones. For a surface
    whose area changes (the shrinking sphere of §5.1) the points drawn,
    averaged over time, are smallest when the intervals are short where the
    area is large. The boundaries minimise :func:`interval_cost_table` over
    the grid by dynamic programming; when that beats equal intervals by less
    than ``min_gain`` (animated characters: the area hardly changes), equal
    intervals are returned.

    Parameters
    ----------
    v0, v1 : (T, 3, 3) float triangle corners at u = 0 and u = 1
    intervals : int >= 1
    grid : int, candidate boundaries k / grid
    min_gain : float, relative gain required to leave equal intervals

    Returns
    -------
    (intervals + 1,) float64 increasing boundaries, first 0 and last 1.
    """
    m = int(intervals)
    eq = interval_times(m)
    G = int(grid)
    v0 = np.asarray(v0, np.float64).reshape(-1, 3, 3)
    if m < 2 or v0.shape[0] == 0 or G < m:
        return eq
    cost = interval_cost_table(v0, v1, G)
    inf = np.inf
    best = np.full((m + 1, G + 1), inf)
    arg = np.zeros((m + 1, G + 1), np.int64)
    best[0, 0] = 0.0
    for j in range(1, m + 1):
        for b in range(j, G + 1):
            c = best[j - 1, :b] + cost[:b, b]
            a = int(np.argmin(c))
            best[j, b] = c[a]
            arg[j, b] = a
    opt = best[m, G]
    equal = 0.0
    if G % m == 0:
        step = G // m
        equal = sum(cost[j * step, (j + 1) * step] for j in range(m))
    else:  # equal intervals off the grid: their cost from exact areas at the ends and the grid inside
        equal = inf
    if not np.isfinite(opt) or opt <= 0.0 or (np.isfinite(equal) and opt > (1.0 - min_gain) * equal):
        return eq
    b = [G]
    for j in range(m, 0, -1):
        b.append(int(arg[j, b[-1]]))
    return np.asarray(b[::-1], np.float64) / G


# --------------------------------------------------------------------------- reference

def _greedy_numpy(adj: np.ndarray, order: np.ndarray) -> np.ndarray:
    n = adj.shape[0]
    nbrs = [np.flatnonzero(adj[i]) for i in range(n)]
    cnt = np.array([len(x) for x in nbrs], np.int64)
    deleted = np.zeros(n, bool)
    for i in order:
        if cnt[i] == 0:
            continue  # (a) nobody present covers it
        nb = nbrs[i]
        if np.any(deleted[nb] & (cnt[nb] < 2)):
            continue  # (b) it is the last coverer of a deleted point
        deleted[i] = True
        cnt[nb] -= 1
    return ~deleted


def stratify_numpy(positions: np.ndarray, spacing: float, order: np.ndarray) -> np.ndarray:
    """Reference stratification with dense distance matrices (small inputs).

    Parameters
    ----------
    positions : (m + 1, N, 3) float64 candidate positions at the interval
        boundaries (:func:`interval_times`)
    spacing : float, maximum sample distance r (coverage radius r/2)
    order : (N,) int permutation, the random deletion order

    Returns
    -------
    keep : (m, N) bool, the kept points of each interval.
    """
    pos = np.asarray(positions, np.float64)
    m = pos.shape[0] - 1
    n = pos.shape[1]
    rad2 = (0.5 * float(spacing)) ** 2
    keep = np.ones((m, n), bool)
    for j in range(m):
        da = ((pos[j][:, None, :] - pos[j][None, :, :]) ** 2).sum(-1)
        db = ((pos[j + 1][:, None, :] - pos[j + 1][None, :, :]) ** 2).sum(-1)
        adj = (da <= rad2) & (db <= rad2)
        np.fill_diagonal(adj, False)
        keep[j] = _greedy_numpy(adj, np.asarray(order))
    return keep


def stratify_poses_numpy(poses: np.ndarray, spacing: float, order: np.ndarray) -> np.ndarray:
    """Reference of the stratification over K poses (``lod.points.follow``): i covers j
    when they are within r/2 at every pose; (N,) bool kept points (dense matrices, small inputs)."""
    pos = np.asarray(poses, np.float64)
    rad2 = (0.5 * float(spacing)) ** 2
    n = pos.shape[1]
    adj = np.ones((n, n), bool)
    for q in range(pos.shape[0]):
        adj &= ((pos[q][:, None, :] - pos[q][None, :, :]) ** 2).sum(-1) <= rad2
    np.fill_diagonal(adj, False)
    return _greedy_numpy(adj, np.asarray(order))


# --------------------------------------------------------------------------- kernels

@intrinsic
def _prefetch(typingctx, arr, idx):  # pragma: no cover - compiled
    """Software prefetch (read, all cache levels) of the line holding element
    ``idx`` of the C-contiguous array ``arr`` (flat index); no effect on results."""
    sig = types.void(arr, idx)

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        size = context.get_abi_sizeof(context.get_data_type(signature.args[0].dtype))
        ptr = builder.gep(builder.bitcast(ary.data, ir.IntType(8).as_pointer()),
                          [builder.mul(args[1], ir.Constant(args[1].type, size))])
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [ptr.type, i32, i32, i32]),
                                            "llvm.prefetch.p0")
        builder.call(fn, [ptr, ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return sig, codegen


@njit(cache=True, nogil=True)
def _cells(pa, cell, sel):  # pragma: no cover - compiled
    """Cells of the points ``pa[sel]`` in a dense grid of cubic cells of side ``cell``.

    Returns (lo, dims, cell_start, cell, cell_of): ``cell_start`` (cells + 1,)
    is the exclusive prefix sum of the cell counts and ``cell_of[t]`` the cell
    of point ``sel[t]``. The cell is enlarged when the dense grid would exceed
    ~8 cells per point (far-spread input), which keeps the 27-cell query exact
    (cells are never smaller than asked).
    """
    n = sel.shape[0]
    lo = np.empty(3)
    hi = np.empty(3)
    for k in range(3):
        lo[k] = pa[sel[0], k]
        hi[k] = pa[sel[0], k]
    for t in range(n):
        i = sel[t]
        for k in range(3):
            v = pa[i, k]
            if v < lo[k]:
                lo[k] = v
            if v > hi[k]:
                hi[k] = v
    limit = max(8 * n, 4096)
    while True:
        dims = np.empty(3, np.int64)
        tot = 1
        for k in range(3):
            dims[k] = int((hi[k] - lo[k]) / cell) + 1
            tot *= dims[k]
        if tot <= limit:
            break
        cell *= 1.5
    cell_of = np.empty(n, np.int64)
    counts = np.zeros(tot + 1, np.int64)
    for t in range(n):
        i = sel[t]
        ix = min(int((pa[i, 0] - lo[0]) / cell), dims[0] - 1)
        iy = min(int((pa[i, 1] - lo[1]) / cell), dims[1] - 1)
        iz = min(int((pa[i, 2] - lo[2]) / cell), dims[2] - 1)
        c = (ix * dims[1] + iy) * dims[2] + iz
        cell_of[t] = c
        counts[c + 1] += 1
    for c in range(tot):
        counts[c + 1] += counts[c]
    return lo, dims, counts, cell, cell_of


@njit(cache=True, nogil=True)
def _grid(pa, cell):  # pragma: no cover - compiled
    """Counting-sort grid of the points pa (:func:`_cells` plus the point ids
    sorted by cell). Returns (lo, dims, cell_start, sorted_ids, cell, cell_of)."""
    n = pa.shape[0]
    lo, dims, counts, cell, cell_of = _cells(pa, cell, np.arange(n))
    fill = counts[:-1].copy()
    ids = np.empty(n, np.int64)
    for i in range(n):
        c = cell_of[i]
        ids[fill[c]] = i
        fill[c] += 1
    return lo, dims, counts, ids, cell, cell_of


def _neighbour_order() -> np.ndarray:
    """(27, 3) int64 cell offsets in "near/far" form, nearest first.

    Component 0 = same cell index, 1 = the neighbour on the side nearer to the
    point, 2 = the neighbour on the far side; sorted by the smallest possible
    distance of such a cell from a point in the centre cell.
    """
    offs = [(a, b, c) for a in range(3) for b in range(3) for c in range(3)]
    key = lambda o: (sum(x == 2 for x in o), sum(x == 1 for x in o))  # noqa: E731
    return np.array(sorted(offs, key=key), np.int64)


_NEIGHBOURS = _neighbour_order()


@njit(cache=True, inline="always")
def _neighbour_step(o, i, step, near):  # pragma: no cover - compiled
    """One axis of a neighbour offset (_NEIGHBOURS code o: 0 same cell, 1 the near neighbour, 2 the far one):
    the cell index along the axis and the squared distance (in cells) from the point to that cell's side."""
    if o == 1:
        return i + step, near * near
    if o == 2:
        return i - step, (1.0 - near) * (1.0 - near)
    return i, 0.0


@njit(cache=True, nogil=True)
def _greedy_witness(pos, rad, order0, out, nbr):  # pragma: no cover - compiled
    """Greedy deletion of §3.4.2 with witnesses instead of neighbour counts.

    ``pos`` (K, N, 3): the candidates at K >= 1 times; i covers j when they
    are within ``rad`` at every one of them (an interval: its start and end,
    K = 2; the poses of ``lod.points.follow``: K poses). The grid is built at
    pos[0]. The points taking part are those ``order0`` lists (all of pos's
    rows, or the eligible subset of an interval); ``out`` is written for them only.

    Every deleted point d keeps a *witness*: a present point covering it
    (linked lists ``head``/``nxt`` per witness). Deleting i needs (a) a present
    coverer of i and (b) a new present witness (other than i) for every
    deleted point whose witness is i; deleted points witnessed by someone
    else already have a present coverer besides i. This decides exactly as
    the neighbour-count formulation of ``stratify_numpy`` (same rule, same
    order) but scans only present points, with early exit.

    Each cell's ids are laid out [unprocessed, latest in order first |
    permanent | deleted]. The point being processed is always the last
    unprocessed one of its cell, so keeping it (it becomes permanent: tried
    once, never deleted later) costs nothing and deleting it is one swap.
    Permanent points and late unprocessed points are preferred as witnesses,
    so witnessed points rarely have to move.

    The coverer search (for i, then for each point i witnesses) is written
    once, in the loop body: as a function, even inlined, numba increfs and
    decrefs its five arrays atomically on every call, which took 40% of the
    kernel's time (perf).
    """
    n = order0.shape[0]  # the points taking part: order0 lists them (a subset of pos's rows, or all)
    K = pos.shape[0]
    rad2 = rad * rad
    lo, dims, start, cell, cell_of0 = _cells(pos[0], rad, order0)
    tot = start.shape[0] - 1
    # renumber the points in (cell, latest in order first) order with a
    # counting sort: the cell scans then read contiguous memory
    fill = start[:-1].copy()
    perm = np.empty(n, np.int32)
    order = np.empty(n, np.int32)
    cell_of = np.empty(n, np.int32)
    for t in range(n - 1, -1, -1):
        c = cell_of0[t]
        perm[fill[c]] = order0[t]
        order[t] = fill[c]
        cell_of[fill[c]] = c
        fill[c] += 1
    P = np.empty((n, 3 * K))
    for s in range(n):
        p = perm[s]
        for q in range(K):
            for k in range(3):
                P[s, 3 * q + k] = pos[q, p, k]
    ids = np.arange(n).astype(np.int32)
    keep = np.ones(n, np.bool_)
    cs = np.zeros((tot, 3), np.int64)  # per cell: start, unprocessed, permanent
    for c in range(tot):
        cs[c, 0] = start[c]
        cs[c, 1] = start[c + 1] - start[c]
    head = np.full(n, -1, np.int32)
    nxt = np.full(n, -1, np.int32)
    lox = lo[0]
    loy = lo[1]
    loz = lo[2]
    dx = dims[0]
    dy = dims[1]
    dz = dims[2]
    lim = rad2 / (cell * cell)
    for t in range(n):
        # the points come in random order: fetch the cell and position of
        # point t + 12 and the cell table row of point t + 6 ahead (~10% faster)
        if t + 12 < n:
            _prefetch(cell_of, order[t + 12])
            _prefetch(P, 3 * K * order[t + 12])
        if t + 6 < n:
            _prefetch(cs, 3 * cell_of[order[t + 6]])
        i = order[t]
        ok = True
        wi = -1
        k = i  # the point whose coverer is searched: i first, then those i witnesses
        excl = -1
        rest = -1  # the points witnessed by i still to re-home
        while True:
            # -- w = a present point other than k and excl within rad of k at both
            # times, or -1. Cells nearest first (_NEIGHBOURS), skipped when their
            # box is farther than rad; in a cell the permanent points first, then
            # the unprocessed ones latest in order first (longest-lived witness)
            px = P[k, 0]
            py = P[k, 1]
            pz = P[k, 2]
            fx = (px - lox) / cell
            fy = (py - loy) / cell
            fz = (pz - loz) / cell
            ix = min(max(int(fx), 0), dx - 1)
            iy = min(max(int(fy), 0), dy - 1)
            iz = min(max(int(fz), 0), dz - 1)
            # distance (in cells) to the near and far neighbouring cells along each axis
            rx = fx - ix
            ry = fy - iy
            rz = fz - iz
            sx = -1 if rx < 0.5 else 1
            sy = -1 if ry < 0.5 else 1
            sz = -1 if rz < 0.5 else 1
            nx = min(rx, 1.0 - rx)
            ny = min(ry, 1.0 - ry)
            nz = min(rz, 1.0 - rz)
            w = -1
            for q in range(27):
                ox = nbr[q, 0]
                oy = nbr[q, 1]
                oz = nbr[q, 2]
                x, ex = _neighbour_step(ox, ix, sx, nx)
                y, ey = _neighbour_step(oy, iy, sy, ny)
                z, ez = _neighbour_step(oz, iz, sz, nz)
                d2 = ex + ey + ez
                if d2 > lim or x < 0 or y < 0 or z < 0 or x >= dx or y >= dy or z >= dz:
                    continue
                cc = (x * dy + y) * dz + z
                s0 = cs[cc, 0]
                u1 = s0 + cs[cc, 1]
                p1 = u1 + cs[cc, 2]
                for a in range(p1 - s0):
                    s = u1 + a if a < p1 - u1 else s0 + a - (p1 - u1)
                    j = ids[s]
                    if j == k or j == excl:
                        continue
                    e0 = px - P[j, 0]
                    e1 = py - P[j, 1]
                    e2 = pz - P[j, 2]
                    if e0 * e0 + e1 * e1 + e2 * e2 > rad2:
                        continue
                    far = False
                    for q in range(3, 3 * K, 3):  # the other times (an interval's end: K = 2)
                        e0 = P[k, q] - P[j, q]
                        e1 = P[k, q + 1] - P[j, q + 1]
                        e2 = P[k, q + 2] - P[j, q + 2]
                        if e0 * e0 + e1 * e1 + e2 * e2 > rad2:
                            far = True
                            break
                    if far:
                        continue
                    w = j
                    break
                if w >= 0:
                    break
            # -- the rule
            if k == i:
                if w < 0:
                    ok = False  # (a) nobody present covers i
                    break
                wi = w
                rest = head[i]
                head[i] = -1
            elif w >= 0:
                nxt[k] = head[w]  # k moves to its new witness
                head[w] = k
            else:
                ok = False  # (b) i is the last coverer of the deleted point k
                nxt[k] = rest  # k and the points not yet re-homed stay with i
                head[i] = k
                break
            if rest == -1:
                break
            k = rest
            rest = nxt[k]
            excl = i
        # i sits at the end of its cell's unprocessed block
        c = cell_of[i]
        s = cs[c, 0] + cs[c, 1] - 1
        cs[c, 1] -= 1
        if not ok:
            cs[c, 2] += 1  # first permanent slot: nothing moves
            continue
        keep[i] = False
        nxt[i] = head[wi]
        head[wi] = i
        last = s + cs[c, 2]  # last permanent slot: swap i behind the permanent block
        ids[s] = ids[last]
        ids[last] = i
    for s in range(n):
        out[perm[s]] = keep[s]
    return out


def _checked(positions, spacing, order):
    """(pos (m + 1, N, 3) float64 C-contiguous, rad, order (N,) int64) or ValueError."""
    pos = np.ascontiguousarray(positions, np.float64)
    if pos.ndim != 3 or pos.shape[0] < 2 or pos.shape[2] != 3:
        raise ValueError(f"stratify: positions must be (m + 1, N, 3) with m >= 1, got {pos.shape}")
    rad, order = _checked_order(spacing, order, pos.shape[1])
    if pos.shape[1] and not np.isfinite(pos).all():
        raise ValueError("stratify: candidate positions must be finite, got NaN or Inf")
    return pos, rad, order


def _checked_order(spacing, order, n=None):
    """(rad, order (N,) int64) or ValueError."""
    if not float(spacing) > 0.0:
        raise ValueError(f"stratify: spacing must be > 0, got {spacing}")
    order = np.ascontiguousarray(order, np.int64).reshape(-1)
    if n is not None and order.shape[0] != n:
        raise ValueError(f"stratify: order must list all {n} candidates, got {order.shape[0]}")
    return 0.5 * float(spacing), order


def stratify(positions: np.ndarray, spacing: float, order: np.ndarray, threads: int | None = None,
             eligible: np.ndarray | None = None) -> np.ndarray:
    """Stratify moving candidates per time interval (§3.4.2, numba kernels).

    Parameters
    ----------
    positions : (m + 1, N, 3) float64 candidate positions at the interval
        boundaries (:func:`interval_times`); finite; or a pair (m, at) as
        :func:`stratify_async` takes it (``at(j)`` may give (K, N, 3): K poses)
    spacing : float > 0, the node's maximum sample distance r; coverage radius
        is r/2
    order : (N,) int64 permutation of range(N), the random deletion order
    threads : None (:func:`worker_count`) or a thread count; the intervals
        run in parallel, and the result does not depend on it
    eligible : None (every candidate in every interval) or (m, N) bool, the
        candidates interval j stratifies (same relative deletion order)

    Returns
    -------
    keep : (m, N) bool. For every interval j and every candidate i eligible in
        it, either ``keep[j, i]`` or some kept k has ``|p_i - p_k| <= r/2`` at
        both ends of interval j (hence throughout it); ineligible candidates
        are not kept.

    Raises
    ------
    ValueError on bad shapes, a non-positive spacing or non-finite positions.
    """
    return stratify_async(positions, spacing, order, threads, eligible=eligible).result()


def stratify_async(positions, spacing: float, order: np.ndarray, threads: int | None = None, on_done=None,
                   eligible: np.ndarray | None = None):
    """Start :func:`stratify` of one candidate set on the thread pool, one
    work item per interval; returns a handle whose ``result()`` waits and
    gives the (m, N) keep array.

    Parameters
    ----------
    positions : (m + 1, N, 3) as for :func:`stratify`, or a pair (m, at) with
        ``at(j)`` returning the (2, N, 3) float64 positions at the start and
        end of interval j (or (K, N, 3): coverage at K times, the poses of
        ``lod.points.follow``); it is called by the work item, so positions
        are only held while the set is being stratified
    spacing, order : as for :func:`stratify`
    threads : None (:func:`worker_count`) or a thread count; with one, or
        below :data:`PARALLEL_MIN_CANDIDATES` candidate-intervals, the work
        runs at once in the calling thread
    on_done : None or ``on_done(keep)``, called once, in the thread that
        finished the last interval (the octree filters the node there)
    eligible : as for :func:`stratify`
    """
    job = _checked_job(positions, spacing, order)
    if eligible is not None:
        eligible = np.asarray(eligible, np.bool_)
        if eligible.shape != (job[0], job[3].shape[0]):
            raise ValueError(f"stratify: eligible must be (m, N) = ({job[0]}, {job[3].shape[0]}), "
                             f"got {eligible.shape}")
    work = job[0] * job[3].shape[0]
    return _submit(job, worker_count(threads) if work >= PARALLEL_MIN_CANDIDATES else 1, on_done, eligible)


def _checked_job(positions, spacing, order):
    """(m, positions array or at(j), rad, order int64) of a valid job, or ValueError."""
    if isinstance(positions, tuple):
        m, at = int(positions[0]), positions[1]
        if m < 1:
            raise ValueError(f"stratify: at least one interval, got {m}")
        rad, order = _checked_order(spacing, order)
        return m, at, rad, order
    pos, rad, order = _checked(positions, spacing, order)
    return pos.shape[0] - 1, pos, rad, order


class _Pending:
    """Handle of :func:`stratify_async`: the keep array once every interval is done."""

    def __init__(self, keep, futures):
        self.keep = keep
        self.futures = futures

    def result(self) -> np.ndarray:
        for f in self.futures:
            f.result()  # re-raises a work item's exception
        return self.keep


def _submit(job, workers: int, on_done, eligible=None) -> _Pending:
    m, pos, rad, order = job
    n = order.shape[0]
    keep = np.ones((m, n), np.bool_)
    left = [m if n else 0]
    lock = threading.Lock()

    def run(j):
        if callable(pos):
            p = np.ascontiguousarray(pos(j), np.float64)
            if p.ndim != 3 or p.shape[0] < 1 or p.shape[1:] != (n, 3) or not np.isfinite(p).all():
                raise ValueError(f"stratify: interval positions must be finite (K, {n}, 3)")
        else:
            p = pos[j:j + 2]
        if eligible is None or eligible[j].all():
            _greedy_witness(p, rad, order, keep[j], _NEIGHBOURS)
        else:  # the eligible candidates alone, in the order's relative order
            keep[j] = False
            sub = np.ascontiguousarray(order[eligible[j][order]])
            if sub.size:
                _greedy_witness(p, rad, sub, keep[j], _NEIGHBOURS)
        with lock:
            left[0] -= 1
            last = left[0] == 0
        if last and on_done is not None:
            on_done(keep)

    if not n:
        if on_done is not None:
            on_done(keep)
        return _Pending(keep, [])
    if workers <= 1:
        for j in range(m):
            run(j)
        return _Pending(keep, [])
    pool = _pool(workers)
    return _Pending(keep, [pool.submit(run, j) for j in range(m)])


#: candidate-intervals of one call below which it runs in the calling thread
PARALLEL_MIN_CANDIDATES = 5_000
#: worker threads of the build when ``threads`` is None; None = the usable
#: cores. The kernels hold no shared reference counts (see ``_greedy_witness``),
#: so two threads scale (1.6-1.9x on two idle cores, scripts/bench_points.md)
STRATIFY_THREADS: int | None = None
_POOLS: dict = {}


def worker_count(threads: int | None = None) -> int:
    """Threads to use: ``threads``, else :data:`STRATIFY_THREADS`, else the usable cores."""
    if threads is None:
        threads = STRATIFY_THREADS
    if threads is None:
        import os

        threads = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, int(threads))


def _pool(workers: int):
    from concurrent.futures import ThreadPoolExecutor

    p = _POOLS.get(workers)
    if p is None:
        p = _POOLS[workers] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="stratify")
    return p
