"""Cluster hierarchy of a skinned character (VDR-AM §3.1, §4.3) in a flat layout.

Claudio, Kim, Kim, Yoon, *VDR-AM: View-Dependent Representation of Articulated
Models*. The build follows §4:

1. sample every clip (``CLUSTERS_POSE_SAMPLES`` poses each), reduce the poses by
   MDS and keep representative poses (§4, §4.1, :mod:`lod.clusters.poses`);
2. deformation level of every vertex (§4.2, :mod:`lod.clusters.deformation`);
3. leaf clusters by error-aware clustering, or by the octree baseline (§4.2,
   §6, :mod:`lod.clusters.clustering`);
4. bottom-up hierarchy (§4.3): each cluster is merged with the adjacent
   cluster of nearest deformation level (a cluster's level is the max of its
   vertices'); the merged triangles are simplified to half with the
   multi-pose quadric error of the representative poses (:mod:`lod.simplify.collapse`).

Departures and choices:

- Pairing runs level by level as a greedy matching (clusters in increasing
  deformation level each take their unmatched adjacent cluster of nearest
  level), so the tree stays balanced (each parent is simplified to half, less
  where locked borders leave nothing to collapse). A
  cluster left without an unmatched neighbour waits for the next round; when
  no pair is adjacent any more (a character made of separate parts), the
  spatially nearest clusters are paired so a single root results.
- Cracks: a parent is simplified with every vertex it shares with triangles
  outside its region locked (plus open-edge vertices). With the link condition
  in :func:`lod.simplify.collapse.simplify` the region's border edges survive unchanged at
  every level, so any cut (any set of clusters covering each leaf once) meets
  its neighbours along identical edges.
- Quadrics are carried upward (a vertex keeps the sum of the quadrics of the
  vertices collapsed into it) and order the collapses. ``error`` departs from
  §5.1's sqrt of the largest quadric value: once a vertex has absorbed hundreds
  of planes that square root grows with the plane count (1.85 m at the root of a
  1.9 m, 2,000-triangle humanoid), which would make the cut refine far too
  much. Each cluster's own error is instead MEASURED, over the representative
  poses, as the two-sided Hausdorff distance between its simplified triangles
  and the ORIGINAL leaf triangles of its region (:func:`lod.simplify.distance.cluster_hausdorff`:
  exact from every original vertex, sampled at triangle centroids and edge
  midpoints the other way), so errors do not compound with depth; the stored
  error is max(own, children's), monotone as §5.1 needs. The distance from an
  original vertex counts only simplified triangles facing its way (normal
  within 80 degrees in that pose, :data:`lod.simplify.distance.HAUSDORFF_NORMAL_COS`): a limb
  or foot flattened into a two-sided sheet is close to the original surface but
  covers no pixel seen edge-on, so the plain distance let the rendered
  silhouette lose whole features (2-4x PoE, ``scripts/bench_clusters.md``).
- Pairing (§4.3 "the adjacent cluster of nearest deformation level") compares
  levels in steps of the §4.2 tolerance and, within a step, takes the
  neighbour sharing the longest border. Every locked border stays at leaf
  resolution up to the cluster holding both sides, so the coarse levels are
  bounded by the border length of their regions: compact merges (and compact
  leaves, :func:`lod.clusters.clustering.compact_partition`) are what let them coarsen.
- Degenerate input: triangles with a repeated vertex index are left out
  (:func:`lod.simplify.collapse.drawable_triangles`): they cover no pixel in any
  pose and the simplifier drops them, so a vertex used only by them vanished
  without a collapse target and the collapse tracking stopped the build
  ("cluster N lost track of collapsed vertices"). Everything else people's
  models hold stays and is handled where it arises: zero-area triangles on
  distinct vertices (a collapse that keeps one alive is refused, the edge
  between coincident vertices collapses first at zero cost), duplicate vertices
  (seams: leaves follow the welded surface), duplicate and two-sided triangles
  (the link condition), non-manifold edges (locked) and disconnected parts
  (paired spatially).
- Geomorph targets (``morph_*``): the vertices each simplification removed and
  the vertex each collapsed onto, for a renderer that blends a child into its
  parent.
- Bounds hold over all *sampled* poses, padded by half the largest movement of
  a vertex between consecutive samples, and a parent's bounds hold its whole
  region (so they nest, as a BVH for culling needs).
- Simplified clusters index the original vertex buffer (subset placement), so
  one skinned vertex buffer serves every cluster.

Runtime rule (§5.1, in :mod:`lod.clusters.cut`): a cluster is drawn when its
error, projected at the distance of its bounding sphere, spans at most PoE
pixels; otherwise its children are examined.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from tqdm import tqdm

from sim.atomic_io import atomic_open
from lod.clusters import clustering, deformation, poses
from lod.clusters.config import (
    CLUSTERS_DEFORM_TOLERANCE,
    CLUSTERS_LEAF_TRIANGLES,
    CLUSTERS_POSE_D_FRACTION,
    CLUSTERS_POSE_SAMPLES,
    CLUSTERS_PROGRESS_SECONDS,
    CLUSTERS_SIMPLIFY_RATIO,
    CLUSTERS_SPHERE_PAD,
)
from lod.simplify import collapse as qem
from lod.simplify import distance as qem_distance
from lod.simplify import quadrics as qem_quadrics
from sim.errors import require_float32

CLUSTERINGS = ("error-aware", "octree")


@dataclass
class ClusterHierarchy:
    """Flat, upload-ready cluster hierarchy (VDR-AM §3.1).

    Node ids are in build order: children before parents, leaves first
    (``0 .. n_leaves-1`` are the leaves in depth-first order, so the leaves under
    any node are the contiguous range ``leaf_lo[i] .. leaf_hi[i]-1``).

    Attributes
    ----------
    indices : (M, 3) uint16 (when the mesh has at most 65,536 vertices) or
        uint32 triangles of every cluster, into the character's original vertex
        buffer (``mesh.positions``/joints/weights)
    tri_start : (N+1,) int64 cluster i owns ``indices[tri_start[i]:tri_start[i+1]]``
    children : (N, 2) int32 child ids, -1 for leaves
    parent : (N,) int32, -1 for the root(s)
    roots : (R,) int32 (one root unless the mesh is empty)
    height : (N,) int16, 0 for leaves, 1 + max child height otherwise
    leaf_lo, leaf_hi : (N,) int32 leaves under each node
    error : (N,) float32 metres, model space: Hausdorff estimate of the cluster
        against the original surface over the representative poses (forward
        distance normal-compatible, :func:`lod.simplify.distance.cluster_hausdorff`); 0 for
        leaves, parent >= children
    sphere : (N, 4) float32 model-space (centre xyz, radius) holding the
        cluster's whole region in every sampled pose
    aabb : (N, 2, 3) float32 model-space (lo, hi) of the same
    deformation : (N,) float32 metres, max deformation level of the cluster's vertices
    n_vertices, n_triangles : original mesh sizes
    pose_clips : list[str] clip names sampled; pose_times : (S,) float64 times of
        the S sampled poses; pose_clip : (S,) int32 clip of each sample;
        representatives : (G,) int64 sample indices of the representative poses
    params : dict of the build parameters (for cache keys and reports)
    build_seconds : float
    morph_ptr : (N+1,) int64; morph_vertex, morph_target : (K,) uint32 geomorph
        targets: for internal cluster i, ``morph_vertex[morph_ptr[i]:morph_ptr[i+1]]``
        are the vertices of its children's geometry that the simplification of
        cluster i removed, and ``morph_target`` (same slice) the vertex of cluster
        i each collapsed onto (subset placement, so blending a removed vertex's
        skinned position towards its target's morphs a child into its parent).
        Empty slices for leaves. Not part of :meth:`arrays` (optional data).
    """

    indices: np.ndarray
    tri_start: np.ndarray
    children: np.ndarray
    parent: np.ndarray
    roots: np.ndarray
    height: np.ndarray
    leaf_lo: np.ndarray
    leaf_hi: np.ndarray
    error: np.ndarray
    sphere: np.ndarray
    aabb: np.ndarray
    deformation: np.ndarray
    n_vertices: int
    n_triangles: int
    pose_clips: list = field(default_factory=list)
    pose_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pose_clip: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    representatives: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    params: dict = field(default_factory=dict)
    build_seconds: float = 0.0
    morph_ptr: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    morph_vertex: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint32))
    morph_target: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint32))

    @property
    def n_clusters(self) -> int:
        return int(self.parent.shape[0])

    @property
    def n_leaves(self) -> int:
        return int(np.count_nonzero(self.children[:, 0] < 0))

    def cluster_triangles(self, i: int) -> np.ndarray:
        """(t, 3) triangles of cluster ``i`` (dtype of ``indices``)."""
        return self.indices[self.tri_start[i]:self.tri_start[i + 1]]

    def triangle_counts(self) -> np.ndarray:
        """(N,) int64 triangles per cluster."""
        return np.diff(self.tri_start)

    def cut_triangles(self, cut: np.ndarray) -> np.ndarray:
        """(t, 3) triangles (dtype of ``indices``) of a set of clusters (e.g. one instance's cut)."""
        cut = np.asarray(cut, np.int64)
        if cut.size == 0:
            return np.zeros((0, 3), self.indices.dtype)
        return np.concatenate([self.cluster_triangles(int(i)) for i in cut])

    def arrays(self) -> dict:
        """The runtime arrays (what a renderer uploads and the cut reads)."""
        return {k: getattr(self, k) for k in ("indices", "tri_start", "children", "parent", "roots", "height",
                                              "leaf_lo", "leaf_hi", "error", "sphere", "aabb", "deformation")}

    def nbytes(self) -> int:
        """Bytes of :meth:`arrays` (the hierarchy without the shared vertex buffer)."""
        return int(sum(a.nbytes for a in self.arrays().values()))

    def save(self, path) -> None:
        """Write to ``path`` (.npz) atomically (:func:`sim.atomic_io.atomic_open`)."""
        import json

        d = dict(self.arrays())
        d["pose_times"] = self.pose_times
        d["pose_clip"] = self.pose_clip
        d["representatives"] = self.representatives
        d["morph_ptr"], d["morph_vertex"], d["morph_target"] = self.morph_ptr, self.morph_vertex, self.morph_target
        meta = {"n_vertices": self.n_vertices, "n_triangles": self.n_triangles, "pose_clips": self.pose_clips,
                "params": self.params, "build_seconds": self.build_seconds}
        d["meta"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
        with atomic_open(path, "wb") as f:
            np.savez(f, **d)

    @classmethod
    def load(cls, path) -> "ClusterHierarchy":
        """Read a file written by :meth:`save`; ValueError names the file when it is corrupt."""
        import json
        try:
            with np.load(path, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
            meta = json.loads(d.pop("meta").tobytes().decode())
            h = cls(**d, **meta)
        except Exception as exc:  # noqa: BLE001 - any damage means: rebuild
            raise ValueError(f"cluster hierarchy file {path}: unreadable or incomplete ({exc}); delete it to rebuild") \
                from None
        validate(h)
        return h


def pack_vertices(mesh) -> dict:
    """Compact GPU vertex format for cluster geometry (what bytes/triangle counts).

    positions (V, 3) float32; normals (V, 2) int16 octahedral; joints (V, 4)
    uint8 (uint16 beyond 256 joints); weights (V, 4) uint8 normalised, rounded
    so each row sums to 255.
    """
    pos = np.asarray(mesh.positions, np.float32)
    n = np.asarray(mesh.ensure_normals(), np.float64)
    n = n / np.maximum(np.abs(n).sum(axis=1, keepdims=True), 1e-30)
    oct_ = n[:, :2].copy()
    neg = n[:, 2] < 0
    oct_[neg] = (1.0 - np.abs(n[neg][:, ::-1][:, :2])) * np.where(n[neg][:, :2] >= 0, 1.0, -1.0)
    normals = np.round(np.clip(oct_, -1, 1) * 32767).astype(np.int16)
    j = np.asarray(mesh.joints)
    joints = j.astype(np.uint8 if (j.size == 0 or j.max() < 256) else np.uint16)
    w = np.asarray(mesh.weights, np.float64)
    wq = np.floor(w / np.maximum(w.sum(1, keepdims=True), 1e-30) * 255.0).astype(np.int64)
    rest = 255 - wq.sum(1)
    wq[np.arange(w.shape[0]), np.argmax(w, axis=1)] += rest
    return {"positions": pos, "normals": normals, "joints": joints, "weights": wq.astype(np.uint8)}


def bytes_per_triangle(h: ClusterHierarchy, mesh) -> float:
    """(hierarchy bytes + packed vertex bytes) / original triangles (VDR-AM §6 reports 72)."""
    vb = sum(a.nbytes for a in pack_vertices(mesh).values())
    return (h.nbytes() + vb) / max(h.n_triangles, 1)


# ------------------------------------------------------------------------------------------ build helpers
def _leaf_pairs_adjacency(labels: np.ndarray, ptr: np.ndarray, nbr: np.ndarray) -> list:
    """Sets of edge-adjacent leaf clusters."""
    C = int(labels.max()) + 1 if labels.size else 0
    src = np.repeat(np.arange(ptr.shape[0] - 1), np.diff(ptr))
    a, b = labels[src], labels[nbr]
    k = a != b
    pairs, cnt = np.unique(np.stack([a[k], b[k]], 1), axis=0, return_counts=True) if np.any(k) else \
        (np.zeros((0, 2), np.int64), np.zeros(0, np.int64))
    adj = [dict() for _ in range(C)]
    for (x, y), n in zip(pairs.tolist(), cnt.tolist()):
        adj[x][y] = n
    return adj


def _merge_adj(x: dict, y: dict, drop) -> dict:
    out = dict(x)
    for o, n in y.items():
        out[o] = out.get(o, 0) + n
    for d in drop:
        out.pop(d, None)
    return out


def _build_topology(n_leaves: int, adj: list, level: np.ndarray, tris: np.ndarray, centroid: np.ndarray,
                    band: float = 0.0):
    """Greedy level-by-level pairing (§4.3). Returns children (N, 2) int64 of all nodes (leaves first).

    ``adj[i]`` maps each adjacent cluster to the number of triangle edges they
    share. A cluster takes the unmatched neighbour of nearest deformation level;
    levels are compared in steps of ``band`` metres (the §4.2 tolerance), and
    within one step the neighbour sharing the longest border wins, so merged
    regions stay compact (their locked border, kept at leaf resolution until
    it becomes interior, is what bounds the coarse levels).
    """
    children = [(-1, -1)] * n_leaves
    level = list(level.tolist())
    tris = list(tris.tolist())
    cent = [c for c in centroid]
    adj = [dict(s) for s in adj]

    def lkey(dl):
        return int(dl // band) if band > 0 else dl
    active = list(range(n_leaves))
    while len(active) > 1:
        act = set(active)
        matched: dict = {}
        new_active = []
        order = sorted(active, key=lambda i: (level[i], tris[i], i))
        merges = 0
        for c in order:
            if c in matched:
                continue
            best, key = -1, None
            for o, shared in adj[c].items():
                if o in act and o not in matched and o != c:
                    k = (lkey(abs(level[o] - level[c])), -shared, tris[o], o)
                    if key is None or k < key:
                        best, key = o, k
            if best < 0:
                continue
            p = len(children)
            children.append((c, best))
            matched[c] = p
            matched[best] = p
            level.append(max(level[c], level[best]))
            tris.append(tris[c] + tris[best])
            cent.append((cent[c] * tris[c] + cent[best] * tris[best]) / max(tris[c] + tris[best], 1))
            adj.append(_merge_adj(adj[c], adj[best], (c, best)))
            merges += 1
        if merges == 0:
            # no adjacent pair left (separate parts): pair spatially nearest clusters
            rest = sorted(active, key=lambda i: (tris[i], i))
            pts = np.array([cent[i] for i in rest])
            used = set()
            for a_i, c in enumerate(rest):
                if c in used:
                    continue
                d = np.linalg.norm(pts - pts[a_i], axis=1)
                d[a_i] = np.inf
                for u in used:
                    d[rest.index(u)] = np.inf
                j = int(np.argmin(d))
                if not np.isfinite(d[j]):
                    continue
                o = rest[j]
                p = len(children)
                children.append((c, o))
                matched[c] = matched[o] = p
                used.update((c, o))
                level.append(max(level[c], level[o]))
                tris.append(tris[c] + tris[o])
                cent.append((cent[c] * tris[c] + cent[o] * tris[o]) / max(tris[c] + tris[o], 1))
                adj.append(_merge_adj(adj[c], adj[o], (c, o)))
                merges += 1
        for c in active:
            if c not in matched:
                new_active.append(c)
        new_active.extend(sorted(set(matched.values())))
        # rewrite adjacency of the surviving nodes in terms of the new nodes
        for c in new_active:
            nd: dict = {}
            for o, n in adj[c].items():
                m = matched.get(o, o)
                if m != c:
                    nd[m] = nd.get(m, 0) + n
            adj[c] = nd
        active = new_active
    return np.array(children, np.int64).reshape(-1, 2)


@njit(cache=True)
def _border_vertices(verts, vt_ptr, vt_idx, owner, node, out):  # pragma: no cover - compiled
    for k in range(verts.shape[0]):
        v = verts[k]
        b = False
        for j in range(vt_ptr[v], vt_ptr[v + 1]):
            if owner[vt_idx[j]] != node:
                b = True
                break
        out[k] = b


def _vertex_triangles(indices: np.ndarray, V: int):
    t = indices.reshape(-1)
    order = np.argsort(t, kind="stable")
    ptr = np.zeros(V + 1, np.int64)
    np.add.at(ptr, t + 1, 1)
    return np.cumsum(ptr), (order // 3).astype(np.int64)


def _vertex_bounds(X_all: np.ndarray, pose_clip: np.ndarray, pad: float):
    """Per-vertex trajectory box (lo, hi) and sphere (centre, radius) over all sampled poses."""
    lo = X_all.min(axis=0)
    hi = X_all.max(axis=0)
    c = 0.5 * (lo + hi)
    r = np.sqrt(np.max(np.sum((X_all - c[None]) ** 2, axis=2), axis=0))
    step = np.zeros(X_all.shape[1])
    for ci in np.unique(pose_clip):
        Xc = X_all[pose_clip == ci]
        if Xc.shape[0] > 1:
            dd = np.linalg.norm(np.diff(np.concatenate([Xc, Xc[:1]]), axis=0), axis=2).max(axis=0)
            step = np.maximum(step, dd)
    g = pad * step
    return lo - g[:, None], hi + g[:, None], c, r + g


@njit(cache=True)
def _region_bounds(verts, vlo, vhi, vc, vr, out_sphere, out_aabb, i):  # pragma: no cover - compiled
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for v in verts:
        for k in range(3):
            lo[k] = min(lo[k], vlo[v, k])
            hi[k] = max(hi[k], vhi[v, k])
    cen = 0.5 * (lo + hi)
    r = 0.0
    for v in verts:
        d = np.sqrt((vc[v, 0] - cen[0]) ** 2 + (vc[v, 1] - cen[1]) ** 2 + (vc[v, 2] - cen[2]) ** 2) + vr[v]
        r = max(r, d)
    out_sphere[i, :3] = cen
    out_sphere[i, 3] = r
    out_aabb[i, 0] = lo
    out_aabb[i, 1] = hi


def skin_poses(mesh, skin_mats: np.ndarray) -> np.ndarray:
    """(N, V, 3) float64 skinned positions of ``mesh`` for (N, J, 4, 4) matrices."""
    from sim.skinning import skin
    return np.stack([skin(mesh, m)[0] for m in skin_mats]) if len(skin_mats) else \
        np.zeros((0, mesh.n_vertices, 3))


def build_cluster_hierarchy(character, clips=None, *, samples: int = CLUSTERS_POSE_SAMPLES,
                            d_fraction: float = CLUSTERS_POSE_D_FRACTION, s: int = CLUSTERS_LEAF_TRIANGLES,
                            tolerance: float = CLUSTERS_DEFORM_TOLERANCE, clustering_method: str = "error-aware",
                            ratio: float = CLUSTERS_SIMPLIFY_RATIO, pose_indices=None,
                            progress: bool | None = None) -> ClusterHierarchy:
    """Build the VDR-AM cluster hierarchy of a skinned character (§4).

    Parameters
    ----------
    character : sim.character.SkinnedCharacter (mesh with joints/weights)
    clips : list of clip names, or None for all clips
    samples : poses sampled per clip
    d_fraction : §4.1 pose distance d as a fraction of the rest box diagonal
    s : §4.2 most triangles per leaf cluster
    tolerance : §4.2 deformation tolerance (fraction of the largest level)
    clustering_method : "error-aware" (§4.2) or "octree" (§6 baseline)
    ratio : §4.3 fraction of triangles a parent keeps (0.5)
    pose_indices : optional sample indices to use as quadric poses instead of
        the §4.1 selection (e.g. ``"all"`` for every sample, for comparisons)
    progress : show a tqdm bar (None: only when the build runs over a second)

    Returns
    -------
    ClusterHierarchy
    """
    t_start = time.perf_counter()
    if clustering_method not in CLUSTERINGS:
        raise ValueError(f"build_cluster_hierarchy: clustering_method must be one of {CLUSTERINGS}, "
                         f"got {clustering_method!r}")
    mesh = character.mesh
    if not mesh.is_skinned:
        raise ValueError(f"character {character.name!r}: the mesh has no joints/weights; the VDR-AM cluster "
                         f"hierarchy needs a skinned mesh")
    if not 0.0 < float(ratio) < 1.0:
        raise ValueError(f"build_cluster_hierarchy: ratio must be in (0, 1), got {ratio}")
    names = list(character.clips) if clips is None else list(clips)
    show = True if progress is None else bool(progress)  # with progress=None tqdm appears only after 1 s
    # on a terminal's stderr only, and cleared when the build ends (as crowd's other bars): a bar left on the
    # line was overwritten by the next line only as far as that line reached (issue 48's "frozen" bar)
    bar = tqdm(total=_STAGES, desc=f"clusters {character.name}", unit="step",
               disable=not show or not _is_terminal(sys.stderr), leave=False, file=sys.stderr, dynamic_ncols=True,
               delay=CLUSTERS_PROGRESS_SECONDS if progress is None else 0.0)
    try:
        return _build(character, names, samples, d_fraction, s, tolerance, clustering_method, ratio, pose_indices,
                      bar, t_start)
    finally:
        bar.close()


_STAGES = 4  # poses + skinning, deformation, leaf clusters, topology; then one step per cluster


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no such method, or a closed stream
        return False


def _build(character, names, samples, d_fraction, s, tolerance, clustering_method, ratio, pose_indices, bar,
           t_start) -> ClusterHierarchy:
    mesh = character.mesh
    mats, reps, pose_clip = poses.representative_poses(character, names, samples, d_fraction)
    times = np.concatenate([poses.sample_times(character.clip(n), samples) for n in names]) if names else np.zeros(1)
    if pose_indices is not None:
        reps = np.arange(mats.shape[0]) if isinstance(pose_indices, str) and pose_indices == "all" else \
            np.unique(np.asarray(pose_indices, np.int64).reshape(-1))
        if reps.size == 0 or reps[0] < 0 or reps[-1] >= mats.shape[0]:
            raise ValueError(f"build_cluster_hierarchy: pose_indices must be 'all' or sample indices in "
                             f"0..{mats.shape[0] - 1}, got {pose_indices!r}")
    X_all = skin_poses(mesh, mats)
    require_float32(character, "skinned positions of the sampled poses", X_all)  # AssetError naming the file
    X_rep = np.ascontiguousarray(X_all[reps])
    V = mesh.n_vertices
    tri = qem.drawable_triangles(mesh.indices)  # a repeated index covers no pixel in any pose (see there)
    T = tri.shape[0]
    bar.update(1)
    vlevel = deformation.character_deformation(character, mats, X_all)
    bar.update(1)

    rest = np.asarray(mesh.positions, np.float64)
    if clustering_method == "octree":
        labels = clustering.octree_clusters(rest, tri, s)
    else:
        labels = clustering.error_aware_clusters(rest, tri, vlevel, s, tolerance)
    L = int(labels.max()) + 1 if T else 0
    bar.update(1)
    ptr, nbr = clustering.triangle_adjacency(clustering.welded_indices(rest, tri), V)
    adj = _leaf_pairs_adjacency(labels, ptr, nbr)
    tlevel = clustering.triangle_levels(tri, vlevel)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(L + 1))
    leaf_tris = [order[bounds[i]:bounds[i + 1]] for i in range(L)]
    leaf_level = np.array([tlevel[g].max() for g in leaf_tris]) if L else np.zeros(0)
    centroid = np.array([rest[tri[g]].mean(axis=(0, 1)) for g in leaf_tris]) if L else np.zeros((0, 3))
    band = float(tolerance) * float(vlevel.max()) if vlevel.size else 0.0
    children = _build_topology(L, adj, leaf_level, np.array([g.size for g in leaf_tris]), centroid, band) if L else \
        np.zeros((0, 2), np.int64)
    N = children.shape[0]
    bar.update(1)

    # depth-first leaf order so that every subtree owns a contiguous leaf range; renumber leaves accordingly
    parent = np.full(N, -1, np.int64)
    for i in range(N):
        for c in children[i]:
            if c >= 0:
                parent[c] = i
    roots = np.nonzero(parent < 0)[0]
    leaf_rank = np.full(N, -1, np.int64)
    k = 0
    for r in roots:
        stack = [int(r)]
        while stack:
            i = stack.pop()
            if children[i, 0] < 0:
                leaf_rank[i] = k
                k += 1
            else:
                stack.append(int(children[i, 1]))
                stack.append(int(children[i, 0]))
    perm = np.empty(N, np.int64)  # old id -> new id: leaves by rank, internal nodes keep build order after them
    perm[:L] = leaf_rank[:L]
    perm[L:] = np.arange(L, N)
    inv = np.empty(N, np.int64)
    inv[perm] = np.arange(N)
    children = np.where(children[inv] >= 0, perm[np.maximum(children[inv], 0)], -1)
    leaf_tris = [leaf_tris[inv[i]] for i in range(L)]
    parent = np.full(N, -1, np.int64)
    for i in range(N):
        for c in children[i]:
            if c >= 0:
                parent[c] = i
    roots = np.nonzero(parent < 0)[0]

    # bottom-up simplification (§4.3)
    Q = qem_quadrics.plane_quadrics(X_rep, tri)
    vnorm = qem_distance.vertex_normals(X_rep, tri)  # normal-compatible forward distance (qem_distance.cluster_hausdorff)
    vt_ptr, vt_idx = _vertex_triangles(tri, V)
    vlo, vhi, vc, vr = _vertex_bounds(X_all, pose_clip, CLUSTERS_SPHERE_PAD)
    owner = np.full(T, -1, np.int64)
    region: list = [None] * N
    node_tris: list = [None] * N
    error = np.zeros(N)
    own = np.zeros(N)
    morph_v: list = [np.zeros(0, np.int64)] * N
    morph_t: list = [np.zeros(0, np.int64)] * N
    height = np.zeros(N, np.int64)
    leaf_lo = np.zeros(N, np.int64)
    leaf_hi = np.zeros(N, np.int64)
    deform = np.zeros(N)
    sphere = np.zeros((N, 4))
    aabb = np.zeros((N, 2, 3))
    local = np.full(V, -1, np.int64)
    inside = np.zeros(V, np.bool_)  # the vertices of the cluster being built
    rep = np.arange(V, dtype=np.int64)  # the vertex each original vertex has collapsed into so far
    bar.total = N + _STAGES
    bar.refresh()
    for i in range(N):
        a, b = children[i]
        if a < 0:
            region[i] = leaf_tris[i]
            node_tris[i] = tri[leaf_tris[i]]
            leaf_lo[i], leaf_hi[i] = i, i + 1
        else:
            region[i] = np.concatenate([region[a], region[b]])
            region[a] = region[b] = None  # parents need only the union
            merged = np.concatenate([node_tris[a], node_tris[b]])
            verts = np.unique(merged)
            owner[region[i]] = i
            border = np.empty(verts.shape[0], np.bool_)
            _border_vertices(verts, vt_ptr, vt_idx, owner, i, border)
            local[verts] = np.arange(verts.shape[0])
            Ql = np.ascontiguousarray(Q[:, verts])
            out, remap, _qerr = qem.simplify(X_rep[:, verts], local[merged], int(ratio * merged.shape[0]),
                                             border, quadrics=Ql)
            Q[:, verts] = Ql
            node_tris[i] = verts[out]
            gone = np.nonzero(remap[:verts.shape[0]] != np.arange(verts.shape[0]))[0]
            morph_v[i] = verts[gone]
            morph_t[i] = verts[remap[gone]]
            rv = np.unique(tri[region[i]])
            cur = rep[rv]
            inside[verts] = True
            if not inside[cur].all():  # invariant: every vertex's survivor is in this cluster (drawable_triangles)
                raise RuntimeError(f"cluster hierarchy build: cluster {i} lost track of collapsed vertices")
            inside[verts] = False
            rep[rv] = verts[remap[local[cur]]]
            fwd, bwd = qem_distance._cluster_hausdorff_sq(X_rep, np.ascontiguousarray(node_tris[i]), rv, rep, vt_ptr, vt_idx,
                                                 tri, owner, i, vnorm, qem_distance.HAUSDORFF_NORMAL_COS)
            own[i] = max(fwd, bwd)
            error[i] = max(own[i], error[a], error[b])
            height[i] = 1 + max(height[a], height[b])
            leaf_lo[i], leaf_hi[i] = min(leaf_lo[a], leaf_lo[b]), max(leaf_hi[a], leaf_hi[b])
        if a < 0:
            owner[region[i]] = i
            rv = np.unique(tri[region[i]])
        deform[i] = vlevel[rv].max() if rv.size else 0.0
        _region_bounds(rv, vlo, vhi, vc, vr, sphere, aabb, i)
        bar.update(1)
    counts = np.array([x.shape[0] for x in node_tris], np.int64)
    tri_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    idx_dtype = np.uint16 if V <= 65536 else np.uint32
    indices = np.concatenate(node_tris).astype(idx_dtype) if N else np.zeros((0, 3), idx_dtype)
    params = {"clips": names, "samples": int(samples), "d_fraction": float(d_fraction), "s": int(s),
              "tolerance": float(tolerance), "clustering": clustering_method, "ratio": float(ratio),
              "quadric_poses": [int(x) for x in reps]}
    h = ClusterHierarchy(
        indices=indices.reshape(-1, 3), tri_start=tri_start, children=children.astype(np.int32),
        parent=parent.astype(np.int32), roots=roots.astype(np.int32), height=height.astype(np.int16),
        leaf_lo=leaf_lo.astype(np.int32), leaf_hi=leaf_hi.astype(np.int32), error=error.astype(np.float32),
        sphere=sphere.astype(np.float32), aabb=aabb.astype(np.float32), deformation=deform.astype(np.float32),
        n_vertices=int(V), n_triangles=int(mesh.n_triangles), pose_clips=names, pose_times=times,
        pose_clip=pose_clip.astype(np.int32), representatives=np.asarray(reps, np.int64), params=params)
    mc = np.array([x.shape[0] for x in morph_v], np.int64)
    h.morph_ptr = np.concatenate([[0], np.cumsum(mc)]).astype(np.int64)
    h.morph_vertex = (np.concatenate(morph_v) if N else np.zeros(0)).astype(np.uint32)
    h.morph_target = (np.concatenate(morph_t) if N else np.zeros(0)).astype(np.uint32)
    # float32 rounding must not shrink a sphere below its float64 value or break monotone errors
    h.sphere[:, 3] = np.nextafter(h.sphere[:, 3], np.float32(np.inf))
    validate(h)
    h.build_seconds = time.perf_counter() - t_start
    return h


def validate(h: ClusterHierarchy) -> None:
    """Check the structural invariants of a hierarchy; ValueError names the first broken one."""
    N = h.parent.shape[0]
    for name in ("children", "height", "leaf_lo", "leaf_hi", "error", "sphere", "aabb", "deformation"):
        if getattr(h, name).shape[0] != N:
            raise ValueError(f"cluster hierarchy: {name} has {getattr(h, name).shape[0]} rows, expected {N}")
    if h.tri_start.shape[0] != N + 1 or (N and h.tri_start[-1] != h.indices.shape[0]):
        raise ValueError("cluster hierarchy: tri_start does not match indices")
    if h.indices.size and int(h.indices.max()) >= h.n_vertices:
        raise ValueError("cluster hierarchy: indices reach past the vertex buffer")
    for name in ("error", "sphere", "aabb"):
        if not np.all(np.isfinite(getattr(h, name))):
            raise ValueError(f"cluster hierarchy: {name} contains NaN or Inf")
