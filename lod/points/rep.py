"""The point representation of a character and its on-disk cache (Wand & Straßer §3):
:class:`PointsRep` (one point hierarchy per keyframe segment), :class:`PointsBatch`
(what a frame draws of it) and :class:`HierarchyCache`, the content-addressed,
atomically written store of built hierarchies.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.atomic_io import write_atomic
from lod.drawlist import DrawBatch
from lod.full.reps import KeyframedRep
from lod.points.octree import PointHierarchy, build_hierarchy, load_hierarchy, save_hierarchy

#: version of the cached hierarchy format and build; bump when either changes
CACHE_FORMAT = 4  # 4: normals filtered as the principal axis of their second moment (lod.points.filter)
#: environment variable naming the cache folder (default ``~/.cache/crowd``)
CACHE_ENV = "CROWD_CACHE_DIR"
# ---------------------------------------------------------------------------- representation
@dataclass
class PointsRep:
    """All segment hierarchies of one character, ready for upload.

    key : ``"points:<name>"``
    keyframed : lod.full.reps.KeyframedRep, the segments' full-detail vertices
        (the triangles stored in the octrees index them) and timing
    hierarchies : list of PointHierarchy, one per segment (global order)
    splat_size : int pixels; renderer : "compute" | "gl_points"
    poses : clip name -> lod.points.poses.ClipPoses, the poses a skinned
        character's clips were baked at (empty for keyframed characters)
    """

    key: str
    keyframed: KeyframedRep
    hierarchies: list
    splat_size: int = 2
    renderer: str = "compute"
    poses: dict = field(default_factory=dict)

    kind = "points"

    @property
    def n_parts(self) -> int:
        return len(self.hierarchies)

    @property
    def n_points(self) -> int:
        return int(sum(h.n_points for h in self.hierarchies))

    @property
    def nbytes(self) -> int:
        return int(sum(h.nbytes for h in self.hierarchies))

    def segment_triangles(self, s: int) -> np.ndarray:
        """(T, 3) uint32 global vertex indices (into ``keyframed`` vertices) of
        segment s's triangles in ``tri_order`` order."""
        kf = self.keyframed
        h = self.hierarchies[s]
        first = int(kf.seg_first[s]) // 3
        return kf.indices[first + h.tri_order.astype(np.int64)]


@dataclass
class PointsBatch(DrawBatch):
    """A DrawBatch of instances at one segment of a points rep, plus what
    each instance draws of it.

    point_jobs : (J, 3) int64 (row in ``instance_data``, first point, count)
    tri_jobs : (Q, 3) int64 (row, first entry of ``tri_order``, count)
    """

    point_jobs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    tri_jobs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))


@dataclass
class FollowBatch(PointsBatch):
    """A :class:`PointsBatch` of a ``lod.points.follow.FollowRep`` (samples that follow the animation):
    besides its jobs, the frame's distinct poses of its instances and what each pose needs placed.

    slot : (k,) int64 the pose of each instance row (index into ``pose``)
    pose : (S,) float64 the poses: the fractional baked row of the base's joint table (skinned; instance
        float 12 holds it too) or the segment's u (keyframed: the segment is ``part``)
    pose_points : (S,) int64 samples (a prefix) each pose's instances draw from
    pose_vertices : (S,) int64 vertices (a prefix, the follow numbering) those samples and triangles use
    """

    slot: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    pose: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pose_points: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    pose_vertices: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def placed(self) -> int:
        """Samples and vertices the frame places for this batch (one set per distinct pose)."""
        return int(self.pose_points.sum() + self.pose_vertices.sum())


# ---------------------------------------------------------------------------- cache
def cache_dir() -> Path:
    """Folder of cached hierarchies: ``$CROWD_CACHE_DIR`` or ``~/.cache/crowd``."""
    d = os.environ.get(CACHE_ENV)
    return Path(d) if d else Path.home() / ".cache" / "crowd"


def hierarchy_key(arrays, params: dict, kind: str = f"points-hierarchy/{CACHE_FORMAT}") -> str:
    """sha256 hex digest of ``kind`` (the entry type and format: by default :data:`CACHE_FORMAT`'s
    hierarchies), the input arrays (shape, dtype, bytes) and the build parameters."""
    h = hashlib.sha256()
    h.update(kind.encode())
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    h.update(json.dumps(params, sort_keys=True).encode())
    return h.hexdigest()


def _file_sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


class HierarchyCache:
    """Content-addressed store of PointHierarchy files.

    Entry ``<key>.npz`` (written atomically by ``save_hierarchy``) and
    ``<key>.sha256``, the digest of the npz bytes, written after it
    (``sim.atomic_io``). An entry is used only if the digest matches and the
    file loads; anything else (truncated, corrupt, missing digest) is rebuilt
    and overwritten. ``hits``/``misses`` count lookups.
    """

    def __init__(self, folder=None):
        self.folder = Path(folder) if folder is not None else cache_dir()
        self.hits = 0
        self.misses = 0

    def paths(self, key: str) -> tuple[Path, Path]:
        return self.folder / f"{key}.npz", self.folder / f"{key}.sha256"

    def load(self, key: str, reader=load_hierarchy):
        """The cached entry of ``key`` read by ``reader(path)`` (a hierarchy by default), or None (missing or
        corrupt)."""
        npz, sha = self.paths(key)
        try:
            if not npz.is_file() or sha.read_text().strip() != _file_sha(npz):
                return None
            return reader(npz)
        except (OSError, ValueError):
            return None

    def store(self, key: str, h, writer=save_hierarchy) -> None:
        """Write ``h`` as entry ``key`` with ``writer(h, path)`` (atomic), then its digest."""
        self.folder.mkdir(parents=True, exist_ok=True)
        npz, sha = self.paths(key)
        writer(h, npz)
        write_atomic(sha, _file_sha(npz) + "\n")

    def fetch(self, key: str, build, reader, writer):
        """Entry ``key`` read by ``reader``, or ``build()`` stored by ``writer`` on a miss (a read-only cache
        still builds); counts hits and misses."""
        got = self.load(key, reader)
        if got is not None:
            self.hits += 1
            return got
        self.misses += 1
        out = build()
        try:
            self.store(key, out, writer)
        except OSError:
            pass
        return out

    def get_or_build(self, arrays, params: dict) -> PointHierarchy:
        """Cached hierarchy of ``build_hierarchy(*arrays, **params)``, built and stored on a miss."""
        key = hierarchy_key(arrays, params)
        h = self.load(key)
        if h is not None:
            self.hits += 1
            return h
        self.misses += 1
        h = build_hierarchy(*arrays, **params, progress=False)
        try:
            self.store(key, h)
        except OSError:  # a read-only cache still builds
            pass
        return h
