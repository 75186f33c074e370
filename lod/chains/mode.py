"""LOD mode ``"triangles"``: a discrete LOD chain per skinned character.

Classic discrete LOD (Luebke et al., *Level of Detail for 3D Graphics*, 2003,
§2.1 and §4.1: a chain of precomputed levels chosen per object by projected
screen-space error). Each level is simplified from the previous one with the
multi-pose quadric error of :mod:`lod.simplify.collapse` (DeCoro & Rusinkiewicz 2005; VDR-AM
§4.3) over the representative poses of the character's clips
(:func:`lod.clusters.poses.representative_poses`, VDR-AM §4.1), so a collapse is cheap
only if it is cheap in every pose. Collapses land on existing vertices, so
every level indexes the original skinned vertex buffer and skins exactly like
the full mesh.

Chain: level 0 is the full mesh, level k+1 targets ``ratio`` times the
triangles of level k; the chain stops early when a level cannot shrink below
``0.9`` times the previous one (locked open borders, tiny closed parts). Each
level's error (metres, model space) is the largest of the quadric estimate and
the measured one-sided distance from every original vertex to the simplified
triangles around the vertex it collapsed into, over *all* sampled poses of all
clips (:func:`lod.simplify.distance.collapse_distance`), made monotone non-decreasing along
the chain; a simplified level never has error exactly 0 (at least
``MIN_ERROR_FRACTION`` of the rest box diagonal), so a bound of 0 always draws
level 0. Bounds over all poses are the full-detail rep's clip bounds: every
level uses a subset of the same skinned vertices, so they hold for every level.

Representation: one :class:`TrianglesRep` per character, a
:class:`lod.full.reps.SkinnedRep` whose ``indices`` are the chain's index buffers
concatenated (vertex data shared by all levels); a batch draws one level
through :attr:`TriangleDrawBatch.index_range` (first index, index count),
which the renderer's skinned path honours. The rep also keeps the collapse of
every vertex (the vertex of the next level it collapsed onto, and that level):
a batch with :attr:`TriangleDrawBatch.morph` draws its level with every vertex
blended towards the vertex it has become in a coarser level (a geomorph between
two keyframe selections, :mod:`lod.temporal.selection`; the same chain walk as
the cluster geomorphs of :mod:`lod.clusters.morph`).

Selection (per instance, every frame): the projected error of level k is
``error_k * s * viewport_scale / d`` pixels, with s the instance's largest axis
scale and d the distance from the camera to the instance's clip bounding
sphere (camera inside the sphere: level 0). The coarsest level whose projected
error is at most ``poe`` pixels is drawn. Instances are culled and packed as in
the full-detail mode and grouped into batches by (character, clip, level).

Cache: chains are stored under ``$CROWD_CACHE_DIR`` (default ``~/.cache/crowd``,
:func:`lod.clusters.mode.cache_dir`) as ``triangles-<sha256>.npz``; the key
extends :func:`lod.clusters.mode.cache_key` with this module's source, the
chain parameters and :data:`FORMAT_VERSION`. Writes are atomic
(:func:`sim.atomic_io.atomic_open`); a file that fails to load is rebuilt.

Morph targets (glTF 2.0 §3.7.2.2): the chain's rep is the full-detail
:class:`lod.full.reps.SkinnedRep` with its :class:`lod.full.targets.TargetTable`,
so every level (whose vertices are original ones) and every geomorph target is
morphed before skinning like level 0; level 0 draws ``skin ∘ morph`` exactly.
The multi-pose simplification and the level errors see the skeletal poses only
(the morph displacements are not part of the error bound).

Keyframed characters fall back to their full-detail representation.
"""
from __future__ import annotations

import numpy as np

from lod.chains.chain import TriangleDrawBatch, TrianglesRep, cached_chain, triangles_rep
from lod.clusters.cut import viewport_scale
from lod.drawlist import DrawList
from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep, build_skinned_rep
from sim.params import Param

#: ``[lod]`` keys of mode "triangles"
PARAMS: dict = {
    "poe": Param("float", 1.0, min=0.0, max=1000.0,
                 doc="pixels of error: the coarsest level whose error projects below this many pixels is drawn"),
    "levels": Param("int", 7, min=1, max=16, doc="levels in each character's chain, level 0 = full mesh"),
    "ratio": Param("float", 0.5, min=0.05, max=0.95,
                   doc="triangles of each level as a fraction of the previous level's"),
}

# ---------------------------------------------------------------------------- selection
def choose_levels(errors: np.ndarray, rows: np.ndarray, sphere: np.ndarray, scale_px: float,
                  poe: float) -> np.ndarray:
    """Per instance, the coarsest level whose projected error is <= ``poe``.

    Parameters
    ----------
    errors : (L,) float64 monotone level errors, metres (model space), errors[0] = 0
    rows : (k, 3, 4) float64 camera-relative model rows (camera at the origin)
    sphere : (4,) float64 model-space bounding sphere over all poses of the clip
    scale_px : pixels per metre at unit distance (:func:`lod.clusters.cut.viewport_scale`)
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
        keyframe levels, :mod:`lod.temporal.selection`)."""
        return {k: r for k, r in self._chains.items() if r.collapse_next is not None}

    def select(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList (see :meth:`lod.full.mode.NoLodSelector.select`).
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


__all__ = ["PARAMS", "TrianglesSelector", "build", "choose_levels", "split_by_level"]
