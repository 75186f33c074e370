"""Point samples that follow the animation: one hierarchy per character, built once, memory independent of
the clips' length (issue 27; Wand & Straßer 2002 §3.1-§3.5, with the animation moved from the hierarchy to
the draw).

Wand & Straßer keep one octree per keyframe pair (§3.3), so a long clip costs poses x triangles of memory and
build (a 35 s dance of a 62 K-triangle character: an estimated 144 GB). Here a character gets one octree:

1. Samples (§3.1, §3.4.1, §3.5). The octree is built in the rest pose (the cells, the stored triangles and the
   filtered colours and normals are the rest pose's), each sample a (triangle, barycentric) pair on the mesh
   the full-detail representation draws (``lod.full.reps``). Candidates are drawn by each triangle's largest
   area over every frame (``lod.points.deform.largest_areas``: the paper's maximum-area argument over the
   whole animation), and the spacing of a node is a fraction of its largest box side over the stratification
   poses (§3.3: over both keyframes).
2. Stratification (§3.4.2 over poses). A candidate may go when another covers it within r/2 at each of K
   stratification poses (``lod.points.deform.choose_poses``: farthest-first in stretch), so the kept samples
   cover the surface wherever it is most stretched, not only in the rest pose (a bind pose can be far from
   every frame: the Fox's triangles stretch up to 7.9x from it).
3. Spacing under deformation. At the other frames the kept samples cover the surface less tightly where it
   stretches. Every node's covering radius is measured at every frame of each clip (probes on its subtree's
   surface against its samples, both placed with the animation: ``lod.points.deform.node_coverage``; the same
   guarantee §3.4.2 constructs at an interval's two ends, and between two baked rows distances are convex in
   the blend), and the traversal (§3.2) tests ``spacing * stretch`` with ``stretch = max(1, 2 radius / r)``: a
   node refines where the animation would open holes larger than the splat (tested on a stretching joint).
4. Bounds over time. Every node keeps, per clip, one box in the frame of its reference joint holding its
   subtree at every frame of the clip (``lod.points.deform.node_boxes``), drawn through that joint's matrix of
   the pose (``lod.points.traverse``; between two baked rows the union of both). Keyframed characters (one
   triangle list over all segments) keep the box at every segment end instead, interpolated as §3.3 does.
   Per-clip data grow with the number of clips, never with their length.
5. Coarser than the root (``lod.points.coarse``): the farthest-point order over the stratification poses, the
   prefix radii measured at every frame of each clip.
6. Drawing. Samples are stored in breadth-first node order, and the vertices are renumbered by their first use
   in that order (``vorder``), so what the nodes up to the deepest one a pose draws need is a prefix of both:
   ``pprefix`` samples and ``vprefix`` vertices. Per frame and distinct pose the renderer poses that vertex
   prefix (skin ∘ morph with the pose's baked rows, or the keyframes' interpolation) and places the sample
   prefix by barycentric interpolation of the posed corners (``render/points/follow.py``): the samples lie on
   the very triangles full detail draws. Normals: the filtered normal is kept in the frame of the sample's
   shading normal and first edge (``lnrm``) and turned with it.

The per-keyframe-pair octrees (``lod.points.mode``, "baked") stay for keyframe animations whose triangles
change between segments, and where a measured rule prefers them (``lod.points.paths.animation_path``).
"""
from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field

import numpy as np

from sim.atomic_io import atomic_open
from lod.points import config as C
from lod.full import frames as full_frames
from lod.points import deform
from lod.points.coarse import add_coarse
from lod.points.octree import PointHierarchy, build_hierarchy

#: version of the follow hierarchies' file format and build; bump when either changes
FOLLOW_FORMAT = 1
#: most stratification poses per character (``lod.points.deform.choose_poses``)
STRATIFY_POSES = 6
#: the pose choice stops when the stretch from the nearest chosen pose is at most this
STRETCH_TARGET = 1.25
#: probes per sample measuring a node's covering radius at every frame (``lod.points.deform.node_coverage``)
COVERAGE_PROBES = 2.0
#: relative pad of the node boxes (float32 arithmetic on the GPU, quantised posed vertices)
BOX_PAD = 1e-4
#: nodes at most this deep compare their joint frame's box with the model frame's and keep the smaller
SHALLOW_DEPTH = 2


@dataclass
class FollowHierarchy:
    """The octree of a character's rest-pose samples and what drawing them in any pose needs.

    octree : PointHierarchy, one interval, built in the rest pose (``pos0 == pos1``); its ``spacing`` is the
        sampled spacing r, its ``coarse_count``/``coarse_spacing`` the root prefixes measured over every frame
    ref : (N,) int32 joint whose frame holds each node's box (-1: the model frame)
    lbox : (C, N, 2, 3) float64 per clip the node boxes over its frames in those frames (skinned; zeros for
        keyframed)
    fbox : (F, N, 2, 3) float32 or None: keyframed, the node boxes at every frame (segment ends)
    stretch : (C, N) float64 >= 1, per clip the node's spacing factor over its frames
    vorder : (V,) int32 vertex renumbering: new vertex i is old vertex ``vorder[i]``
    vprefix, pprefix : (N,) int64 vertices (new numbering) and samples nodes 0..i need
    corners : (T, 3) int32 the triangles' corners in the new numbering
    lnrm : (P, 3) float16 the samples' filtered normals in their shading frame (:func:`frame_coordinates`)
    poses : (K,) int64 the stratification frames
    cspacing : (C, L) float64 per clip the spacings of the root's prefixes (``octree.coarse_count``)
    stats : dict of build figures (seconds, poses, stretch left)
    """

    octree: PointHierarchy
    ref: np.ndarray
    lbox: np.ndarray
    fbox: np.ndarray | None
    stretch: np.ndarray
    vorder: np.ndarray
    vprefix: np.ndarray
    pprefix: np.ndarray
    corners: np.ndarray
    lnrm: np.ndarray
    poses: np.ndarray
    cspacing: np.ndarray
    stats: dict = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        return self.octree.n_nodes

    @property
    def n_points(self) -> int:
        return self.octree.n_points

    @property
    def nbytes(self) -> int:
        extra = sum(v.nbytes for k, v in self.__dict__.items() if isinstance(v, np.ndarray))
        return int(self.octree.nbytes + extra)

    def effective_spacing(self, clip: int = 0) -> np.ndarray:
        """(N,) the spacing the traversal tests for ``clip``: r x stretch."""
        return np.asarray(self.octree.spacing, np.float64) * self.stretch[min(int(clip), self.stretch.shape[0] - 1)]


# ---------------------------------------------------------------------------- helpers
def triangle_nodes(h: PointHierarchy) -> np.ndarray:
    """(T,) int64 the node storing each triangle (from ``tri_order`` and the nodes' ranges)."""
    out = np.full(h.indices.shape[0], -1, np.int64)
    for i in np.flatnonzero(h.tri_count > 0).tolist():
        s, c = int(h.tri_start[i]), int(h.tri_count[i])
        out[h.tri_order[s:s + c]] = i
    return out


def vertex_order(h: PointHierarchy, V: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vorder (V,) int32, vprefix (N,) int64, pprefix (N,) int64): vertices renumbered by first use over the
    nodes in breadth-first order (a node's samples' triangles, then its stored triangles), the vertices the
    nodes 0..i use and the samples they hold (samples are stored in node order)."""
    N = h.n_nodes
    idx = np.asarray(h.indices, np.int64)
    seq, lab = [], []
    for i in range(N):
        s, c = int(h.point_start[i, 0]), int(h.point_count[i, 0])
        t = np.concatenate([h.tri[s:s + c].astype(np.int64),
                            h.tri_order[int(h.tri_start[i]):int(h.tri_start[i] + h.tri_count[i])].astype(np.int64)])
        if t.size:
            seq.append(idx[t].reshape(-1))
            lab.append(np.full(3 * t.size, i, np.int64))
    seq = np.concatenate(seq) if seq else np.zeros(0, np.int64)
    lab = np.concatenate(lab) if lab else np.zeros(0, np.int64)
    uniq, first = np.unique(seq, return_index=True)
    by_use = np.argsort(first, kind="stable")
    used = uniq[by_use]
    rest = np.setdiff1d(np.arange(V), used)  # vertices of no triangle
    vorder = np.concatenate([used, rest]).astype(np.int32)
    first_node = lab[first[by_use]]
    vprefix = np.searchsorted(first_node, np.arange(N), side="right").astype(np.int64)
    ends = (h.point_start[:, 0] + h.point_count[:, 0]).astype(np.int64) if N else np.zeros(0, np.int64)
    pprefix = np.maximum.accumulate(ends) if N else ends
    return vorder, vprefix, pprefix


def frame_coordinates(p, n, idx, tri, bary, nrm) -> np.ndarray:
    """(P, 3) float64 unit coordinates of the filtered normals ``nrm`` of samples (tri, bary) in their
    shading frame at positions p (V, 3) and vertex normals n (V, 3): N the interpolated vertex normal,
    T the triangle's first edge made orthogonal to N, B = N x T (``render/shaders/points/points_place.glsl``
    turns them back with the posed frame). A degenerate frame keeps the normal in N's direction."""
    tri = np.asarray(tri, np.int64)
    b = np.asarray(bary, np.float64)
    c = np.asarray(idx, np.int64)[tri]
    w = np.stack([1.0 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)[:, :, None]
    N = (w * np.asarray(n, np.float64)[c]).sum(1)
    P = np.asarray(p, np.float64)
    e = P[c[:, 1]] - P[c[:, 0]]
    ln = np.linalg.norm(N, axis=1, keepdims=True)
    N = np.where(ln > 1e-12, N / np.where(ln > 1e-12, ln, 1.0), np.array([0.0, 1.0, 0.0]))
    T = e - (e * N).sum(1, keepdims=True) * N
    lt = np.linalg.norm(T, axis=1, keepdims=True)
    ok = lt[:, 0] > 1e-12
    T = np.where(ok[:, None], T / np.where(ok[:, None], lt, 1.0), 0.0)
    B = np.cross(N, T)
    f = np.asarray(nrm, np.float64)
    out = np.stack([(f * T).sum(1), (f * B).sum(1), (f * N).sum(1)], 1)
    out[~ok] = (0.0, 0.0, 1.0)
    ln = np.linalg.norm(out, axis=1, keepdims=True)
    return np.where(ln > 1e-12, out / np.where(ln > 1e-12, ln, 1.0), np.array([0.0, 0.0, 1.0]))


def posed_prefix_radii(frames, h: PointHierarchy, counts: np.ndarray, rows=None) -> np.ndarray:
    """(L,) float64: for each prefix size m of the root's points (farthest-point order), the largest distance
    over every frame from a root point to its nearest of the first m (``lod.points.coarse`` at every frame)."""
    s, n = int(h.point_start[0, 0]), int(h.point_count[0, 0])
    idx = np.asarray(h.indices, np.int64)
    tri = idx[h.tri[s:s + n].astype(np.int64)]
    b = np.asarray(h.bary[s:s + n], np.float64)
    w = np.stack([1.0 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)[None, :, :, None]
    verts, local = np.unique(tri.reshape(-1), return_inverse=True)
    local = local.reshape(-1, 3)
    out = np.zeros(counts.shape[0])
    step = max(1, min(full_frames.FRAME_CHUNK, 2_000_000 // max(1, n * n)))  # (f, n, n) distances at most 16 MB
    for r in full_frames.row_chunks(frames, rows, step):
        q = (frames.positions(r, verts)[:, local] * w).sum(2)  # (f, n, 3)
        d = np.sqrt(((q[:, :, None, :] - q[:, None, :, :]) ** 2).sum(-1))  # (f, n, n)
        for k, m in enumerate(counts.tolist()):
            out[k] = max(out[k], float(d[:, :, :m].min(2).max()) if m < n else 0.0)
    return out


# ---------------------------------------------------------------------------- build
def build_follow(frames, colors, normals, *, joints=None, weights=None, n_joints: int = 0, clips=None,
                 spacing_fraction: float = C.POINTS_SPACING_FRACTION, max_poses: int = STRATIFY_POSES,
                 stretch_target: float = STRETCH_TARGET, coarse: bool = True, seed: int = 0,
                 progress=None) -> FollowHierarchy:
    """Build the :class:`FollowHierarchy` of a character (module docstring).

    Parameters
    ----------
    frames : ``lod.full.frames.SkinnedFrames`` or ``KeyframedFrames`` (rest pose, triangles, every frame)
    colors (V, 4), normals (V, 3) : the rest pose's vertex attributes
    joints (V, 4), weights (V, 4), n_joints : the skin (skinned frames; the node boxes' joint frames)
    clips : None (one group of every frame) or per clip its frame rows: the stretch, node boxes and coarse
        prefixes are measured per clip (a view draws one clip), the samples and octree are shared
    spacing_fraction : r as a fraction of a node's box side (§3.3)
    max_poses, stretch_target : the stratification poses (``lod.points.deform.choose_poses``)
    coarse : the root's farthest-point prefixes (``lod.points.coarse``)
    progress : None or ``progress(message)`` called between the steps
    """
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    rest = np.asarray(frames.rest, np.float64)
    idx = np.asarray(frames.indices, np.int64)
    V = rest.shape[0]
    say("areas")
    areas = deform.largest_areas(frames)
    say("stratification poses")
    scale = spacing_fraction * float(np.ptp(rest, axis=0).max()) if V else 1.0  # about the root's spacing
    poses, left = deform.choose_poses(frames, max_poses, stretch_target, scale)
    P = frames.positions(poses) if poses.size else rest[None]
    say("octree")
    h = build_hierarchy(rest, rest, idx, colors, colors, normals, normals, intervals=1,
                        spacing_fraction=spacing_fraction, seed=seed, poses=P, areas=areas, progress=False)
    t_tree = time.perf_counter()
    tri_node = triangle_nodes(h)
    parent = np.asarray(h.parent, np.int64)
    ptr, vert = deform.subtree_vertices(parent, tri_node, idx, V)
    N = h.n_nodes
    skinned = joints is not None
    groups = [np.asarray(g, np.int64) for g in clips] if clips is not None else [np.arange(frames.n_frames)]
    Cn = len(groups)
    r = np.asarray(h.spacing, np.float64)
    rng = np.random.default_rng([int(seed), 0x636F76])
    pad = BOX_PAD * float(max(np.ptp(rest, axis=0).max(), 1e-9)) if V else 0.0
    if coarse and N:
        # farthest-point order of the root's points by their largest distance over the stratification poses
        s0, n0 = int(h.point_start[0, 0]), int(h.point_count[0, 0])
        c0 = idx[h.tri[s0:s0 + n0].astype(np.int64)]
        b = np.asarray(h.bary[s0:s0 + n0], np.float64)
        wb = np.stack([1.0 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)[None, :, :, None]
        add_coarse(h, poses=(P[:, c0] * wb).sum(2) if n0 else None)
    has_coarse = coarse and N and h.coarse_count.shape[1] > 0
    stretch = np.ones((Cn, N))
    cspacing = np.zeros((Cn, h.coarse_count.shape[1] if has_coarse else 0))
    if skinned:
        ok = np.ones(n_joints, bool)  # joints invertible at every frame (a usable box frame)
        for a, b in full_frames.chunks(frames.n_frames, 256):
            ok &= frames.joint_inverses(np.arange(a, b))[1]
        ref = deform.reference_joints(ptr, vert, np.asarray(joints, np.int64), np.asarray(weights, np.float64),
                                      n_joints)
        ref = np.where(ok[ref], ref, -1).astype(np.int32)
        shallow = np.asarray(h.depth) <= SHALLOW_DEPTH
        lbox = np.zeros((Cn, N, 2, 3))
        model = np.zeros((Cn, N, 2, 3))
    else:
        ref = np.full(N, -1, np.int32)
        lbox = np.zeros((Cn, N, 2, 3))
    for c, rows in enumerate(groups):  # per clip: its frames alone (memory: clips x nodes, not frames)
        say(f"clip {c}: coverage and bounds")
        cover = deform.node_coverage(frames, h, COVERAGE_PROBES, rng, weights=areas, rows=rows)
        stretch[c] = np.where(r > 0.0, np.maximum(1.0, 2.0 * cover / np.where(r > 0.0, r, 1.0)), 1.0)
        if skinned:
            lbox[c] = deform.node_boxes(frames, ptr, vert, ref, rows=rows)
            model[c] = deform.node_boxes(frames, ptr, vert, np.where(shallow, -1, -2), rows=rows)
        if has_coarse:
            counts = h.coarse_count[0]
            uniq = np.unique(counts)
            radii = posed_prefix_radii(frames, h, uniq, rows=rows)
            r_eff = float(r[0] * stretch[c, 0])
            sp = 2.0 * radii[np.searchsorted(uniq, counts)] + r_eff
            sp[counts == int(h.point_count[0, 0])] = r_eff
            cspacing[c] = sp
    if skinned:  # shallow nodes keep the model frame where its boxes are smaller over the clips
        ext = lambda x: (x[:, :, 1] - x[:, :, 0]).sum(axis=(0, 2))  # noqa: E731
        better = shallow & (ext(model) < ext(lbox))
        ref[better] = -1
        lbox[:, better] = model[:, better]
        lbox = lbox + np.array([-pad, pad])[None, None, :, None]
        fbox = None
    else:
        fbox = deform.segment_boxes(frames, ptr, vert)
        fbox = (fbox + np.array([-pad, pad])[None, None, :, None]).astype(np.float32)
    if has_coarse:
        h.coarse_spacing = cspacing[:1].copy()  # the first clip's in the octree; every clip's in ``cspacing``
    say("order")
    vorder, vprefix, pprefix = vertex_order(h, V)
    inv = np.empty(V, np.int64)
    inv[vorder] = np.arange(V)
    corners = inv[idx].astype(np.int32)
    lnrm = frame_coordinates(rest, normals, idx, h.tri, h.bary, h.nrm0).astype(np.float16)
    stats = {"seconds": time.perf_counter() - t0, "octree_seconds": t_tree - t0, "poses": int(poses.size),
             "stretch_left": float(left), "frames": int(frames.n_frames)}
    return FollowHierarchy(h, ref, lbox, fbox, stretch, vorder, vprefix, pprefix, corners, lnrm,
                           poses.astype(np.int64), cspacing, stats)


# ---------------------------------------------------------------------------- files
def save_follow(t: FollowHierarchy, path) -> None:
    """Write ``t`` to an ``.npz`` file atomically (the octree's arrays prefixed ``h_``)."""
    arrays = {f"h_{k}": v for k, v in t.octree.__dict__.items() if isinstance(v, np.ndarray) and not k.startswith("_")}
    arrays.update({k: v for k, v in t.__dict__.items() if isinstance(v, np.ndarray)})
    meta = json.dumps({"format": FOLLOW_FORMAT, "params": t.octree.params, "stats": t.stats,
                       "coarse": getattr(t.octree, "coarse_count", None) is not None})
    with atomic_open(path, "wb") as f:
        np.savez(f, __meta__=np.frombuffer(meta.encode(), np.uint8), **arrays)


def load_follow(path) -> FollowHierarchy:
    """Read a file of :func:`save_follow`; ValueError naming the file when it is unreadable or of another format."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["__meta__"]).decode())
            if meta.get("format") != FOLLOW_FORMAT:
                raise ValueError(f"{path}: follow hierarchy format {meta.get('format')}, expected {FOLLOW_FORMAT}")
            names = [f for f in PointHierarchy.__dataclass_fields__ if f not in ("intervals", "params")]
            h = PointHierarchy(**{k: z[f"h_{k}"] for k in names}, intervals=1, params=dict(meta["params"]))
            if meta.get("coarse"):
                h.coarse_count, h.coarse_spacing = z["h_coarse_count"], z["h_coarse_spacing"]
            fields = [f for f in FollowHierarchy.__dataclass_fields__ if f not in ("octree", "stats", "fbox")]
            t = FollowHierarchy(octree=h, fbox=z["fbox"] if "fbox" in z.files else None,
                                stats=dict(meta.get("stats", {})), **{k: z[k] for k in fields})
    except Exception as e:  # a damaged file can fail anywhere in zipfile/numpy
        if isinstance(e, ValueError) and str(e).startswith(str(path)):
            raise
        raise ValueError(f"{path}: not a readable follow hierarchy file ({type(e).__name__}: {e})") from None
    return t


#: the modules whose code builds a follow hierarchy: their sources are part of its cache key
BUILD_MODULES = ("follow.py", "deform.py", "octree.py", "stratify.py", "sampling.py", "filter.py", "coarse.py")


def _source_digest() -> str:
    from pathlib import Path

    from lod.points.rep import hierarchy_key

    here = Path(__file__).resolve().parent
    return hierarchy_key([np.frombuffer(name.encode() + (here / name).read_bytes(), np.uint8)
                          for name in BUILD_MODULES], {}, kind="sources")


def follow_key(arrays, params: dict) -> str:
    """sha256 hex digest of the inputs (shape, dtype, bytes), the parameters, :data:`FOLLOW_FORMAT` and the
    sources of :data:`BUILD_MODULES` (a changed build never reads an entry of the old one)."""
    from lod.points.rep import hierarchy_key

    global _SOURCES
    if _SOURCES is None:
        _SOURCES = _source_digest()
    return hierarchy_key(arrays, params, kind=f"points-follow/{FOLLOW_FORMAT}/{_SOURCES}")


_SOURCES = None


def cached_follow(cache, arrays, params: dict, build):
    """The cached :class:`FollowHierarchy` of ``arrays`` and ``params`` (``cache``: a
    ``lod.points.rep.HierarchyCache``), built with ``build()`` and stored on a miss."""
    return cache.fetch("follow-" + follow_key(arrays, params), build, load_follow, save_follow)


# ---------------------------------------------------------------------------- representation
@dataclass
class FollowRep:
    """Mode points' representation of a character whose samples follow the animation.

    key : ``"points:<name>"``
    base : the full-detail representation the samples are placed with and the selector culls and locates
        with (``lod.full.reps.SkinnedRep``, parts = clips, instance float 12 the frame coordinate; or
        ``KeyframedRep``, parts = segments, float 12 the segment's u), keyed ``key`` as well
    tree : FollowHierarchy; vbase : (S,) first vertex of each segment (keyframed), else None
    splat_size : int pixels; renderer : "compute" | "gl_points"
    """

    key: str
    base: object
    tree: FollowHierarchy
    vbase: np.ndarray | None = None
    splat_size: int = 2
    renderer: str = "compute"
    coarse: bool = True  # the root's farthest-point prefixes (lod.points.coarse) in the traversal

    kind = "points"
    follow = True

    @property
    def skinned(self) -> bool:
        return getattr(self.base, "kind", "") == "skinned"

    @property
    def poses(self) -> dict:
        """No baked poses (``lod.points.poses``): the samples follow the animation."""
        return {}

    @property
    def pose_source(self):
        """The SkinnedRep whose joint table the copies' frame coordinates index (the pose cache's group of the
        character, ``lod.poses``), or None (keyframed)."""
        return self.base if self.skinned else None

    @property
    def n_parts(self) -> int:
        return int(self.base.n_parts)

    @property
    def n_points(self) -> int:
        return self.tree.n_points

    @property
    def nbytes(self) -> int:
        """Bytes of the hierarchy (the base representation is the animation the mesh already has)."""
        return self.tree.nbytes

    def view(self, part: int) -> PointHierarchy:
        """The octree as the traversal (``lod.points.jobs.traverse_instances``) reads it for ``part``:
        node boxes in joint frames over clip ``part``'s frames (skinned) or at segment ``part``'s ends
        (keyframed), the spacing times the clip's stretch, the clip's coarse prefixes."""
        views = self.__dict__.setdefault("_views", {})
        k = int(part)
        v = views.get(k)
        if v is None:
            t = self.tree
            h = t.octree
            c = k if self.skinned else 0  # skinned: a part is a clip; keyframed: a segment (measured as one)
            if self.skinned:
                b0 = b1 = np.ascontiguousarray(t.lbox[c], np.float64)
            else:
                b0 = np.ascontiguousarray(t.fbox[2 * k], np.float64)
                b1 = np.ascontiguousarray(t.fbox[2 * k + 1], np.float64)
            v = dataclasses.replace(h, box0=b0, box1=b1, spacing=t.effective_spacing(c), interval_bounds=None)
            v.intervals = 1
            if self.coarse and getattr(h, "coarse_count", None) is not None and t.cspacing.shape[1]:
                v.coarse_count, v.coarse_spacing = h.coarse_count, np.ascontiguousarray(t.cspacing[c:c + 1])
            else:
                v.coarse_count = v.coarse_spacing = None
            if self.skinned:
                v.ref = np.ascontiguousarray(t.ref, np.int32)
                v.joint_table = np.ascontiguousarray(self.base.joint_table, np.float32)
            views[k] = v
        return v


__all__ = ["FOLLOW_FORMAT", "FollowHierarchy", "FollowRep", "STRATIFY_POSES", "STRETCH_TARGET", "build_follow",
           "cached_follow", "follow_key", "frame_coordinates", "load_follow", "posed_prefix_radii", "save_follow",
           "triangle_nodes", "vertex_order"]
