"""LOD mode ``"clusters"``: per-instance cuts of VDR-AM cluster hierarchies.

Claudio, Kim, Kim, Yoon, *VDR-AM: View-Dependent Representation of Articulated
Models*. The hierarchy of every skinned character is built once (§4,
:func:`lod.clusters.dag.build_cluster_hierarchy`) or loaded from an on-disk
cache; each frame, every visible instance gets its own LOD cut by pixels of
error (§5.1, :func:`lod.clusters.cut.cut`) and the renderer draws the selected
clusters with GPU skinning (``render/clusters/draw.py``).

Batching: instances are culled and packed exactly as in the full-detail mode
(:class:`lod.full.mode.NoLodSelector`, one :class:`ClusterDrawBatch` per
(character, clip)); each batch carries the CSR cut of its instances. The
drawer merges the batches of one character, groups instances by identical cut
and submits one multi-draw-indirect call per character, one command per
distinct cut (drawn instanced), so the draw-call count stays at one per
character whatever the number of instances, and instances far away (whose cut
is the same few coarse clusters) share their command.

Characters without a skin (keyframed) fall back to their full-detail
representation.

Morph targets (glTF 2.0 §3.7.2.2, ``sim.mesh.MorphTargets``) are ignored: the
hierarchy is built from, and the clusters are drawn as, the skinned mesh at its
default morph weights (``build_skinned_rep(..., morph_targets=False)``), and the
cache key is that of the same character without morph targets. VDR-AM models
articulated (skeletal) motion only (§4: poses are joint transforms); the
deformation levels, multi-pose quadrics and cut errors would all have to
account for the morphs. Modes ``"none"`` and ``"triangles"`` draw them.

Cache: a hierarchy is stored under ``$CROWD_CACHE_DIR`` (default
``~/.cache/crowd``) as ``clusters-<sha256>.npz``, the key hashing the mesh, the
skin, the clips (as the baked skinning-matrix table), the build parameters,
:data:`FORMAT_VERSION` and the source of the build modules; files are written
atomically (temp file + rename), and a file that fails to load is rebuilt.
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit

from lod.clusters import cut as cluster_cut
from lod.clusters.config import CLUSTERS_DEFAULT_POE, CLUSTERS_LEAF_TRIANGLES
from lod.clusters.dag import ClusterHierarchy, build_cluster_hierarchy
from lod.drawlist import DrawBatch, DrawList
from lod.full.mode import NoLodSelector
from lod.full.reps import SkinnedRep, build_rep, build_skinned_rep
from sim.params import Param

#: bump when the cached file layout or its meaning changes
FORMAT_VERSION = 2  # 2: geomorph targets (morph_ptr, morph_vertex, morph_target)
#: environment variable naming the cache folder
CACHE_ENV = "CROWD_CACHE_DIR"
#: modules whose source is part of the cache key (a changed algorithm rebuilds)
_BUILD_MODULES = ("clusters/dag.py", "clusters/clustering.py", "simplify/quadrics.py", "simplify/kernels.py",
                  "simplify/collapse.py", "simplify/distance.py", "clusters/poses.py", "clusters/deformation.py",
                  "clusters/config.py")

#: ``[lod]`` keys of mode "clusters"
PARAMS: dict = {
    "poe": Param("float", CLUSTERS_DEFAULT_POE, min=0.0, max=1000.0,
                 doc="pixels of error: a cluster is drawn when its error projects below this many pixels (§5.1)"),
    "occlusion": Param("bool", False, doc="GL occlusion queries on cluster boxes (§5.2)"),
    "occlusion_every": Param("int", 8, min=1, max=10000,
                             doc="frames between rebuilds of the potentially visible set (§5.2)"),
    "clustering": Param("str", "error-aware", choices=("error-aware", "octree"),
                        doc="leaf clustering: error-aware (§4.2) or the octree baseline (§6)"),
    "leaf_triangles": Param("int", CLUSTERS_LEAF_TRIANGLES, min=8, max=1_000_000,
                            doc="§4.2 s: clusters of more triangles are split (the paper's default 100); larger "
                                "leaves leave fewer locked borders, so far cuts keep fewer triangles "
                                "(scripts/bench_clusters.md)"),
}


# ---------------------------------------------------------------------------- rep
@dataclass
class ClustersRep:
    """A skinned character drawn as per-instance cuts of its cluster hierarchy.

    Attributes
    ----------
    key : str, ``"clusters:<name>"``
    skinned : lod.full.reps.SkinnedRep with the same key: vertex buffer, skin and
        baked joint table (the same as the full-detail path, so both skin alike)
    hierarchy : lod.clusters.dag.ClusterHierarchy; its ``indices`` index
        ``skinned.positions``
    occlusion : bool, occlusion culling requested (§5.2)
    occlusion_every : int, frames between rebuilds of the visible set
    """

    key: str
    skinned: SkinnedRep
    hierarchy: ClusterHierarchy
    occlusion: bool = False
    occlusion_every: int = 8

    kind = "clusters"

    @property
    def sphere64(self) -> np.ndarray:
        """(N, 4) float64 cluster spheres (cached), for per-frame culling."""
        s = self.__dict__.get("_sphere64")
        if s is None:
            s = np.ascontiguousarray(self.hierarchy.sphere, np.float64)
            self.__dict__["_sphere64"] = s
        return s

    @property
    def n_parts(self) -> int:
        return self.skinned.n_parts

    @property
    def n_triangles(self) -> int:
        return self.skinned.n_triangles

    def part_sphere(self) -> np.ndarray:
        return self.skinned.part_sphere()

    def part_triangles(self) -> np.ndarray:
        return self.skinned.part_triangles()


@dataclass
class ClusterDrawBatch(DrawBatch):
    """A :class:`lod.drawlist.DrawBatch` of a :class:`ClustersRep` with the
    instances' cuts (CSR): instance i draws clusters
    ``clusters[offsets[i]:offsets[i+1]]``.

    offsets : (k+1,) int64; clusters : (offsets[-1],) int32 cluster ids
    morph_height, morph_weight : None, or (offsets[-1],) int32 / float32 per cluster
        entry: a geomorphed union of two cuts (:mod:`lod.clusters.morph`, drawn by
        ``render/shaders/clusters/clusters_morph.vert``): the entry's vertices are blended
        with weight ``morph_weight`` towards the vertices they collapse into in
        the ancestor cluster of height ``morph_height`` (-1: drawn unmoved)
    """

    offsets: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    clusters: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    morph_height: np.ndarray | None = None
    morph_weight: np.ndarray | None = None


# ---------------------------------------------------------------------------- cache
def cache_dir() -> Path:
    """The hierarchy cache folder: ``$CROWD_CACHE_DIR`` or ``~/.cache/crowd``."""
    d = os.environ.get(CACHE_ENV, "")
    return Path(d).expanduser() if d else Path.home() / ".cache" / "crowd"


def _source_digest() -> str:
    h = hashlib.sha256()
    here = Path(__file__).resolve().parent.parent  # lod/
    for name in _BUILD_MODULES:
        p = here / name
        h.update(name.encode())
        h.update(p.read_bytes() if p.is_file() else b"")
    return h.hexdigest()


def cache_key(skinned: SkinnedRep, build_params: dict) -> str:
    """sha256 hex of everything a hierarchy depends on.

    Parameters
    ----------
    skinned : lod.full.reps.SkinnedRep of the character (mesh, skin, clips baked)
    build_params : dict of JSON-serialisable build parameters
    """
    h = hashlib.sha256()
    h.update(f"clusters-format-{FORMAT_VERSION}".encode())
    h.update(_source_digest().encode())
    # the progress bar does not change the hierarchy
    h.update(json.dumps({k: v for k, v in build_params.items() if k != "progress"}, sort_keys=True).encode())
    for a in (skinned.positions, skinned.indices, skinned.joints, skinned.weights, skinned.joint_table,
              skinned.clip_duration, skinned.clip_loop):
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    h.update(json.dumps(list(skinned.clip_names)).encode())
    return h.hexdigest()


def cached_hierarchy(character, skinned: SkinnedRep, build_params: dict, cache: bool = True,
                     directory: Path | None = None, quiet: bool = False) -> ClusterHierarchy:
    """Load the character's hierarchy from the cache, or build and store it.

    A cached file that cannot be read (truncated, corrupt, wrong layout) is
    rebuilt and overwritten; the write is atomic (temp file + rename), so
    concurrent runs never read a half-written file. An unwritable cache folder
    only costs the rebuild next time. ``quiet`` hides the build's progress bar.
    """
    build_params = dict(build_params)
    bar = build_params.pop("progress", False if quiet else None)  # None: a bar once the build has run a second
    if not cache:
        return build_cluster_hierarchy(character, **build_params, progress=bar)
    d = Path(directory) if directory is not None else cache_dir()
    path = d / f"clusters-{cache_key(skinned, build_params)}.npz"
    if path.is_file():
        try:
            return ClusterHierarchy.load(path)
        except ValueError:
            pass  # corrupt: rebuild below
    h = build_cluster_hierarchy(character, **build_params, progress=bar)
    try:
        d.mkdir(parents=True, exist_ok=True)
        h.save(path)
    except OSError:
        pass
    return h


# ---------------------------------------------------------------------------- cluster frustum culling
def cull_clusters_numpy(sphere, rows, offsets, clusters, planes):
    """Reference of :func:`cull_clusters`: drop the clusters of each cut whose
    bounding sphere (all poses) lies outside a frustum plane.

    Parameters
    ----------
    sphere : (N, 4) float model-space cluster spheres (centre, radius)
    rows : (k, 3, 4) float64 camera-relative model rows of the k instances
    offsets : (k+1,) int64; clusters : int32 CSR cuts
    planes : (P, 4) float64 camera-relative planes (inside: n.x + d >= 0)

    Returns
    -------
    offsets (k+1,) int64, clusters int32: the cuts without the culled clusters
    """
    k = rows.shape[0]
    keep_off = [0]
    keep = []
    for i in range(k):
        c = clusters[offsets[i]:offsets[i + 1]]
        s = np.asarray(sphere, np.float64)[c]
        cen = s[:, :3] @ rows[i, :, :3].T + rows[i, :, 3]
        r = s[:, 3] * np.linalg.norm(rows[i, :, :3], axis=0).max()
        dist = cen @ planes[:, :3].T + planes[:, 3]
        inside = np.all(dist >= -r[:, None], axis=1)
        keep.append(c[inside])
        keep_off.append(keep_off[-1] + int(inside.sum()))
    cl = np.concatenate(keep).astype(np.int32) if keep else np.zeros(0, np.int32)
    return np.asarray(keep_off, np.int64), cl


@njit(cache=True)
def _cull_kernel(sphere, rows, offsets, clusters, planes, out_off, out):  # pragma: no cover - compiled
    n = 0
    for i in range(rows.shape[0]):
        s0 = np.sqrt(rows[i, 0, 0] ** 2 + rows[i, 1, 0] ** 2 + rows[i, 2, 0] ** 2)
        s1 = np.sqrt(rows[i, 0, 1] ** 2 + rows[i, 1, 1] ** 2 + rows[i, 2, 1] ** 2)
        s2 = np.sqrt(rows[i, 0, 2] ** 2 + rows[i, 1, 2] ** 2 + rows[i, 2, 2] ** 2)
        sc = max(s0, max(s1, s2))
        for j in range(offsets[i], offsets[i + 1]):
            c = clusters[j]
            x, y, z = sphere[c, 0], sphere[c, 1], sphere[c, 2]
            r = sphere[c, 3] * sc
            ok = True
            cx = rows[i, 0, 0] * x + rows[i, 0, 1] * y + rows[i, 0, 2] * z + rows[i, 0, 3]
            cy = rows[i, 1, 0] * x + rows[i, 1, 1] * y + rows[i, 1, 2] * z + rows[i, 1, 3]
            cz = rows[i, 2, 0] * x + rows[i, 2, 1] * y + rows[i, 2, 2] * z + rows[i, 2, 3]
            for p in range(planes.shape[0]):
                if planes[p, 0] * cx + planes[p, 1] * cy + planes[p, 2] * cz + planes[p, 3] < -r:
                    ok = False
                    break
            if ok:
                out[n] = c
                n += 1
        out_off[i + 1] = n
    return n


def cull_clusters(sphere, rows, offsets, clusters, planes):
    """Frustum culling of the clusters of each cut (numba; see :func:`cull_clusters_numpy`).

    A cut stays a consistent cover of what is inside the frustum: only
    clusters whose sphere (which holds the cluster in every pose) is wholly
    outside one plane are dropped, so nothing visible is lost.
    """
    rows = np.ascontiguousarray(rows, np.float64)
    out_off = np.zeros(rows.shape[0] + 1, np.int64)
    out = np.empty(clusters.shape[0], np.int32)
    n = _cull_kernel(np.asarray(sphere, np.float64), rows, np.asarray(offsets, np.int64),
                     np.asarray(clusters, np.int32), np.ascontiguousarray(planes, np.float64), out_off, out)
    return out_off, out[:n].copy()


# ---------------------------------------------------------------------------- selector
def _model_rows(instance_data: np.ndarray) -> np.ndarray:
    """(k, 3, 4) float64 camera-relative model rows of DrawBatch instance data."""
    return np.asarray(instance_data, np.float32)[:, :12].astype(np.float64).reshape(-1, 3, 4)


class ClustersSelector:
    """Cull and pack instances as the full-detail mode, then cut each one (§5.1)
    and drop the clusters of the cut that lie outside the view frustum.

    Parameters
    ----------
    reps : list aligned with ``CrowdState.character``: :class:`ClustersRep`
        for skinned characters, full-detail reps for the others
    static_reps : StaticRep scenery ``select`` may be asked to draw
    poe : float >= 0, pixels of error
    cull : frustum culling of instances and clusters on (default)
    """

    def __init__(self, reps, static_reps=(), poe: float = CLUSTERS_DEFAULT_POE, cull: bool = True):
        if not (float(poe) >= 0.0 and np.isfinite(poe)):
            raise ValueError(f"[lod] poe: expected a finite number >= 0, got {poe}")
        self.poe = float(poe)
        self.reps = list(reps)
        self._clusters = {r.key: r for r in self.reps if r.kind == "clusters"}
        self._inner = NoLodSelector([r.skinned if r.kind == "clusters" else r for r in self.reps],
                                    static_reps=static_reps, cull=cull)
        self._ws = cluster_cut.CutWorkspace()
        #: frustum culling of instances and, after the cut, of clusters
        self.cull = bool(cull)
        #: seconds spent in the cut (§5.1) during the last ``select``
        self.last_cut_seconds = 0.0

    def cluster_hierarchies(self) -> dict:
        """{rep key: ClusterHierarchy} of the clustered characters (for geomorphs between
        keyframe cuts, :mod:`lod.temporal.selection`)."""
        return {k: r.hierarchy for k, r in self._clusters.items()}

    def select(self, state, camera, size, statics=()) -> DrawList:
        """The frame's DrawList (see :meth:`lod.full.mode.NoLodSelector.select`);
        batches of clustered characters are :class:`ClusterDrawBatch` and
        ``stats`` gains "clusters" (clusters drawn) and counts the cuts' triangles."""
        dl = self._inner.select(state, camera, size, statics)
        planes = camera.frustum_planes(max(1, int(size[0])) / max(1, int(size[1])))
        scale = cluster_cut.viewport_scale(max(1, int(size[1])), camera.fov_y)
        out = []
        n_clusters = 0
        t_cut = 0.0
        for b in dl.batches:
            r = self._clusters.get(b.rep)
            if r is None:
                out.append(b)
                continue
            h = r.hierarchy
            rows = _model_rows(b.instance_data)
            t0 = time.perf_counter()
            offsets, clusters = cluster_cut.cut(h, rows, np.zeros(3), scale, self.poe, self._ws)
            t_cut += time.perf_counter() - t0
            if self.cull:
                offsets, clusters = cull_clusters(r.sphere64, rows, offsets, clusters, planes)
            tris = int(cluster_cut.cut_triangle_count(h, offsets, clusters).sum())
            n_clusters += int(clusters.shape[0])
            out.append(ClusterDrawBatch(b.rep, b.part, b.instance_ids, b.instance_data, triangles=tris,
                                        points=0, level=b.level, tint=b.tint, offsets=offsets, clusters=clusters))
        dl.batches = out
        self.last_cut_seconds = t_cut
        dl.stats["triangles"] = int(sum(b.triangles for b in out))
        dl.stats["clusters"] = n_clusters
        return dl


# ---------------------------------------------------------------------------- mode protocol
def build_params_of(params: dict) -> dict:
    """Hierarchy build parameters taken from a validated ``[lod]`` table (the leaf size only when it is
    not the default, so the cache keys of default hierarchies stay as they were)."""
    out = {"clustering_method": str(params.get("clustering", PARAMS["clustering"].default))}
    s = int(params.get("leaf_triangles", PARAMS["leaf_triangles"].default))
    if s != CLUSTERS_LEAF_TRIANGLES:
        out["s"] = s
    return out


def build(characters, names, fps, params, static_reps=(), progress=None, cache: bool = True):
    """Mode "clusters" for ``lod.modes``: a :class:`ClustersRep` per skinned
    character (hierarchy built or loaded from the cache), full-detail reps for
    the others, and a :class:`ClustersSelector`.

    Parameters
    ----------
    characters, names, fps, params, static_reps, progress : see ``lod.modes``
    cache : use the on-disk hierarchy cache (default)
    """
    params = dict(params or {})
    poe = float(params.get("poe", PARAMS["poe"].default))
    occ = bool(params.get("occlusion", PARAMS["occlusion"].default))
    every = int(params.get("occlusion_every", PARAMS["occlusion_every"].default))
    bp = build_params_of(params)
    items = list(zip(characters, names, fps))
    if callable(progress):
        items = progress(items, "cluster hierarchies")
    reps = []
    for ch, name, f in items:
        key = f"clusters:{name}"
        if getattr(ch, "kind", "") == "skinned" and ch.mesh.is_skinned:
            sk = build_skinned_rep(ch, fps=f, key=key, morph_targets=False)  # morphs ignored (module docstring)
            h = cached_hierarchy(ch, sk, bp, cache=cache, quiet=progress is False)
            reps.append(ClustersRep(key, sk, h, occlusion=occ, occlusion_every=every))
        else:
            reps.append(build_rep(ch, fps=f, key=key))
    return reps, ClustersSelector(reps, static_reps=static_reps, poe=poe)


__all__ = ["PARAMS", "FORMAT_VERSION", "ClustersRep", "ClusterDrawBatch", "ClustersSelector", "build",
           "cache_dir", "cache_key", "cached_hierarchy"]
