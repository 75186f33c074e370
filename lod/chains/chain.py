"""Triangle LOD chains of skinned characters: level 0 is the full mesh, each
further level a multi-pose QEM simplification (:mod:`lod.simplify`) of the
previous one with every vertex's collapse kept (the geomorph targets), and
their content-addressed cache (``triangles-<sha256>.npz``, written atomically).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.atomic_io import atomic_open
from lod.clusters import poses
from lod.clusters.dag import skin_poses
from lod.clusters.mode import cache_dir, cache_key
from lod.clusters.morph import NEVER_REMOVED
from lod.drawlist import DrawBatch
from lod.full.reps import SkinnedRep
from lod.simplify import collapse as qem
from lod.simplify import distance as qem_distance
from lod.simplify import quadrics as qem_quadrics

#: bump when the cached file layout or its meaning changes
FORMAT_VERSION = 2  # 2: the vertex collapses (geomorph targets)
#: a simplified level's error is at least this fraction of the rest box diagonal
MIN_ERROR_FRACTION = 1e-6
#: the chain stops when a level keeps more than this fraction of the previous one
STALL_FRACTION = 0.9


# ---------------------------------------------------------------------------- rep
@dataclass
class TrianglesRep(SkinnedRep):
    """A :class:`lod.full.reps.SkinnedRep` whose ``indices`` hold a whole LOD chain.

    Extra attributes
    ----------------
    level_first : (L,) int64, first triangle of each level in ``indices``
    level_count : (L,) int64, triangles of each level (level 0 = full mesh)
    level_error : (L,) float64, metres in model space, monotone non-decreasing,
        0 for level 0 and > 0 for every other level
    collapse_next : (V,) int32 or None, the vertex each vertex collapsed onto when
        it left the chain (itself when it never did)
    collapse_level : (V,) int32 or None, the first level without the vertex
        (:data:`lod.clusters.morph.NEVER_REMOVED` when none): following
        ``collapse_next`` while ``collapse_level <= L`` gives the vertex of level L
        a vertex has become (:func:`lod.clusters.morph.chain_targets`)

    ``n_triangles`` and ``part_triangles`` give the full mesh (level 0).
    """

    level_first: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    level_count: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    level_error: np.ndarray = field(default_factory=lambda: np.zeros(1))
    collapse_next: np.ndarray | None = None
    collapse_level: np.ndarray | None = None

    kind = "skinned"

    @property
    def n_levels(self) -> int:
        return int(self.level_count.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.level_count[0])

    def level_indices(self, level: int) -> np.ndarray:
        """(T_level, 3) uint32 triangles of ``level``."""
        a = int(self.level_first[level])
        return self.indices[a:a + int(self.level_count[level])]


@dataclass
class TriangleDrawBatch(DrawBatch):
    """A :class:`lod.drawlist.DrawBatch` drawing one level of a chain:
    ``index_range`` = (first index, index count) into the rep's index buffer
    (indices, i.e. 3 per triangle). ``morph`` = (coarser level, weight in [0, 1])
    or None: the level's vertices are drawn blended by the weight towards the
    vertices they have become in the coarser level (weight 1 draws exactly that
    level's triangles, plus degenerate ones)."""

    index_range: tuple | None = None
    morph: tuple | None = None


# ---------------------------------------------------------------------------- chain
def build_chain(character, skinned: SkinnedRep, levels: int = 7, ratio: float = 0.5):
    """Simplify a skinned character into a discrete LOD chain (module docstring).

    Parameters
    ----------
    character : sim.character.SkinnedCharacter
    skinned : its full-detail :class:`lod.full.reps.SkinnedRep` (indices used as level 0)
    levels : int >= 1, at most this many levels
    ratio : float in (0, 1), target triangles of a level / previous level

    Returns
    -------
    indices : list of (T_k, 3) int64 arrays, level 0 first
    error : (L,) float64 metres, monotone, 0 for level 0, > 0 after
    collapse : ((V,) int32, (V,) int32) the vertex each vertex collapsed onto and the first level
        without it (``TrianglesRep.collapse_next`` / ``collapse_level``)
    """
    levels = int(levels)
    ratio = float(ratio)
    if levels < 1:
        raise ValueError(f"[lod] levels: expected >= 1, got {levels}")
    if not 0.0 < ratio < 1.0:
        raise ValueError(f"[lod] ratio: expected a number in (0, 1), got {ratio}")
    base = np.asarray(skinned.indices, np.int64).reshape(-1, 3)
    chain, errors = [base], [0.0]
    V = int(np.asarray(skinned.positions).shape[0])
    nxt = np.arange(V, dtype=np.int32)
    gone_at = np.full(V, NEVER_REMOVED, np.int32)
    if levels == 1 or base.shape[0] == 0:
        return chain, np.asarray(errors), (nxt, gone_at)
    mats, reps, _ = poses.representative_poses(character)
    X_all = skin_poses(character.mesh, mats)
    X_rep = np.ascontiguousarray(X_all[reps])
    lo, hi = character.rest_bounds()
    floor = MIN_ERROR_FRACTION * max(float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))), 1e-9)
    V = X_all.shape[1]
    original = np.unique(base)
    rep_of = np.arange(V, dtype=np.int64)
    Q = qem_quadrics.plane_quadrics(X_rep, base)
    for _ in range(1, levels):
        prev = chain[-1]
        target = int(prev.shape[0] * ratio)
        new, remap, e = qem.simplify(X_rep, prev, target, quadrics=Q)
        if new.shape[0] == 0 or new.shape[0] > STALL_FRACTION * prev.shape[0]:
            break
        remap = np.asarray(remap, np.int64)
        rep_of = remap[rep_of]
        measured = qem_distance.collapse_distance(X_all, new, original, rep_of)
        err = max(float(e), float(measured), errors[-1], floor)
        if not np.isfinite(err):
            break
        gone = np.flatnonzero(remap != np.arange(remap.shape[0]))  # collapsed onto a survivor of the new level
        nxt[gone] = remap[gone]
        gone_at[gone] = len(chain)
        chain.append(np.asarray(new, np.int64))
        errors.append(err)
    return chain, np.asarray(errors, np.float64), (nxt, gone_at)


def _chain_key(skinned: SkinnedRep, levels: int, ratio: float) -> str:
    h = hashlib.sha256()
    h.update(f"triangles-format-{FORMAT_VERSION}".encode())
    h.update(Path(__file__).read_bytes())
    h.update(cache_key(skinned, {"levels": int(levels), "ratio": float(ratio)}).encode())
    return h.hexdigest()


def _save(path: Path, chain, errors, collapse) -> None:
    with atomic_open(path, "wb") as f:
        np.savez(f, indices=np.concatenate(chain).astype(np.uint32),
                 count=np.asarray([c.shape[0] for c in chain], np.int64), error=np.asarray(errors, np.float64),
                 collapse_next=np.asarray(collapse[0], np.int32), collapse_level=np.asarray(collapse[1], np.int32))


def _load(path: Path, n_vertices: int):
    try:
        with np.load(path) as z:
            idx, count, err = z["indices"], z["count"], z["error"]
            nxt, lvl = z["collapse_next"], z["collapse_level"]
    except Exception as exc:  # truncated, corrupt, wrong layout
        raise ValueError(f"{path}: unreadable chain ({exc})") from exc
    if (idx.ndim != 2 or idx.shape[1] != 3 or count.ndim != 1 or err.shape != count.shape or count.sum() != idx.shape[0]
            or (idx.size and idx.max() >= n_vertices) or not np.isfinite(err).all()
            or nxt.shape != (n_vertices,) or lvl.shape != (n_vertices,)
            or (nxt.size and (nxt.min() < 0 or nxt.max() >= n_vertices))):
        raise ValueError(f"{path}: inconsistent chain arrays")
    moved = np.flatnonzero(nxt != np.arange(n_vertices))
    if np.any(lvl[nxt[moved]] <= lvl[moved]):  # a chain must climb, else the walk could loop
        raise ValueError(f"{path}: inconsistent vertex collapses")
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    return ([idx[a:a + c].astype(np.int64) for a, c in zip(first, count)], err.astype(np.float64),
            (nxt.astype(np.int32), lvl.astype(np.int32)))


def cached_chain(character, skinned: SkinnedRep, levels: int = 7, ratio: float = 0.5, cache: bool = True,
                 directory: Path | None = None):
    """:func:`build_chain`, loaded from / stored to the on-disk cache.

    A cached file that cannot be read is rebuilt and overwritten; an
    unwritable cache folder only costs the rebuild next time.
    """
    if not cache:
        return build_chain(character, skinned, levels, ratio)
    d = Path(directory) if directory is not None else cache_dir()
    path = d / f"triangles-{_chain_key(skinned, levels, ratio)}.npz"
    if path.is_file():
        try:
            return _load(path, skinned.positions.shape[0])
        except ValueError:
            pass
    chain, err, collapse = build_chain(character, skinned, levels, ratio)
    try:
        d.mkdir(parents=True, exist_ok=True)
        _save(path, chain, err, collapse)
    except OSError:
        pass
    return chain, err, collapse


def triangles_rep(skinned: SkinnedRep, chain, errors, collapse=None) -> TrianglesRep:
    """A :class:`TrianglesRep` from a full-detail rep and its chain (``collapse``: the
    vertex collapses of :func:`build_chain`, for geomorphs; None: none)."""
    count = np.asarray([c.shape[0] for c in chain], np.int64)
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    fields = {k: getattr(skinned, k) for k in SkinnedRep.__dataclass_fields__}
    fields["indices"] = np.ascontiguousarray(np.concatenate(chain), np.uint32).reshape(-1, 3)
    nxt, lvl = (None, None) if collapse is None else (np.asarray(collapse[0], np.int32),
                                                      np.asarray(collapse[1], np.int32))
    return TrianglesRep(**fields, level_first=first, level_count=count,
                        level_error=np.asarray(errors, np.float64), collapse_next=nxt, collapse_level=lvl)


__all__ = ["FORMAT_VERSION", "TrianglesRep", "TriangleDrawBatch", "build_chain", "cached_chain", "triangles_rep"]
