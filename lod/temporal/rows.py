"""Per-row payloads of the DrawList's batch types for the keyframed selection (Friedrich, Polthier & Schmies:
selection every n-th frame, the frames between drawn from it): a row's signature and counts, taking rows of a
batch for a subset of its agents, and the agents' state subset. Re-exported by :mod:`lod.temporal.selection`."""
from __future__ import annotations

import copy
from dataclasses import fields, is_dataclass

import numpy as np


_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def _mix64(x: np.ndarray) -> np.ndarray:
    """splitmix64 finaliser of (m,) uint64 (a well-mixed hash per element)."""
    x = np.asarray(x).astype(np.uint64)
    with np.errstate(over="ignore"):
        x = (x ^ (x >> np.uint64(30))) * _M1
        x = (x ^ (x >> np.uint64(27))) * _M2
        return x ^ (x >> np.uint64(31))


def _is_csr(b) -> bool:
    return hasattr(b, "offsets") and hasattr(b, "clusters")


def part_dependent(b) -> bool:
    """Whether batch ``b``'s payload is only valid for its ``part``: point and
    triangle jobs (``*_jobs``) index one keyframe segment's octree. A LOD chain
    level, a cluster cut or a whole part do not depend on the clip, so an
    instance whose clip changed between keyframes keeps its representation."""
    return bool(_job_fields(b))


_JOB_FIELDS: dict = {}
#: optional per-entry arrays of a CSR batch, aligned with ``clusters`` (lod.clusters.mode.ClusterDrawBatch)
_ENTRY_FIELDS = ("morph_height", "morph_weight")


def _job_fields(b) -> tuple:
    t = type(b)
    names = _JOB_FIELDS.get(t)
    if names is None:
        names = _JOB_FIELDS[t] = tuple(f.name for f in fields(b) if f.name.endswith("_jobs"))
    return names


def row_signatures(b) -> np.ndarray:
    """(k,) uint64 hash per instance row of batch ``b`` of what it draws.

    The representation (``rep``, ``level``, ``index_range``, and ``part`` for a
    :func:`part_dependent` batch) plus the
    row's own payload: its cluster cut (``offsets``/``clusters`` CSR, as a
    multiset) or its ``*_jobs`` rows ``(row, first, count)`` (points mode).
    Two rows with equal signatures draw the same thing (up to hash collisions,
    2^-64).
    """
    k = b.n_instances
    # the part only matters where the payload depends on it (a clip change keeps a chain level or a cut)
    head = hash((b.rep, int(b.part) if part_dependent(b) else -1, int(getattr(b, "level", 0)),
                 tuple(int(v) for v in (getattr(b, "index_range", None) or ()))))
    sig = np.full(k, np.uint64(head & 0xFFFFFFFFFFFFFFFF), np.uint64)
    if _is_csr(b):
        off = np.asarray(b.offsets, np.int64)
        h = _mix64(np.asarray(b.clusters, np.int64) + 1)
        cs = np.zeros(h.shape[0] + 1, np.uint64)
        with np.errstate(over="ignore"):
            np.cumsum(h, out=cs[1:])
            sig = sig ^ _mix64(cs[off[1:]] - cs[off[:-1]])
    for salt, name in enumerate(_job_fields(b), start=1):
        j = np.asarray(getattr(b, name), np.int64).reshape(-1, 3)
        if not j.shape[0]:
            continue
        with np.errstate(over="ignore"):
            h = _mix64(_mix64(j[:, 1] * 1_000_003 + salt) + j[:, 2].astype(np.uint64))
            acc = np.zeros(k, np.uint64)
            np.add.at(acc, j[:, 0], h)
            sig = sig ^ _mix64(acc + np.uint64(salt))
    return sig


def row_counts(b) -> tuple[np.ndarray, np.ndarray]:
    """(k,) float64 triangles and points per instance row of ``b``: from the
    ``tri_jobs`` / ``point_jobs`` rows when present, else ``b.triangles`` /
    ``b.points`` shared among the rows (in proportion to the clusters of each
    row's cut for a cluster batch: an estimate, exact for equal-size clusters)."""
    k = b.n_instances
    tri = np.full(k, float(b.triangles) / max(k, 1))
    pts = np.full(k, float(b.points) / max(k, 1))
    if _is_csr(b):
        n = np.diff(np.asarray(b.offsets, np.int64)).astype(np.float64)
        if n.sum() > 0:
            tri = float(b.triangles) * n / n.sum()
    if hasattr(b, "tri_jobs"):
        j = np.asarray(b.tri_jobs, np.int64).reshape(-1, 3)
        tri = np.bincount(j[:, 0], weights=j[:, 2], minlength=k).astype(np.float64)[:k]
    if hasattr(b, "point_jobs"):
        j = np.asarray(b.point_jobs, np.int64).reshape(-1, 3)
        pts = np.bincount(j[:, 0], weights=j[:, 2], minlength=k).astype(np.float64)[:k]
    return tri, pts


def take_rows(b, rows: np.ndarray, ids: np.ndarray, data: np.ndarray, fade=None, triangles: int = 0,
              points: int = 0, part: int | None = None):
    """A batch of ``b``'s type drawing the instance rows ``rows`` of ``b``
    with new instance ids / data (the current frame's transforms).

    Parameters
    ----------
    b : DrawBatch (or a subclass: per-row CSR ``offsets``/``clusters`` (with
        their per-entry ``morph_height``/``morph_weight``) and ``*_jobs`` arrays
        are subset and renumbered; other fields are copied)
    rows : (m,) int64 rows of ``b``
    ids : (m,) int32 agent ids; data : (m, 16) float32 instance data
    fade : ``DrawBatch.fade`` of the new batch
    triangles, points : counts of the new batch
    part : the new batch's part (default ``b.part``; only for a batch that is
        not :func:`part_dependent`)

    A batch type may provide its own ``take_rows(rows, ids, data)`` method.
    """
    rows = np.asarray(rows, np.int64)
    own = getattr(b, "take_rows", None)
    if callable(own):
        out = own(rows, ids, data)
        out.fade, out.triangles, out.points = fade, int(triangles), int(points)
        if part is not None:
            out.part = int(part)
        return out
    kw = dict(instance_ids=np.asarray(ids, np.int32), instance_data=np.asarray(data, np.float32), fade=fade,
              triangles=int(triangles), points=int(points))
    if part is not None:
        kw["part"] = int(part)
    if _is_csr(b):
        off = np.asarray(b.offsets, np.int64)
        lens = off[rows + 1] - off[rows]
        new_off = np.zeros(rows.shape[0] + 1, np.int64)
        np.cumsum(lens, out=new_off[1:])
        src = np.repeat(off[rows] - new_off[:-1], lens) + np.arange(int(new_off[-1]))
        kw["offsets"] = new_off
        kw["clusters"] = np.asarray(b.clusters)[src]
        for name in _ENTRY_FIELDS:  # per-entry arrays aligned with the cut (a geomorphed union's)
            v = getattr(b, name, None)
            if v is not None:
                kw[name] = np.asarray(v)[src]
    if _job_fields(b):
        pos = np.full(b.n_instances, -1, np.int64)
        pos[rows] = np.arange(rows.shape[0])
        for name in _job_fields(b):
            j = np.asarray(getattr(b, name), np.int64).reshape(-1, 3)
            j = j[pos[j[:, 0]] >= 0].copy() if j.shape[0] else j.copy()
            j[:, 0] = pos[j[:, 0]]
            kw[name] = j
    out = copy.copy(b)  # a shallow copy keeps the batch-wide fields (rep, level, index_range, tint, ...)
    for k, v in kw.items():
        setattr(out, k, v)
    return out


def subset_state(state, ids: np.ndarray):
    """The agents ``ids`` ((m,) int64) of a ``sim.state.CrowdState`` (or of a
    namespace of per-agent arrays with an ``n``) as a new state of the same kind."""
    ids = np.asarray(ids, np.int64)
    if is_dataclass(state):
        return type(state)(**{f.name: np.asarray(getattr(state, f.name))[ids] for f in fields(state)})
    n = int(state.n)
    out = {k: (np.asarray(v)[ids] if isinstance(v, np.ndarray) and v.shape[:1] == (n,) else v)
           for k, v in vars(state).items()}
    out["n"] = int(ids.shape[0])
    return type(state)(**out)


__all__ = ["part_dependent", "row_counts", "row_signatures", "subset_state", "take_rows"]
