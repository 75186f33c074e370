"""Occlusion culling of point-hierarchy nodes against a hierarchical depth
buffer (render side of mode "points"; ``render.points.draw`` calls it).

Wand & Straßer 2002 (*Multi-Resolution Rendering of Complex Animated Scenes*)
have no occlusion culling at all: their traversal (§3.2) culls by the view
frustum only, so a view from inside a crowd splats every instance behind the
first rows (the grid scene seen from 3 m up: depth complexity 2.8). This module
adds the two-phase occlusion test of GPU-driven renderers (Greene, Kass, Miller,
*Hierarchical Z-Buffer Visibility*, SIGGRAPH 1993, §4-§5 for the depth pyramid;
Haar & Aaltonen, *GPU-Driven Rendering Pipelines*, SIGGRAPH 2015 course, for
the "draw the likely occluders first, then test the rest against their depth"
order), the same idea as the cluster drawer's queries (``render.clusters.draw``,
VDR-AM §5.2) with a depth pyramid instead of one GL query per box:

1. every job the traversal selected (a node drawn as points, or a node's
   triangles, for one instance) gets a conservative screen bound
   (:func:`job_bounds`): the node's box at the instance's u (the linear
   interpolation of its start and end boxes holds every point and triangle of
   the subtree at u, Wand & Straßer §3.3) projected to a pixel rectangle,
   grown by the splat footprint, and its nearest window depth;
2. the likely occluders are drawn first: the jobs of the instances found
   visible in the previous frame (its potentially visible set) and the
   nearest jobs (a share of the work, :data:`OCCLUSION_FIRST_SHARE`; all of
   the first frame's occluders): triangles depth-tested and written, points
   splatted into the anchor depth keys;
3. the depth so far (GL depth buffer and anchor keys, per pixel the nearer) is
   read back and reduced to a max-depth pyramid (:func:`depth_pyramid`): each
   level's texel holds the farthest depth of its 2^k x 2^k pixels;
4. every other job is tested (:func:`occluded`): its rectangle is covered by
   at most 2 x 2 texels of one level, and it is hidden when its nearest depth
   lies behind the farthest depth there (plus :data:`DEPTH_EPSILON`). Hidden
   jobs are not drawn; the others are drawn as in step 2, then the colour pass
   and the resolve run over all drawn points. The instances with a job not
   hidden by that pyramid (drawn first or after the test) are the next
   frame's visible set, so an instance that became hidden leaves it. A frame
   whose test finds less than :data:`OCCLUSION_MIN_SHARE` of the work hidden
   turns the culling off for :data:`OCCLUSION_RETRY_FRAMES` frames (its cost
   would not be paid back), then it is tried again.

The test only ever drops a job none of whose pixels can win the depth test
against geometry already in this frame's buffers, so the image is the one
without culling (up to ties within the epsilon). Departure from Greene et al.:
the pyramid is built on the CPU from a read-back (llvmpipe: the "GPU" is the
CPU, the read-back is a copy) and the test is a numba kernel
(:func:`occluded`) beside the numpy reference :func:`occluded_reference`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: share of the frame's work (points + TRIANGLE_WEIGHT x triangles) drawn untested first, nearest jobs first
#: (with the instances found visible in the previous frame); the rest is tested against their depth
OCCLUSION_FIRST_SHARE = 0.1
#: a frame whose test finds less than this share of the work hidden (every job tested, the first ones too)
#: stops the culling for OCCLUSION_RETRY_FRAMES frames: where little is hidden (a view over the heads) the
#: test's own cost (bounds, read-back, pyramid, split draws) is not paid back
OCCLUSION_MIN_SHARE = 0.1
#: frames drawn without the test after a frame that found too little hidden (then it is tried again)
OCCLUSION_RETRY_FRAMES = 8
#: weight of one triangle against one point when the first share is measured
TRIANGLE_WEIGHT = 4.0
#: a job is hidden when its nearest window depth exceeds the farthest occluder depth over its rectangle by
#: more than this (float32 splat depths, 24-bit depth buffer: ~6e-8 each)
DEPTH_EPSILON = 1e-6
#: texels per side read at most when a job's rectangle is tested: the finest pyramid level where the
#: rectangle spans at most this many texels each way (2 is Greene et al.'s choice; wider reads fit long thin
#: rectangles, a row of heads on the horizon, much closer to the true maximum)
PYRAMID_SPAN = 8
#: clip w below which a box corner counts as at or behind the eye (the job is then never culled)
MIN_W = 1e-6


# ---------------------------------------------------------------------------- per-job bounds
def node_boxes(box0: np.ndarray, box1: np.ndarray, nodes: np.ndarray, u: np.ndarray) -> tuple:
    """(lo (J, 3), hi (J, 3)) float64 boxes of ``nodes`` at times ``u`` (J,):
    ``(1 - u) box0 + u box1`` (Wand & Straßer §3.3), u clamped to [0, 1]."""
    u = np.asarray(u, np.float64)
    u = np.clip(np.where(u == u, u, 0.0), 0.0, 1.0)[:, None, None]  # NaN -> 0
    b = (1.0 - u) * box0[nodes] + u * box1[nodes]
    return b[:, 0], b[:, 1]


@njit(cache=True)
def _bounds_kernel(lo, hi, model, vp, w, h, pad, rect, zmin):  # pragma: no cover - compiled
    J = lo.shape[0]
    for j in range(J):
        x0 = np.inf
        y0 = np.inf
        x1 = -np.inf
        y1 = -np.inf
        zm = np.inf
        ok = True
        for c in range(8):
            p0 = lo[j, 0] if (c & 1) == 0 else hi[j, 0]
            p1 = lo[j, 1] if (c & 2) == 0 else hi[j, 1]
            p2 = lo[j, 2] if (c & 4) == 0 else hi[j, 2]
            q0 = model[j, 0] * p0 + model[j, 1] * p1 + model[j, 2] * p2 + model[j, 3]
            q1 = model[j, 4] * p0 + model[j, 5] * p1 + model[j, 6] * p2 + model[j, 7]
            q2 = model[j, 8] * p0 + model[j, 9] * p1 + model[j, 10] * p2 + model[j, 11]
            cw = vp[3, 0] * q0 + vp[3, 1] * q1 + vp[3, 2] * q2 + vp[3, 3]
            if not (cw > MIN_W):
                ok = False
                break
            cx = (vp[0, 0] * q0 + vp[0, 1] * q1 + vp[0, 2] * q2 + vp[0, 3]) / cw
            cy = (vp[1, 0] * q0 + vp[1, 1] * q1 + vp[1, 2] * q2 + vp[1, 3]) / cw
            cz = (vp[2, 0] * q0 + vp[2, 1] * q1 + vp[2, 2] * q2 + vp[2, 3]) / cw
            x = (cx * 0.5 + 0.5) * w
            y = (cy * 0.5 + 0.5) * h
            z = cz * 0.5 + 0.5
            x0 = min(x0, x)
            x1 = max(x1, x)
            y0 = min(y0, y)
            y1 = max(y1, y)
            zm = min(zm, z)
        if not ok or not (np.isfinite(x0) and np.isfinite(x1) and np.isfinite(y0) and np.isfinite(y1)
                          and np.isfinite(zm)):
            rect[j, 0] = 0
            rect[j, 1] = 0
            rect[j, 2] = w - 1
            rect[j, 3] = h - 1
            zmin[j] = -1.0
            continue
        a = np.floor(x0 - pad)
        b = np.ceil(x1 + pad)
        c_ = np.floor(y0 - pad)
        d = np.ceil(y1 + pad)
        rect[j, 0] = int(min(max(a, -1.0), w))
        rect[j, 1] = int(min(max(c_, -1.0), h))
        rect[j, 2] = int(min(max(b, -1.0), w))
        rect[j, 3] = int(min(max(d, -1.0), h))
        zmin[j] = zm


def _clamp_rects(rect, zmin, w, h):
    """Clamp rectangles to the screen; a rectangle wholly off screen becomes empty (x0 > x1)."""
    r = rect
    off = (r[:, 2] < 0) | (r[:, 3] < 0) | (r[:, 0] >= w) | (r[:, 1] >= h)
    r[:, 0] = np.clip(r[:, 0], 0, w - 1)
    r[:, 1] = np.clip(r[:, 1], 0, h - 1)
    r[:, 2] = np.clip(r[:, 2], 0, w - 1)
    r[:, 3] = np.clip(r[:, 3], 0, h - 1)
    r[off, 0] = 1
    r[off, 2] = 0
    return r, zmin


def job_bounds(lo, hi, model, view_proj, size, pad: float) -> tuple:
    """Conservative screen bounds of boxes (numba).

    Parameters
    ----------
    lo, hi : (J, 3) float64 box corners in each job's model space
    model : (J, 12) float64 rows of each job's model matrix (camera-relative, row-major 3 x 4)
    view_proj : (4, 4) float64 the frame's view-projection (camera-relative)
    size : (width, height) pixels; pad : pixels added on every side (splat footprint)

    Returns
    -------
    rect : (J, 4) int64 inclusive pixel rectangle (x0, y0, x1, y1) clamped to the
        screen, empty (x0 > x1) when wholly off screen
    zmin : (J,) float64 nearest window depth of the box (-1 when a corner is at or
        behind the eye plane: such a job is never culled)
    """
    w, h = int(size[0]), int(size[1])
    lo = np.ascontiguousarray(lo, np.float64).reshape(-1, 3)
    hi = np.ascontiguousarray(hi, np.float64).reshape(-1, 3)
    model = np.ascontiguousarray(model, np.float64).reshape(-1, 12)
    J = lo.shape[0]
    rect = np.empty((J, 4), np.int64)
    zmin = np.empty(J, np.float64)
    _bounds_kernel(lo, hi, model, np.ascontiguousarray(view_proj, np.float64), float(w), float(h), float(pad),
                   rect, zmin)
    return _clamp_rects(rect, zmin, w, h)


def job_bounds_reference(lo, hi, model, view_proj, size, pad: float) -> tuple:
    """Numpy reference of :func:`job_bounds`."""
    w, h = int(size[0]), int(size[1])
    lo = np.asarray(lo, np.float64).reshape(-1, 3)
    hi = np.asarray(hi, np.float64).reshape(-1, 3)
    M = np.asarray(model, np.float64).reshape(-1, 3, 4)
    sel = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)])
    corners = np.where(sel[None] == 1, hi[:, None, :], lo[:, None, :])  # (J, 8, 3)
    q = np.einsum("jab,jcb->jca", M[:, :, :3], corners) + M[:, None, :, 3]
    vp = np.asarray(view_proj, np.float64)
    clip = q @ vp[:, :3].T + vp[:, 3]
    cw = clip[..., 3]
    ok = np.all(cw > MIN_W, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc = clip[..., :3] / np.where(ok[:, None], cw, 1.0)[..., None]
    x = (ndc[..., 0] * 0.5 + 0.5) * w
    y = (ndc[..., 1] * 0.5 + 0.5) * h
    z = ndc[..., 2] * 0.5 + 0.5
    ok &= np.isfinite(x).all(1) & np.isfinite(y).all(1) & np.isfinite(z).all(1)
    rect = np.empty((lo.shape[0], 4), np.int64)
    rect[:, 0] = np.clip(np.floor(x.min(1) - pad), -1, w).astype(np.int64)
    rect[:, 1] = np.clip(np.floor(y.min(1) - pad), -1, h).astype(np.int64)
    rect[:, 2] = np.clip(np.ceil(x.max(1) + pad), -1, w).astype(np.int64)
    rect[:, 3] = np.clip(np.ceil(y.max(1) + pad), -1, h).astype(np.int64)
    rect[~ok] = (0, 0, w - 1, h - 1)
    zmin = np.where(ok, z.min(1), -1.0)
    return _clamp_rects(rect, zmin, w, h)


# ---------------------------------------------------------------------------- depth pyramid
def occluder_depth(gl_depth, anchor_keys, size, margin: int, splat: int = 1) -> np.ndarray:
    """(h, w) float32 per-pixel depth of what is drawn so far: the nearer of the
    GL depth buffer (h, w), bottom row first, and the nearest splat covering the
    pixel (``render.points.draw``: the point anchored at slot q covers pixels
    q - margin + d, 0 <= d < splat, each way, as the resolve reads them; key
    0xFFFFFFFF = empty = depth 1). Non-finite depths count as 1."""
    w, h = int(size[0]), int(size[1])
    d = np.asarray(gl_depth, np.float32).reshape(h, w)
    if anchor_keys is not None:
        keys = np.asarray(anchor_keys, np.uint32).reshape(h + margin, w + margin)
        a = np.where(keys == np.uint32(0xFFFFFFFF), np.uint32(0x3F800000), keys).view(np.float32)
        for dy in range(max(1, min(int(splat), margin + 1))):
            for dx in range(max(1, min(int(splat), margin + 1))):
                d = np.minimum(d, a[margin - dy:margin - dy + h, margin - dx:margin - dx + w])
    return np.where(np.isfinite(d), d, np.float32(1.0)).astype(np.float32)


def _level_shapes(h: int, w: int) -> tuple:
    hs, ws = [h], [w]
    while hs[-1] > 1 or ws[-1] > 1:
        hs.append((hs[-1] + 1) // 2)
        ws.append((ws[-1] + 1) // 2)
    heights = np.array(hs, np.int64)
    widths = np.array(ws, np.int64)
    offsets = np.zeros(len(hs), np.int64)
    np.cumsum((heights * widths)[:-1], out=offsets[1:])
    return offsets, widths, heights


@njit(cache=True)
def _pyramid_kernel(flat, offsets, widths, heights):  # pragma: no cover - compiled
    for k in range(1, offsets.shape[0]):
        po, pw, ph = offsets[k - 1], widths[k - 1], heights[k - 1]
        o, w, h = offsets[k], widths[k], heights[k]
        for y in range(h):
            for x in range(w):
                m = np.float32(0.0)
                for dy in range(2):
                    yy = 2 * y + dy
                    if yy >= ph:
                        continue
                    for dx in range(2):
                        xx = 2 * x + dx
                        if xx < pw:
                            v = flat[po + yy * pw + xx]
                            if v > m:
                                m = v
                flat[o + y * w + x] = m


def depth_pyramid(depth: np.ndarray) -> tuple:
    """Max-depth pyramid (Greene et al. §4, with max instead of the z-buffer's
    per-tile farthest value) of an (h, w) depth image, packed for the kernel (numba;
    :func:`depth_pyramid_reference` is the numpy reference).

    Returns (flat (T,) float32 texels of every level, offsets (L,) int64,
    widths (L,) int64, heights (L,) int64); level 0 is the image, level k's
    texel (x, y) holds the farthest depth of pixels [2^k x, 2^k (x+1)) x
    [2^k y, 2^k (y+1)) (pixels beyond the image count as depth 0: nothing is
    drawn there). The last level is 1 x 1."""
    d = np.ascontiguousarray(depth, np.float32)
    offsets, widths, heights = _level_shapes(d.shape[0], d.shape[1])
    flat = np.empty(int(offsets[-1] + widths[-1] * heights[-1]), np.float32)
    flat[:d.size] = d.reshape(-1)
    _pyramid_kernel(flat, offsets, widths, heights)
    return flat, offsets, widths, heights


def depth_pyramid_reference(depth: np.ndarray) -> tuple:
    """Numpy reference of :func:`depth_pyramid`.

    Returns (flat (T,) float32 texels of every level, offsets (L,) int64,
    widths (L,) int64, heights (L,) int64); level 0 is the image, level k's
    texel (x, y) holds the farthest depth of pixels [2^k x, 2^k (x+1)) x
    [2^k y, 2^k (y+1)) (pixels beyond the image count as depth 0: nothing is
    drawn there). The last level is 1 x 1."""
    lv = [np.ascontiguousarray(depth, np.float32)]
    while lv[-1].shape[0] > 1 or lv[-1].shape[1] > 1:
        a = lv[-1]
        hh, ww = a.shape
        p = np.zeros((hh + (hh & 1), ww + (ww & 1)), np.float32)
        p[:hh, :ww] = a
        lv.append(p.reshape(p.shape[0] // 2, 2, p.shape[1] // 2, 2).max(axis=(1, 3)))
    heights = np.array([a.shape[0] for a in lv], np.int64)
    widths = np.array([a.shape[1] for a in lv], np.int64)
    offsets = np.zeros(len(lv), np.int64)
    np.cumsum((heights * widths)[:-1], out=offsets[1:])
    return np.concatenate([a.reshape(-1) for a in lv]), offsets, widths, heights


@njit(cache=True)
def _occluded_kernel(rect, zmin, flat, offsets, widths, eps, span, out):  # pragma: no cover - compiled
    L = offsets.shape[0]
    for j in range(rect.shape[0]):
        x0 = rect[j, 0]
        y0 = rect[j, 1]
        x1 = rect[j, 2]
        y1 = rect[j, 3]
        if x0 > x1 or y0 > y1:  # wholly off screen
            out[j] = True
            continue
        if zmin[j] < 0.0:
            out[j] = False
            continue
        k = 0
        while k < L - 1 and ((x1 >> k) - (x0 >> k) >= span or (y1 >> k) - (y0 >> k) >= span):
            k += 1
        far = 0.0
        for ty in range(y0 >> k, (y1 >> k) + 1):
            for tx in range(x0 >> k, (x1 >> k) + 1):
                v = flat[offsets[k] + ty * widths[k] + tx]
                if v > far:
                    far = v
        out[j] = zmin[j] > far + eps


def occluded(rect, zmin, pyramid, eps: float = DEPTH_EPSILON, span: int = PYRAMID_SPAN) -> np.ndarray:
    """(J,) bool: is each job hidden behind the pyramid's depth (numba)?

    A job is hidden when its rectangle is empty (off screen) or its nearest
    depth ``zmin`` exceeds, by more than ``eps``, the farthest depth of the
    texels of the finest level where its rectangle spans at most ``span``
    texels each way (:data:`PYRAMID_SPAN`); never when ``zmin < 0`` (box reaching the eye plane)."""
    flat, offsets, widths, _ = pyramid
    rect = np.ascontiguousarray(rect, np.int64).reshape(-1, 4)
    out = np.empty(rect.shape[0], np.bool_)
    _occluded_kernel(rect, np.ascontiguousarray(zmin, np.float64), flat, offsets, widths, float(eps), int(span), out)
    return out


def occluded_reference(rect, zmin, pyramid, eps: float = DEPTH_EPSILON, span: int = PYRAMID_SPAN) -> np.ndarray:
    """Plain Python reference of :func:`occluded` (same level choice)."""
    flat, offsets, widths, heights = pyramid
    out = np.zeros(len(rect), bool)
    for j, (x0, y0, x1, y1) in enumerate(np.asarray(rect, np.int64).tolist()):
        if x0 > x1 or y0 > y1:
            out[j] = True
            continue
        if zmin[j] < 0.0:
            continue
        k = 0
        while k < len(offsets) - 1 and ((x1 >> k) - (x0 >> k) >= span or (y1 >> k) - (y0 >> k) >= span):
            k += 1
        lvl = flat[offsets[k]:offsets[k] + widths[k] * heights[k]].reshape(heights[k], widths[k])
        out[j] = zmin[j] > float(lvl[y0 >> k:(y1 >> k) + 1, x0 >> k:(x1 >> k) + 1].max()) + eps
    return out


def first_share(zmin, work, share: float = OCCLUSION_FIRST_SHARE) -> np.ndarray:
    """(J,) bool, the nearest jobs (by ``zmin``; untestable ones, zmin < 0, always) holding at
    least ``share`` of the total ``work`` (J,): the occluders drawn before the test."""
    zmin = np.asarray(zmin, np.float64)
    work = np.asarray(work, np.float64)
    order = np.argsort(zmin, kind="stable")
    cum = np.cumsum(work[order])
    n = int(np.searchsorted(cum, share * (cum[-1] if cum.shape[0] else 0.0), side="left")) + 1
    out = np.zeros(zmin.shape[0], bool)
    out[order[:n]] = True
    out |= zmin < 0.0
    return out


# ---------------------------------------------------------------------------- jobs of a frame
def _tri_lookup(h) -> tuple:
    """(sorted first triangles, their nodes) of the nodes of ``h`` holding triangles (cached on ``h``)."""
    t = getattr(h, "_occlusion_tri_lookup", None)
    if t is None:
        nodes = np.flatnonzero(np.asarray(h.tri_count) > 0)
        starts = np.asarray(h.tri_start, np.int64)[nodes]
        o = np.argsort(starts, kind="stable")
        t = h._occlusion_tri_lookup = (starts[o], nodes[o])
    return t


def job_nodes(h, starts: np.ndarray, which: str) -> np.ndarray:
    """(J,) int64 node of each job of hierarchy ``h`` from its first point
    (``which = "point_jobs"``: ``h.node`` of that point) or first triangle in
    ``tri_order`` (``"tri_jobs"``: the node whose triangle range starts there)."""
    starts = np.asarray(starts, np.int64)
    if which == "point_jobs":
        return np.asarray(h.node, np.int64)[starts]
    s, n = _tri_lookup(h)
    return n[np.clip(np.searchsorted(s, starts), 0, max(0, s.shape[0] - 1))]


def job_key(part: int, ids: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(J,) int64 keys of jobs (segment ``part``, instance ``ids``, hierarchy ``nodes``):
    ``((part * P + id) * Q + node)`` with large primes P, Q, wrapping in int64."""
    with np.errstate(over="ignore"):
        return (np.int64(part) * np.int64(1_000_003) + np.asarray(ids, np.int64)) * np.int64(4_194_319) \
            + np.asarray(nodes, np.int64)


def job_boxes(batches, key: str, hierarchies, which: str) -> tuple:
    """Model-space boxes and model rows of the jobs of representation ``key``,
    in the order of ``render.points.draw.job_table`` (batches of ``key`` in order,
    jobs with a positive count): (lo (J, 3), hi (J, 3), model (J, 12)) float64,
    the job's node box at its instance's u (:func:`node_boxes`), and keys (J,)
    int64 naming the job from frame to frame: a mix of its instance id and
    node (:func:`job_key`; not its segment: the octrees of consecutive keyframe pairs of one
    character split the same body alike, and an instance changes segment every few frames;
    a collision only draws a job untested)."""
    los, his, models, ids = [], [], [], []
    for b in batches:
        if b.rep != key:
            continue
        j = np.asarray(getattr(b, which), np.int64).reshape(-1, 3)
        j = j[j[:, 2] > 0]
        if not j.shape[0]:
            continue
        h = hierarchies[b.part]
        data = np.asarray(b.instance_data, np.float64).reshape(-1, 16)[j[:, 0]]
        nodes = job_nodes(h, j[:, 1], which)
        lo, hi = node_boxes(h.box0, h.box1, nodes, data[:, 12])
        los.append(lo)
        his.append(hi)
        models.append(data[:, :12])
        ids.append(job_key(0, np.asarray(b.instance_ids, np.int64).reshape(-1)[j[:, 0]], nodes))
    if not los:
        z = np.zeros((0, 3))
        return z, z, np.zeros((0, 12)), np.zeros(0, np.int64)
    return np.concatenate(los), np.concatenate(his), np.concatenate(models), np.concatenate(ids)


@njit(cache=True)
def _batch_bounds_kernel(box0, box1, nodes, rows, data, vp, w, h, pad, rect, zmin):  # pragma: no cover
    J = nodes.shape[0]
    lo = np.empty((1, 3))
    hi = np.empty((1, 3))
    model = np.empty((1, 12))
    for j in range(J):
        r = rows[j]
        u = data[r, 12]
        if not (u == u):
            u = 0.0
        u = min(max(u, 0.0), 1.0)
        n = nodes[j]
        for a in range(3):
            lo[0, a] = (1.0 - u) * box0[n, 0, a] + u * box1[n, 0, a]
            hi[0, a] = (1.0 - u) * box0[n, 1, a] + u * box1[n, 1, a]
        for a in range(12):
            model[0, a] = data[r, a]
        _bounds_kernel(lo, hi, model, vp, w, h, pad, rect[j:j + 1], zmin[j:j + 1])


def batch_bounds(h, jobs, data, which: str, view_proj, size, pad: float) -> tuple:
    """:func:`job_bounds` of one batch's jobs in one numba call: node boxes at each
    instance's u (:func:`node_boxes`) projected with the instance's model rows, without
    the intermediate arrays of :func:`job_boxes` (the drawer's per-frame path; the tests
    compare it with ``job_boxes`` + ``job_bounds``).

    h : the batch's PointHierarchy; jobs : (J, 3) int64 (row, start, count), counts > 0;
    data : (k, 16) instance data; returns (rect (J, 4) int64, zmin (J,) float64, nodes (J,) int64)."""
    jobs = np.asarray(jobs, np.int64).reshape(-1, 3)
    nodes = job_nodes(h, jobs[:, 1], which)
    w, hh = int(size[0]), int(size[1])
    rect = np.empty((jobs.shape[0], 4), np.int64)
    zmin = np.empty(jobs.shape[0], np.float64)
    _batch_bounds_kernel(np.ascontiguousarray(h.box0, np.float64), np.ascontiguousarray(h.box1, np.float64), nodes,
                         np.ascontiguousarray(jobs[:, 0]), np.ascontiguousarray(data, np.float64).reshape(-1, 16),
                         np.ascontiguousarray(view_proj, np.float64), float(w), float(hh), float(pad), rect, zmin)
    r, z = _clamp_rects(rect, zmin, w, hh)
    return r, z, nodes


def split_first(reps: dict, pvs: np.ndarray, by_fade: dict, tris: list, groups: list, vp, size,
                splat: int) -> tuple:
    """Screen bounds of every job of the point drawer's frame (``render.points.draw``: ``reps`` its GPU reps,
    the job tables ``tris`` and ``groups``; each job's node box at its instance's u) and the nearest share
    drawn before the occlusion test, with the jobs visible last frame (``pvs``).

    Returns (tri_first, pt_first: a bool mask per table, tri_bounds, pt_bounds:
    a (rect, zmin) pair per table)."""
    pad = float(splat) + 1.0  # the splat footprint (and a pixel of rounding) around the box

    rep_no = {k: i for i, k in enumerate(reps)}

    def bounds(bs, key, which):  # (rect, zmin, key of the job: rep number mixed into job_key)
        rs, zs, ks = [], [], []
        for b in bs:  # the order of job_table: batches of rep ``key`` in order, jobs with a count
            if b.rep != key:
                continue
            j = np.asarray(getattr(b, which), np.int64).reshape(-1, 3)
            j = j[j[:, 2] > 0]
            if not j.shape[0]:
                continue
            r_, z_, nodes = batch_bounds(reps[key].hier[b.part], j, b.instance_data, which, vp, size, pad)
            rs.append(r_)
            zs.append(z_)
            ks.append(job_key(0, np.asarray(b.instance_ids, np.int64).reshape(-1)[j[:, 0]], nodes))
        if not rs:
            return np.zeros((0, 4), np.int64), np.zeros(0), np.zeros(0, np.int64)
        return np.concatenate(rs), np.concatenate(zs), np.concatenate(ks) ^ np.int64(rep_no[key] << 56)

    tb = [bounds(by_fade[f], k, "tri_jobs") for f, k, _, _ in tris]
    pb = []
    for fade, _ in groups:
        parts = [bounds(by_fade[fade], k, "point_jobs") for k in reps]
        pb.append(tuple(np.concatenate([p[i] for p in parts]) for i in range(3)))
    z = np.concatenate([b[1] for b in tb + pb])
    work = np.concatenate([TRIANGLE_WEIGHT * t[3][:, 1].astype(np.float64) for t in tris]
                          + [j[:, 1].astype(np.float64) for _, j in groups])
    first = first_share(z, work) | np.isin(np.concatenate([b[2] for b in tb + pb]), pvs)
    cuts = np.cumsum([b[1].shape[0] for b in tb + pb])[:-1]
    masks = np.split(first, cuts)
    return masks[:len(tb)], masks[len(tb):], tb, pb
