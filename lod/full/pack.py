"""Per-frame instance packing of the full-detail mode: camera-relative model
rows, frustum culling with whole-animation bounds and a stable counting sort
into one instanced batch per (representation, part) — two numba passes
(:func:`instance_batches`) beside the plain numpy reference
(:func:`instance_batches_numpy`); no per-instance Python loop.
"""
from __future__ import annotations

import types

import numba
import numpy as np
from numba import njit, prange

from lod.cull import cull_spheres_numpy
from lod.drawlist import INSTANCE_FLOATS


#: instances from which :func:`instance_batches` runs its passes in parallel (below, serial: llvmpipe's
#: render threads share the cores and a parallel region costs a thread wake-up; measured slower at 100 K
#: on the loaded 2-core machine, see instance_batches); a million agents pay it back
PACK_PARALLEL_MIN = 250_000
#: chunks of agents per numba thread in the parallel counting sort
PACK_CHUNKS_PER_THREAD = 4


# ---------------------------------------------------------------------------- selection
def model_rows(rel: np.ndarray, heading: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(n, 12) float32 rows 0..2 of camera-relative model matrices.

    rel : (n, 3) float64 position minus camera position; heading : (n,) yaw
    about +Y (0 faces +Z); scale : (n,) uniform scale.
    """
    n = rel.shape[0]
    c = np.cos(heading) * scale
    s = np.sin(heading) * scale
    out = np.zeros((n, 12), np.float32)
    out[:, 0] = c
    out[:, 2] = s
    out[:, 3] = rel[:, 0]
    out[:, 5] = scale
    out[:, 7] = rel[:, 1]
    out[:, 8] = -s
    out[:, 10] = c
    out[:, 11] = rel[:, 2]
    return out


def instance_batches_numpy(pos, origin, heading, scale, gid, t, anim, g_sphere, g_skinned, g_off, g_fps, g_dur,
                           g_loop, g_last, planes, cull):
    """Reference of :func:`instance_batches` (plain numpy, same results)."""
    n = pos.shape[0]
    G = g_sphere.shape[0]
    rel = pos - origin
    heading = np.where(np.isfinite(heading), heading, 0.0)
    anim = anim.astype(np.float64).copy()
    sk = g_skinned[gid] if n else np.zeros(0, bool)
    if sk.any():
        gs = gid[sk]
        ts = np.where(np.isfinite(t[sk]), t[sk], 0.0)
        dur = g_dur[gs]
        safe = np.where(dur > 0.0, dur, 1.0)
        tl = np.where(g_loop[gs], np.mod(ts, safe), np.clip(ts, 0.0, dur))
        tl = np.where(dur > 0.0, tl, 0.0)
        anim[sk] = np.clip(g_off[gs] + tl * g_fps[gs], g_off[gs], g_last[gs])
    if cull and n:
        sph = g_sphere[gid]
        c, s = np.cos(heading), np.sin(heading)
        cx = (c * sph[:, 0] + s * sph[:, 2]) * scale
        cz = (-s * sph[:, 0] + c * sph[:, 2]) * scale
        centers = rel + np.stack([cx, sph[:, 1] * scale, cz], axis=1)
        idx = np.flatnonzero(cull_spheres_numpy(centers, sph[:, 3] * np.abs(scale), planes))
    else:
        idx = np.arange(n)
    order = idx[np.argsort(gid[idx], kind="stable")]
    data = np.zeros((order.size, INSTANCE_FLOATS), np.float32)
    data[:, :12] = model_rows(rel[order], heading[order], scale[order])
    data[:, 12] = anim[order]
    counts = np.bincount(gid[order], minlength=G).astype(np.int64)
    return order.astype(np.int32), data, counts


def _twin(f, suffix: str):
    """A copy of loop function ``f`` named ``f.__name__ + suffix``: numba caches compiled code per
    function name, so one loop source compiled serially and in parallel needs two names."""
    g = types.FunctionType(f.__code__, f.__globals__, f.__name__ + suffix, f.__defaults__, f.__closure__)
    g.__qualname__ = f.__qualname__ + suffix
    g.__doc__ = f.__doc__
    return g


def _instance_loop(pos, origin, heading, scale, gid, t, anim, g_sphere, g_skinned, g_off, g_fps, g_dur, g_loop,
                   g_last, planes, cull, vis, cs):  # pragma: no cover - compiled
    """Per instance: the skinned frame coordinate, cos/sin of the heading, the frustum test (every
    instance writes only its own rows). One body for the serial and the parallel kernel (``prange`` is
    ``range`` in the serial one); no helper call per instance: a call passing these arrays costs a
    reference-count update of each, 3x the whole loop."""
    for i in prange(pos.shape[0]):
        g = gid[i]
        h = heading[i]
        if not np.isfinite(h):
            h = 0.0
            heading[i] = 0.0
        if g_skinned[g]:
            ti = t[i]
            if not np.isfinite(ti):
                ti = 0.0
            d = g_dur[g]
            if d > 0.0:
                if g_loop[g]:
                    tl = ti - np.floor(ti / d) * d
                else:
                    tl = min(max(ti, 0.0), d)
            else:
                tl = 0.0
            f = g_off[g] + tl * g_fps[g]
            anim[i] = min(max(f, g_off[g]), g_last[g])
        ok = True
        c = np.cos(h)
        s = np.sin(h)
        cs[i, 0] = c
        cs[i, 1] = s
        if cull:
            sc = scale[i]
            sx, sy, sz, sr = g_sphere[g, 0], g_sphere[g, 1], g_sphere[g, 2], g_sphere[g, 3]
            cx = pos[i, 0] - origin[0] + (c * sx + s * sz) * sc
            cy = pos[i, 1] - origin[1] + sy * sc
            cz = pos[i, 2] - origin[2] + (-s * sx + c * sz) * sc
            r = sr * abs(sc)
            for k in range(planes.shape[0]):
                if planes[k, 0] * cx + planes[k, 1] * cy + planes[k, 2] * cz + planes[k, 3] < -r:
                    ok = False
                    break
        vis[i] = ok


_instance_pass = njit(cache=True)(_twin(_instance_loop, "_serial"))
_instance_pass_parallel = njit(cache=True, parallel=True)(_twin(_instance_loop, "_parallel"))


@njit(cache=True, parallel=True)
def _chunk_counts(gid, vis, first, G):  # pragma: no cover - compiled
    """(C, G) visible instances of each group in each chunk of agents."""
    C = first.shape[0] - 1
    out = np.zeros((C, G), np.int64)
    for c in prange(C):
        for i in range(first[c], first[c + 1]):
            if vis[i]:
                out[c, gid[i]] += 1
    return out


def _scatter_loop(pos, origin, cs, scale, gid, anim, vis, first, cstarts, ids, data):  # pragma: no cover
    """The stable counting sort by chunks of agents: chunk c writes group g from ``cstarts[c, g]`` (the
    group's start plus the earlier chunks' counts), so every row lands where a serial pass puts it: the
    camera-relative model rows and the animation float of each visible instance, keeping agent order
    within a group. Serial (one chunk) and parallel kernels share this body."""
    for c in prange(first.shape[0] - 1):
        cursor = cstarts[c].copy()
        for i in range(first[c], first[c + 1]):
            if not vis[i]:
                continue
            g = gid[i]
            k = cursor[g]
            cursor[g] += 1
            ids[k] = i
            sc = scale[i]
            co = cs[i, 0] * sc
            si = cs[i, 1] * sc
            data[k, 0] = co
            data[k, 1] = 0.0
            data[k, 2] = si
            data[k, 3] = pos[i, 0] - origin[0]
            data[k, 4] = 0.0
            data[k, 5] = sc
            data[k, 6] = 0.0
            data[k, 7] = pos[i, 1] - origin[1]
            data[k, 8] = -si
            data[k, 9] = 0.0
            data[k, 10] = co
            data[k, 11] = pos[i, 2] - origin[2]
            data[k, 12] = anim[i]
            data[k, 13] = 0.0
            data[k, 14] = 0.0
            data[k, 15] = 0.0


_scatter = njit(cache=True)(_twin(_scatter_loop, "_serial"))
_scatter_parallel = njit(cache=True, parallel=True)(_twin(_scatter_loop, "_parallel"))


def instance_batches(pos, origin, heading, scale, gid, t, anim, g_sphere, g_skinned, g_off, g_fps, g_dur, g_loop,
                     g_last, planes, cull):
    """Cull instances and pack their instance data grouped by draw group.

    Two numba passes, serial below :data:`PACK_PARALLEL_MIN` instances (llvmpipe's render threads
    share the same cores, and a ``parallel=True`` first pass measured slower
    on the loaded 2-core machine, 32 ms against 6-12 ms for 100K instances), in parallel above
    (the counting sort by chunks of agents, each from its exclusive prefix: the same rows):
    the first computes skinned frame coordinates (clip offset + wrapped time * fps, in float64) and tests
    each instance's whole-animation bounding sphere (rotated by the heading,
    scaled) against the frustum; after a per-group count, the second (serial)
    is a counting sort that writes each visible instance's camera-relative
    model rows and animation float in group order, keeping agent order within
    a group (stable), in O(n).

    Parameters
    ----------
    pos : (n, 3) float64 world; origin : (3,) float64 camera position
    heading : (n,) float64; scale : (n,) float64; gid : (n,) int64 group
    t : (n,) float64 animation times; anim : (n,) float64 precomputed
        animation floats for non-skinned groups (keyframed u)
    g_sphere : (G, 4) float64 model-space spheres; g_skinned : (G,) bool;
    g_off, g_fps, g_dur, g_last : (G,) float64; g_loop : (G,) bool
    planes : (6, 4) float64 camera-relative; cull : bool

    Returns
    -------
    ids : (k,) int32 agent indices in group order; data : (k, 16) float32
    instance data; counts : (G,) int64 visible instances per group.
    """
    n = pos.shape[0]
    G = g_sphere.shape[0]
    if n == 0:
        return np.zeros(0, np.int32), np.zeros((0, INSTANCE_FLOATS), np.float32), np.zeros(G, np.int64)
    heading = np.array(heading, np.float64)  # the kernel sanitises a copy
    anim = np.array(anim, np.float64)
    vis = np.empty(n, np.bool_)
    cs = np.empty((n, 2), np.float64)
    par = n >= PACK_PARALLEL_MIN and numba.get_num_threads() > 1
    first_pass = _instance_pass_parallel if par else _instance_pass
    first_pass(np.ascontiguousarray(pos, np.float64), np.ascontiguousarray(origin, np.float64), heading,
               np.ascontiguousarray(scale, np.float64), np.ascontiguousarray(gid, np.int64),
               np.ascontiguousarray(t, np.float64), anim, g_sphere, g_skinned, g_off, g_fps, g_dur, g_loop,
               g_last, np.ascontiguousarray(planes, np.float64), bool(cull), vis, cs)
    counts = np.bincount(gid[vis], minlength=G).astype(np.int64)
    starts = np.zeros(G, np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    k = int(counts.sum())
    ids = np.empty(k, np.int32)
    data = np.empty((k, INSTANCE_FLOATS), np.float32)
    args = (np.ascontiguousarray(pos, np.float64), np.ascontiguousarray(origin, np.float64), cs,
            np.ascontiguousarray(scale, np.float64), np.ascontiguousarray(gid, np.int64), anim, vis)
    if par:
        first = np.linspace(0, n, numba.get_num_threads() * PACK_CHUNKS_PER_THREAD + 1).astype(np.int64)
        cc = _chunk_counts(args[4], vis, first, G)
        cstarts = starts[None, :] + np.cumsum(cc, axis=0) - cc  # exclusive prefix over the chunks
        _scatter_parallel(*args, first, np.ascontiguousarray(cstarts), ids, data)
    else:
        _scatter(*args, np.array([0, n], np.int64), starts[None, :].copy(), ids, data)
    return ids, data, counts
