"""LOD mode ``"triangles"``: a discrete LOD chain per skinned character.

Classic discrete LOD (Luebke et al., *Level of Detail for 3D Graphics*, 2003,
§2.1 and §4.1: a chain of precomputed levels chosen per object by projected
screen-space error). Each level is simplified from the previous one with the
multi-pose quadric error of :mod:`lod.qem` (DeCoro & Rusinkiewicz 2005; VDR-AM
§4.3) over the representative poses of the character's clips
(:func:`lod.poses.representative_poses`, VDR-AM §4.1), so a collapse is cheap
only if it is cheap in every pose. Collapses land on existing vertices, so
every level indexes the original skinned vertex buffer and skins exactly like
the full mesh.

Chain: level 0 is the full mesh, level k+1 targets ``ratio`` times the
triangles of level k; the chain stops early when a level cannot shrink below
``0.9`` times the previous one (locked open borders, tiny closed parts). Each
level's error (metres, model space) is the largest of the quadric estimate and
the measured one-sided distance from every original vertex to the simplified
triangles around the vertex it collapsed into, over *all* sampled poses of all
clips (:func:`lod.qem.collapse_distance`), made monotone non-decreasing along
the chain; a simplified level never has error exactly 0 (at least
``MIN_ERROR_FRACTION`` of the rest box diagonal), so a bound of 0 always draws
level 0. Bounds over all poses are the full-detail rep's clip bounds: every
level uses a subset of the same skinned vertices, so they hold for every level.

Representation: one :class:`TrianglesRep` per character, a
:class:`lod.nolod.SkinnedRep` whose ``indices`` are the chain's index buffers
concatenated (vertex data shared by all levels); a batch draws one level
through :attr:`TriangleDrawBatch.index_range` (first index, index count),
which the renderer's skinned path honours. The rep also keeps the collapse of
every vertex (the vertex of the next level it collapsed onto, and that level):
a batch with :attr:`TriangleDrawBatch.morph` draws its level with every vertex
blended towards the vertex it has become in a coarser level (a geomorph between
two keyframe selections, :mod:`lod.keyframed_selection`; the same chain walk as
the cluster geomorphs of :mod:`lod.cluster_morph`).

Selection (per instance, every frame): the projected error of level k is
``error_k * s * viewport_scale / d`` pixels, with s the instance's largest axis
scale and d the distance from the camera to the instance's clip bounding
sphere (camera inside the sphere: level 0). The coarsest level whose projected
error is at most ``poe`` pixels is drawn. Instances are culled and packed as in
the full-detail mode and grouped into batches by (character, clip, level).

Cache: chains are stored under ``$CROWD_CACHE_DIR`` (default ``~/.cache/crowd``,
:func:`lod.clusters_mode.cache_dir`) as ``triangles-<sha256>.npz``; the key
extends :func:`lod.clusters_mode.cache_key` with this module's source, the
chain parameters and :data:`FORMAT_VERSION`. Writes are atomic
(:func:`lod.atomic_io.atomic_open`); a file that fails to load is rebuilt.

Keyframed characters fall back to their full-detail representation.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lod import poses, qem
from lod.atomic_io import atomic_open
from lod.cluster_cut import viewport_scale
from lod.cluster_dag import skin_poses
from lod.cluster_morph import NEVER_REMOVED
from lod.clusters_mode import cache_dir, cache_key
from lod.drawlist import DrawBatch, DrawList
from lod.nolod import NoLodSelector, SkinnedRep, build_rep, build_skinned_rep
from sim.params import Param

#: bump when the cached file layout or its meaning changes
FORMAT_VERSION = 2  # 2: the vertex collapses (geomorph targets)
#: a simplified level's error is at least this fraction of the rest box diagonal
MIN_ERROR_FRACTION = 1e-6
#: the chain stops when a level keeps more than this fraction of the previous one
STALL_FRACTION = 0.9

#: ``[lod]`` keys of mode "triangles"
PARAMS: dict = {
    "poe": Param("float", 1.0, min=0.0, max=1000.0,
                 doc="pixels of error: the coarsest level whose error projects below this many pixels is drawn"),
    "levels": Param("int", 7, min=1, max=16, doc="levels in each character's chain, level 0 = full mesh"),
    "ratio": Param("float", 0.5, min=0.05, max=0.95,
                   doc="triangles of each level as a fraction of the previous level's"),
}


# ---------------------------------------------------------------------------- rep
@dataclass
class TrianglesRep(SkinnedRep):
    """A :class:`lod.nolod.SkinnedRep` whose ``indices`` hold a whole LOD chain.

    Extra attributes
    ----------------
    level_first : (L,) int64, first triangle of each level in ``indices``
    level_count : (L,) int64, triangles of each level (level 0 = full mesh)
    level_error : (L,) float64, metres in model space, monotone non-decreasing,
        0 for level 0 and > 0 for every other level
    collapse_next : (V,) int32 or None, the vertex each vertex collapsed onto when
        it left the chain (itself when it never did)
    collapse_level : (V,) int32 or None, the first level without the vertex
        (:data:`lod.cluster_morph.NEVER_REMOVED` when none): following
        ``collapse_next`` while ``collapse_level <= L`` gives the vertex of level L
        a vertex has become (:func:`lod.cluster_morph.chain_targets`)

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
    skinned : its full-detail :class:`lod.nolod.SkinnedRep` (indices used as level 0)
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
    Q = qem.plane_quadrics(X_rep, base)
    for _ in range(1, levels):
        prev = chain[-1]
        target = int(prev.shape[0] * ratio)
        new, remap, e = qem.simplify(X_rep, prev, target, quadrics=Q)
        if new.shape[0] == 0 or new.shape[0] > STALL_FRACTION * prev.shape[0]:
            break
        remap = np.asarray(remap, np.int64)
        rep_of = remap[rep_of]
        measured = qem.collapse_distance(X_all, new, original, rep_of)
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


# ---------------------------------------------------------------------------- selection
def choose_levels(errors: np.ndarray, rows: np.ndarray, sphere: np.ndarray, scale_px: float,
                  poe: float) -> np.ndarray:
    """Per instance, the coarsest level whose projected error is <= ``poe``.

    Parameters
    ----------
    errors : (L,) float64 monotone level errors, metres (model space), errors[0] = 0
    rows : (k, 3, 4) float64 camera-relative model rows (camera at the origin)
    sphere : (4,) float64 model-space bounding sphere over all poses of the clip
    scale_px : pixels per metre at unit distance (:func:`lod.cluster_cut.viewport_scale`)
    poe : pixels of error >= 0

    Returns
    -------
    (k,) int64 levels; 0 where the camera is inside the instance's sphere.
    """
    rows = np.asarray(rows, np.float64).reshape(-1, 3, 4)
    s = np.linalg.norm(rows[:, :, :3], axis=1).max(axis=1)
    c = rows[:, :, :3] @ np.asarray(sphere[:3], np.float64) + rows[:, :, 3]
    d = np.linalg.norm(c, axis=1) - float(sphere[3]) * s
    inside = ~(d > 0.0)
    px = np.asarray(errors, np.float64)[None, :] * (s * scale_px / np.where(inside, 1.0, d))[:, None]
    lvl = (px <= float(poe)).sum(axis=1) - 1  # errors monotone: the passing levels are a prefix
    lvl = np.maximum(lvl, 0)
    lvl[inside] = 0
    return lvl.astype(np.int64)


class TrianglesSelector:
    """Cull and pack as the full-detail mode, then give each instance of a
    chained character the coarsest level within ``poe`` pixels.

    Parameters
    ----------
    reps : list aligned with ``CrowdState.character``: :class:`TrianglesRep`
        for skinned characters, full-detail reps for the others
    static_reps : StaticRep scenery ``select`` may be asked to draw
    poe : float >= 0, pixels of error
    cull : frustum culling of instances on (default)
    """

    def __init__(self, reps, static_reps=(), poe: float = 1.0, cull: bool = True):
        if not (np.isfinite(poe) and float(poe) >= 0.0):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {poe}")
        self.poe = float(poe)
        self.reps = list(reps)
        self._chains = {r.key: r for r in self.reps if isinstance(r, TrianglesRep)}
        self._inner = NoLodSelector(self.reps, static_reps=static_reps, cull=cull)
        self._n_levels = max([r.n_levels for r in self._chains.values()] or [1])

    def chain_reps(self) -> dict:
        """{rep key: TrianglesRep} of the chains with vertex collapses (for geomorphs between
        keyframe levels, :mod:`lod.keyframed_selection`)."""
        return {k: r for k, r in self._chains.items() if r.collapse_next is not None}

    def select(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList (see :meth:`lod.nolod.NoLodSelector.select`).
        Batches of chained characters are :class:`TriangleDrawBatch` with
        ``level`` and ``index_range`` set, sorted by (rep, clip, level);
        ``stats["triangles"]`` counts the drawn levels and ``stats["levels"]``
        (list) the character instances drawn at each level (fallback reps at 0)."""
        if not (np.isfinite(self.poe) and self.poe >= 0.0):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {self.poe}")
        dl = self._inner.select(state, camera, size, statics)
        scale_px = viewport_scale(max(1, int(size[1])), camera.fov_y)
        split_by_level(dl, self._chains, self._n_levels,
                       lambda r, b, rows: choose_levels(r.level_error, rows, r.clip_sphere[b.part], scale_px, self.poe))
        return dl


def split_by_level(dl, chains: dict, n_levels: int, levels_of) -> np.ndarray:
    """Split the full-detail batches of ``dl`` into one batch per chain level, in place.

    chains : rep key -> :class:`TrianglesRep`; batches of other reps are kept as they are (level 0)
    levels_of : ``levels_of(rep, batch, rows)`` -> (k,) int level per instance of the batch, where rows
        (k, 3, 4) float64 are the instances' camera-relative model matrices
    Returns the (n_levels,) int64 instance count per level; sets stats "triangles", "batches", "levels".
    """
    counts = np.zeros(n_levels, np.int64)
    out = []
    for b in dl.batches:
        r = chains.get(b.rep)
        if r is None:
            if int(np.asarray(b.instance_ids).size) and int(b.instance_ids[0]) >= 0:
                counts[0] += b.n_instances
            out.append(b)
            continue
        rows = np.asarray(b.instance_data, np.float32)[:, :12].astype(np.float64).reshape(-1, 3, 4)
        lvl = np.asarray(levels_of(r, b, rows))
        order = np.argsort(lvl, kind="stable")
        ls = lvl[order]
        for L in np.unique(ls).tolist():
            sel = order[ls == L]
            n_t = int(r.level_count[L])
            out.append(TriangleDrawBatch(b.rep, b.part, b.instance_ids[sel], b.instance_data[sel],
                                         triangles=n_t * int(sel.size), level=int(L), tint=b.tint,
                                         index_range=(3 * int(r.level_first[L]), 3 * n_t)))
            counts[L] += sel.size
    dl.batches = out
    dl.stats["triangles"] = int(sum(b.triangles for b in out))
    dl.stats["batches"] = len(out)
    dl.stats["levels"] = [int(c) for c in counts]
    return counts


# ---------------------------------------------------------------------------- mode protocol
def build(characters, names, fps, params, static_reps=(), progress=None, cache: bool = True):
    """Mode "triangles" for ``lod.modes``: a :class:`TrianglesRep` per skinned
    character (chain built or loaded from the cache), full-detail reps for the
    others, and a :class:`TrianglesSelector`.

    Parameters
    ----------
    characters, names, fps, params, static_reps, progress : see ``lod.modes``
    cache : use the on-disk chain cache (default)
    """
    params = dict(params or {})
    poe = float(params.get("poe", PARAMS["poe"].default))
    levels = int(params.get("levels", PARAMS["levels"].default))
    ratio = float(params.get("ratio", PARAMS["ratio"].default))
    items = list(zip(characters, names, fps))
    if callable(progress):
        items = progress(items, "triangle LOD chains")
    reps = []
    for ch, name, f in items:
        key = f"triangles:{name}"
        if getattr(ch, "kind", "") == "skinned" and ch.mesh.is_skinned:
            sk = build_skinned_rep(ch, fps=f, key=key)
            chain, err, collapse = cached_chain(ch, sk, levels, ratio, cache=cache)
            reps.append(triangles_rep(sk, chain, err, collapse))
        else:
            reps.append(build_rep(ch, fps=f, key=key))
    return reps, TrianglesSelector(reps, static_reps=static_reps, poe=poe)


__all__ = ["PARAMS", "FORMAT_VERSION", "TrianglesRep", "TriangleDrawBatch", "TrianglesSelector", "build",
           "build_chain", "cached_chain", "choose_levels", "triangles_rep"]
