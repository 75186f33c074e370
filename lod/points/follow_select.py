"""Per-frame selection of the representations whose samples follow the animation (``lod.points.follow``):
the instances' poses, the traversal of the one hierarchy at each instance's pose (§3.2, node boxes in joint
frames) and the prefixes each distinct pose needs placed.

Poses (pose sharing, issue 27 item 4 and the board's pose cache): copies at the same quantised pose share
one: skinned, the frame coordinate rounded to a baked row of the base's joint table (``pose_rate = "key"``,
the default), to multiples of ``1 / pose_rate`` seconds (a rate > 0), or exact (0); keyframed, the segment
cut into about 30 steps a second (``"key"``) or ``pose_rate`` steps a second, or exact (0). The rules are those of
``lod.poses`` (the pose cache's LOD side, written by the helper ``poses``): this module is the adapter that
lets mode points run before that lands, and then calls it. A copy is drawn at its quantised pose, so the
traversal runs there too: its node boxes are the drawn samples' bounds.

Prefixes: the samples are stored and the vertices numbered in breadth-first node order
(``lod.points.follow.vertex_order``), so a pose whose instances draw nodes up to the deepest one d needs the
samples ``pprefix[d]`` and the vertices ``vprefix[d]``: the render layer places that much once per pose
(``render/points/follow.py``), however many copies share it.
"""
from __future__ import annotations

import numpy as np

from lod.points.jobs import follow_traverse
from lod.points.rep import FollowBatch

#: ``pose_rate`` that quantises to the baked rows
KEY_RATE = "key"
#: poses per second of a keyframed segment under ``"key"`` (its keys are the keyframes: far too coarse)
KEYFRAMED_KEY_RATE = 30.0
#: frames of tolerance at a clip's loop point and end (as lod.poses)
_EPS = 1e-6


def quantise_frames(base, clip: int, f: np.ndarray, rate=KEY_RATE) -> np.ndarray:
    """Frame coordinates ``f`` of clip ``clip`` of a ``lod.full.reps.SkinnedRep`` quantised by ``rate``: the
    local row rounded to the grid of step 1 (``"key"``) or ``clip_fps / rate`` rows; a looping clip's
    rounded end is its start, a non-looping one's last row stays; ``rate = 0`` keeps ``f`` (clamped)."""
    f = np.asarray(f, np.float64)
    off = float(base.clip_offset[clip])
    last = float(int(base.clip_frames[clip]) - 1)
    lf = np.clip(np.where(np.isfinite(f), f, off) - off, 0.0, last)
    st = 1.0 if rate == KEY_RATE else (0.0 if float(rate) == 0.0 else float(base.clip_fps[clip]) / float(rate))
    if not st > 0.0:
        return off + lf
    q = np.floor(lf / st + 0.5) * st
    if bool(base.clip_loop[clip]):
        q = np.where(q >= last - _EPS, 0.0, q)
    return off + np.minimum(q, last)


def quantise_u(kf, seg: int, u: np.ndarray, rate=KEY_RATE) -> np.ndarray:
    """The segment parameters ``u`` of segment ``seg`` of a ``KeyframedRep`` quantised in time by ``rate``
    (``"key"``: :data:`KEYFRAMED_KEY_RATE` per second; 0: exact): the segment cut into
    ``round(duration * rate)`` equal steps (at least one)."""
    u = np.clip(np.where(np.isfinite(u), u, 0.0), 0.0, 1.0)
    r = KEYFRAMED_KEY_RATE if rate == KEY_RATE else float(rate)
    dur = float(kf.seg_end[seg] - kf.seg_start[seg])
    if not (r > 0.0 and dur > 0.0):
        return u
    n = max(1.0, np.round(dur * r))
    return np.round(u * n) / n


#: widest range of keys :func:`_distinct` counts with a presence table instead of a sort
DISTINCT_TABLE = 1 << 20


def _distinct(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(q, return_inverse=True)`` of quantised float64 values, O(n) by a presence table where the
    sort cost 30 ms for a million instances: keyed by the values themselves when they are whole numbers (frames
    quantised to a clip's keys), else by their float32 bit patterns when they came from float32 (positive
    float32s order as their patterns), when either spans at most :data:`DISTINCT_TABLE` keys; else the sort.
    Same values in the same (ascending) order."""
    q = np.asarray(q, np.float64).reshape(-1)
    if q.size == 0 or not (np.isfinite(q).all() and (q >= 0.0).all()):
        return np.unique(q, return_inverse=True)
    keys = None
    if q.max() < 2.0 ** 52 and np.array_equal(np.rint(q), q):  # whole numbers: their own keys
        keys, to_value = q.astype(np.int64), lambda k: k.astype(np.float64)
    elif np.array_equal(q.astype(np.float32).astype(np.float64), q) and (np.signbit(q) == 0).all():
        keys = q.astype(np.float32).view(np.int32).astype(np.int64)
        to_value = lambda k: k.astype(np.int32).view(np.float32).astype(np.float64)  # noqa: E731
    if keys is None:
        return np.unique(q, return_inverse=True)
    lo = int(keys.min())
    span = int(keys.max()) - lo + 1
    if span > DISTINCT_TABLE:
        return np.unique(q, return_inverse=True)
    k = keys - lo
    present = np.zeros(span, np.bool_)
    present[k] = True
    index = np.cumsum(present) - 1
    return to_value(np.flatnonzero(present) + lo), index[k]


def _prefixes(rep, slot, n_poses: int, deep) -> tuple[np.ndarray, np.ndarray]:
    """(samples, vertices) per pose: the prefixes of the deepest node any of its instances draws."""
    d = np.full(int(n_poses), -1, np.int64)
    np.maximum.at(d, np.asarray(slot, np.int64), np.asarray(deep, np.int64))
    t = rep.tree
    have = d >= 0
    return (np.where(have, t.pprefix[np.maximum(d, 0)], 0).astype(np.int64),
            np.where(have, t.vprefix[np.maximum(d, 0)], 0).astype(np.int64))


def follow_batch(rep, batch, planes, vscale: float, splat: float, rate=KEY_RATE, traverse=None) -> FollowBatch:
    """The :class:`lod.points.rep.FollowBatch` of one culled and located batch of ``rep`` (instances of one
    clip, or one segment): poses quantised (module docstring), the hierarchy traversed at each instance's pose
    (``lod.points.jobs.traverse_instances``), the prefixes of every distinct pose. The batch also keeps each
    instance's point and triangle totals and deepest node (``inst_points``, ``inst_triangles``, ``deep``) for
    :func:`subset` (mode auto's choice among candidates). ``traverse``: a function with
    ``traverse_instances``' signature and results; default :func:`lod.points.jobs.follow_traverse`
    (the same results, each instance's root decided in line: far crowds stop there)."""
    traverse = follow_traverse if traverse is None else traverse

    data = np.array(batch.instance_data, np.float32)
    col = data[:, 12].astype(np.float64)
    if rep.skinned:
        q = quantise_frames(rep.base, int(batch.part), col, rate)
    else:
        q = quantise_u(rep.base, int(batch.part), col, rate)
    data[:, 12] = q
    pose, slot = _distinct(data[:, 12].astype(np.float64))
    pj, tj, psum, tsum, deep = traverse(rep.view(batch.part), data, planes, vscale, splat, totals=True,
                                        deepest=True)
    pts, vts = _prefixes(rep, slot, pose.shape[0], deep)
    fb = FollowBatch(batch.rep, int(batch.part), batch.instance_ids, data, triangles=int(tsum.sum()),
                     points=int(psum.sum()), level=batch.level, tint=batch.tint, fade=batch.fade, point_jobs=pj,
                     tri_jobs=tj, slot=slot.astype(np.int64), pose=pose, pose_points=pts, pose_vertices=vts)
    fb.inst_points, fb.inst_triangles, fb.deep = psum, tsum, deep
    return fb


def subset(rep, fb: FollowBatch, rows) -> FollowBatch | None:
    """The FollowBatch of the instance rows ``rows`` (bool mask or indices) of ``fb`` alone: its jobs
    renumbered, its poses those the rows use, their prefixes recomputed; None when no row is left."""
    take = np.zeros(fb.n_instances, bool)
    take[np.asarray(rows)] = True
    if take.all():
        return fb
    if not take.any():
        return None
    local = np.cumsum(take) - 1
    pj = fb.point_jobs[take[fb.point_jobs[:, 0]]].copy()
    tj = fb.tri_jobs[take[fb.tri_jobs[:, 0]]].copy()
    pj[:, 0] = local[pj[:, 0]]
    tj[:, 0] = local[tj[:, 0]]
    used, slot = np.unique(fb.slot[take], return_inverse=True)
    pts, vts = _prefixes(rep, slot, used.shape[0], fb.deep[take])
    out = FollowBatch(fb.rep, fb.part, fb.instance_ids[take], fb.instance_data[take],
                      triangles=int(fb.inst_triangles[take].sum()), points=int(fb.inst_points[take].sum()),
                      level=fb.level, tint=fb.tint, fade=fb.fade, point_jobs=pj, tri_jobs=tj,
                      slot=slot.astype(np.int64), pose=fb.pose[used], pose_points=pts, pose_vertices=vts)
    out.inst_points, out.inst_triangles, out.deep = fb.inst_points[take], fb.inst_triangles[take], fb.deep[take]
    return out


__all__ = ["KEYFRAMED_KEY_RATE", "KEY_RATE", "follow_batch", "quantise_frames", "quantise_u", "subset"]
