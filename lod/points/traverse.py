"""Per-frame traversal of a point/triangle octree (Wand & Straßer 2002, §3.2, §3.3).

At time u in [0, 1] of the keyframe pair, from the root down:

* the node's box is the linear interpolation of its start and end boxes (§3.3);
* a node whose (transformed) box lies entirely outside one frustum plane is
  culled with its subtree;
* the triangles stored at every visited node are drawn (§3.2: "all triangles
  that are found during hierarchy traversal");
* the node's projected spacing is ``spacing / min depth * viewport_scale``
  (min depth: the smallest view depth of the 8 box corners; viewport scale:
  pixels per metre at depth 1). If it is at most the splat size the node's
  points of the current time interval are drawn and the subtree ends there;
  else the children are visited. A box reaching to or behind the camera
  (min depth <= 0) always descends: no division by zero, no projection of a
  point behind the eye. A leaf draws its triangles and, if it has any, its
  points of the current interval (the octrees of ``lod.points.octree`` keep
  no points at leaves; the super-hierarchy leaves of ``lod.points.instancing``
  (§3.6) hold only points, and their owners ensure they are fine enough).

Coordinates: the node boxes are in the model space of the hierarchy; ``model``
(3, 4) maps model space to camera-relative world space (the camera at the
origin, see ``lod.view``), where ``planes`` (6, 4) are given with unit inward
normals, ordered left, right, bottom, top, near, far as
``Camera.frustum_planes`` returns them. The view depth of a point is its
distance along the near plane's normal (the viewing direction). Spacings are
scaled by the largest column norm of the model's linear part.

No occlusion culling: Wand & Straßer's traversal culls by the view frustum only (the paper
has no occlusion test at all). Hidden nodes are culled at draw time, optionally, by
``render.points.occlusion`` (``[lod] occlusion``), which tests the boxes of the nodes this traversal
selects against a depth pyramid of the frame's likely occluders.

``traverse`` runs the numba kernel; ``traverse_reference`` is the plain Python
recursion the tests compare it with.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from lod.points.coarse import coarse_arrays
from lod.points.stratify import interval_of


@dataclass
class TraversalResult:
    """What to draw of one hierarchy at one time.

    point_ranges : (P, 2) int64 (start, count) into the hierarchy's point arrays
    point_nodes : (P,) int32 the nodes drawn as points
    tri_ranges : (Q, 2) int64 (start, count) into ``tri_order``
    tri_nodes : (Q,) int32 the nodes whose triangles are drawn
    points, triangles : int totals
    """

    point_ranges: np.ndarray
    point_nodes: np.ndarray
    tri_ranges: np.ndarray
    tri_nodes: np.ndarray

    @property
    def points(self) -> int:
        return int(self.point_ranges[:, 1].sum()) if self.point_ranges.size else 0

    @property
    def triangles(self) -> int:
        return int(self.tri_ranges[:, 1].sum()) if self.tri_ranges.size else 0


def _model(model) -> np.ndarray:
    if model is None:
        return np.hstack([np.eye(3), np.zeros((3, 1))])
    m = np.asarray(model, np.float64)
    if m.shape == (4, 4):
        m = m[:3]
    if m.shape != (3, 4) or not np.isfinite(m).all():
        raise ValueError(f"traverse: model must be a finite (3, 4) or (4, 4) matrix, got shape {m.shape}")
    return np.ascontiguousarray(m)


def _corners(lo, hi, model, mats=()):
    """(8, 3) transformed corners of the box [lo, hi] (through each (3, 4) of ``mats`` first: 8 per matrix)."""
    c = np.array([[lo[0] if (k >> 2) & 1 == 0 else hi[0], lo[1] if (k >> 1) & 1 == 0 else hi[1],
                   lo[2] if k & 1 == 0 else hi[2]] for k in range(8)])
    if len(mats):
        c = np.concatenate([c @ np.asarray(m, np.float64)[:, :3].T + np.asarray(m, np.float64)[:, 3] for m in mats])
    return c @ model[:, :3].T + model[:, 3]


def traverse_reference(h, u: float, planes, viewport_scale: float, splat_size: float, model=None,
                       frame: float = 0.0) -> TraversalResult:
    """Reference traversal (plain Python recursion), same contract as :func:`traverse`."""
    planes = np.asarray(planes, np.float64).reshape(6, 4)
    model = _model(model)
    scale = float(np.linalg.norm(model[:, :3], axis=0).max())
    fwd = planes[4, :3]
    j = interval_of(u, h.intervals, getattr(h, "interval_bounds", None))
    box = h.box_at(float(u))
    coarse_n, coarse_s = coarse_arrays(h)
    ref, jt = joint_frames(h)
    f0, f1, a = frame_rows(frame, jt.shape[0])
    pr, pn, tr, tn = [], [], [], []

    def visit(i):
        mats = () if ref.shape[0] == 0 or ref[i] < 0 else [jt[f, ref[i]] for f in ((f0, f1) if a > 0.0 else (f0,))]
        cs = _corners(box[i, 0], box[i, 1], model, mats)
        if np.any(np.all(cs @ planes[:, :3].T + planes[:, 3] < 0.0, axis=0)):
            return
        if h.tri_count[i] > 0:
            tr.append((h.tri_start[i], h.tri_count[i]))
            tn.append(i)
        if h.child_count[i] == 0:
            if h.point_count[i, j] > 0:  # a leaf with points (a §3.6 super-hierarchy leaf)
                pr.append((h.point_start[i, j], h.point_count[i, j]))
                pn.append(i)
            return
        dmin = float((cs @ fwd).min())
        if dmin > 0.0 and h.spacing[i] * scale / dmin * viewport_scale <= splat_size:
            if h.point_count[i, j] > 0:
                cnt = int(h.point_count[i, j])
                if i == 0:  # coarser than the root: the smallest prefix within the splat (lod.points.coarse)
                    fit = [int(m) for m, s in zip(coarse_n[j], coarse_s[j])
                           if s * scale / dmin * viewport_scale <= splat_size]
                    cnt = min([cnt] + fit[:1])
                pr.append((h.point_start[i, j], cnt))
                pn.append(i)
            return
        for c in range(h.child_start[i], h.child_start[i] + h.child_count[i]):
            visit(c)

    if h.n_nodes:
        visit(0)
    return TraversalResult(np.array(pr, np.int64).reshape(-1, 2), np.array(pn, np.int32),
                           np.array(tr, np.int64).reshape(-1, 2), np.array(tn, np.int32))


@njit(cache=True, inline="always")
def _node_corners(i, lo, hi, ref, jt, f0, f1, a, model, cs):  # pragma: no cover - compiled
    """Corners of node i's box [lo, hi] in camera-relative world space into ``cs``; returns their count.

    Without joint frames (``ref`` empty or ``ref[i] < 0``) the 8 corners through ``model``. In the frame
    of joint ``ref[i]`` (``lod.points.follow``): the corners through the joint's skinning matrix at baked
    row ``f0`` (8), and, for a fractional frame (``a > 0``), also at row ``f1`` (16): a vertex between two
    rows is the blend of its positions at both (LBS is linear in the matrices), inside the hull of both."""
    n = 0
    joint = ref.shape[0] > 0 and ref[i] >= 0
    rows = 2 if joint and a > 0.0 else 1
    for q in range(rows):
        f = f0 if q == 0 else f1
        for c in range(8):
            x = lo[0] if (c >> 2) & 1 == 0 else hi[0]
            y = lo[1] if (c >> 1) & 1 == 0 else hi[1]
            z = lo[2] if c & 1 == 0 else hi[2]
            if joint:
                j = ref[i]
                px = jt[f, j, 0, 0] * x + jt[f, j, 0, 1] * y + jt[f, j, 0, 2] * z + jt[f, j, 0, 3]
                py = jt[f, j, 1, 0] * x + jt[f, j, 1, 1] * y + jt[f, j, 1, 2] * z + jt[f, j, 1, 3]
                pz = jt[f, j, 2, 0] * x + jt[f, j, 2, 1] * y + jt[f, j, 2, 2] * z + jt[f, j, 2, 3]
                x = px
                y = py
                z = pz
            for k in range(3):
                cs[n, k] = model[k, 0] * x + model[k, 1] * y + model[k, 2] * z + model[k, 3]
            n += 1
    return n


@njit(cache=True)
def _traverse_kernel(child_start, child_count, box0, box1, spacing, point_start, point_count,
                     tri_start, tri_count, coarse_count, coarse_spacing, ref, jt, f0, f1, a, u, j, planes, model,
                     scale, viewport_scale, splat, out_p, out_pn, out_t, out_tn, stack, cs, lo,
                     hi):  # pragma: no cover - compiled
    # stack (N + 8,) int64, cs (16, 3), lo (3,), hi (3,) float64: scratch of the caller (no allocation per
    # call: the instance kernels call this once per instance, a million times a frame). ref (N,) int32 and
    # jt (F, J, 3, 4): the joint frames of the node boxes (lod.points.follow; ref empty: none), f0, f1, a
    # the instance's baked rows and blend
    N = child_start.shape[0]
    sp = 0
    np_ = 0
    nt = 0
    if N == 0:
        return 0, 0
    stack[sp] = 0
    sp += 1
    w = 1.0 - u
    while sp > 0:
        sp -= 1
        i = stack[sp]
        for k in range(3):
            lo[k] = w * box0[i, 0, k] + u * box1[i, 0, k]
            hi[k] = w * box0[i, 1, k] + u * box1[i, 1, k]
        nc = _node_corners(i, lo, hi, ref, jt, f0, f1, a, model, cs)
        culled = False
        for p in range(planes.shape[0]):
            outside = True
            for c in range(nc):
                if planes[p, 0] * cs[c, 0] + planes[p, 1] * cs[c, 1] + planes[p, 2] * cs[c, 2] + planes[p, 3] >= 0.0:
                    outside = False
                    break
            if outside:
                culled = True
                break
        if culled:
            continue
        if tri_count[i] > 0:
            out_t[nt, 0] = tri_start[i]
            out_t[nt, 1] = tri_count[i]
            out_tn[nt] = i
            nt += 1
        if child_count[i] == 0:
            if point_count[i, j] > 0:  # a leaf with points (a §3.6 super-hierarchy leaf)
                out_p[np_, 0] = point_start[i, j]
                out_p[np_, 1] = point_count[i, j]
                out_pn[np_] = i
                np_ += 1
            continue
        dmin = np.inf
        for c in range(nc):
            d = planes[4, 0] * cs[c, 0] + planes[4, 1] * cs[c, 1] + planes[4, 2] * cs[c, 2]
            if d < dmin:
                dmin = d
        if dmin > 0.0 and spacing[i] * scale / dmin * viewport_scale <= splat:
            if point_count[i, j] > 0:
                cnt = point_count[i, j]
                if i == 0:  # the root: its smallest prefix within the splat (lod.points.coarse)
                    f = scale / dmin * viewport_scale
                    for q in range(coarse_count.shape[1]):
                        if coarse_spacing[j, q] * f <= splat:
                            cnt = min(cnt, coarse_count[j, q])
                            break
                out_p[np_, 0] = point_start[i, j]
                out_p[np_, 1] = cnt
                out_pn[np_] = i
                np_ += 1
            continue
        # push children in reverse so they pop in order (same order as the reference)
        for c in range(child_start[i] + child_count[i] - 1, child_start[i] - 1, -1):
            stack[sp] = c
            sp += 1
    return np_, nt


#: ``ref`` and ``jt`` of a hierarchy without joint frames (the per-keyframe-pair octrees)
NO_JOINTS = (np.zeros(0, np.int32), np.zeros((1, 1, 3, 4), np.float32))


def joint_frames(h) -> tuple:
    """(ref (N,) int32, jt (F, J, 3, 4) float32) of ``h``'s node boxes: its own (``lod.points.follow``:
    ``h.ref`` and ``h.joint_table``) or none (:data:`NO_JOINTS`)."""
    ref = getattr(h, "ref", None)
    if ref is None:
        return NO_JOINTS
    return ref, h.joint_table


def frame_rows(frame, rows: int) -> tuple:
    """(f0, f1, a): the baked rows around a fractional frame coordinate (clamped to 0 .. rows - 1; a
    non-finite one is row 0), as the GPU blends them (shaders/poses/skinning.glsl ``frame_pair``)."""
    f = float(frame) if np.isfinite(frame) else 0.0
    f = min(max(f, 0.0), float(max(rows - 1, 0)))
    f0 = int(np.floor(f))
    return f0, min(f0 + 1, max(rows - 1, 0)), f - f0


def traverse(h, u: float, planes, viewport_scale: float, splat_size: float, model=None,
             frame: float = 0.0) -> TraversalResult:
    """Select the points and triangles of hierarchy ``h`` to draw at time u (§3.2).

    Parameters
    ----------
    h : lod.points.octree.PointHierarchy
    u : float in [0, 1], time within the keyframe pair (clamped)
    planes : (6, 4) float64 camera-relative unit inward frustum planes
        (``Camera.frustum_planes``); the near plane (row 4) defines depth
    viewport_scale : float > 0, pixels per metre at depth 1
        (``height / (2 tan(fov_y / 2))``)
    splat_size : float > 0, splat size in pixels
    model : (3, 4) or (4, 4) float64 model-to-camera-relative-world transform
        (default identity: the hierarchy is already camera-relative)
    frame : the fractional baked row of a hierarchy whose node boxes sit in
        joint frames (``lod.points.follow``; ignored otherwise)

    Returns
    -------
    TraversalResult (ranges in depth-first order, children in storage order).

    Raises
    ------
    ValueError for bad planes, model, scale or splat size.
    """
    planes = np.ascontiguousarray(planes, np.float64)
    if planes.shape != (6, 4) or not np.isfinite(planes).all():
        raise ValueError(f"traverse: planes must be a finite (6, 4) array, got shape {planes.shape}")
    if not (viewport_scale > 0.0 and splat_size > 0.0):
        raise ValueError(f"traverse: viewport_scale and splat_size must be > 0, got {viewport_scale}, {splat_size}")
    model = _model(model)
    u = float(np.clip(u, 0.0, 1.0)) if np.isfinite(u) else 0.0
    scale = float(np.linalg.norm(model[:, :3], axis=0).max())
    N = h.n_nodes
    out_p = np.empty((N, 2), np.int64)
    out_pn = np.empty(N, np.int32)
    out_t = np.empty((N, 2), np.int64)
    out_tn = np.empty(N, np.int32)
    ref, jt = joint_frames(h)
    f0, f1, a = frame_rows(frame, jt.shape[0])
    np_, nt = _traverse_kernel(h.child_start.astype(np.int64), h.child_count.astype(np.int64), h.box0, h.box1,
                               h.spacing, h.point_start, h.point_count, h.tri_start, h.tri_count,
                               *coarse_arrays(h), ref, jt, f0, f1, a, u,
                               interval_of(u, h.intervals, getattr(h, "interval_bounds", None)), planes, model,
                               scale, float(viewport_scale), float(splat_size), out_p, out_pn, out_t, out_tn,
                               np.empty(N + 8, np.int64), np.empty((16, 3)), np.empty(3), np.empty(3))
    return TraversalResult(out_p[:np_].copy(), out_pn[:np_].copy(), out_t[:nt].copy(), out_tn[:nt].copy())


def viewport_scale(height_px: float, fov_y_deg: float) -> float:
    """Pixels per metre at depth 1: ``height / (2 tan(fov_y / 2))``."""
    return float(height_px) / (2.0 * np.tan(np.radians(float(fov_y_deg)) * 0.5))
