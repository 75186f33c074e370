"""Triangle LOD chains of static props and their cache.

Level 0 is the prop's full mesh; level ``l`` is the full mesh simplified by
fast-simplification (the Fast Quadric Mesh Simplification of Sven Forstmann,
after Garland & Heckbert, *Surface Simplification Using Quadric Error Metrics*,
SIGGRAPH 1997) to ``ratio ** l`` of its triangles. A static mesh needs neither
the multi-pose quadrics nor the locked borders of the characters' chains
(:mod:`lod.chains`): one pose, and each level is simplified from the full mesh
(no error accumulates from level to level).

Each level's geometric error is a sampled symmetric Hausdorff distance to the
full mesh (metres, model space): ``max(max_a d(a, B), max_b d(b, A))`` over
area-uniform samples a of the full surface A and b of the level's surface B
(and their vertices), ``d`` the exact point-to-triangle distance (Ericson
§5.1.5) to the nearest of the candidate triangles that a k-d tree of a dense
surface sample proposes (scipy ``cKDTree``; an upper bound of the
point-to-surface distance, exact when the nearest triangle is a candidate). The errors are made monotone (a level's error is at least
its finer neighbour's) and multiplied by :data:`ERROR_SAFETY` (the samples miss
the exact maximum, and the pixels-of-error rule needs an upper bound), level 0's is 0, and a level whose error exceeds
:data:`MAX_ERROR_FRACTION` of the bounding radius is dropped (too coarse to be
worth drawing: the LOD rule would show it only below a pixel anyway).

Levels are flat shaded (corners unshared, one normal per triangle): props are
mostly hard-edged architecture, and unshared corners keep every level's
colours and normals independent. Colours of simplified vertices are those of
the nearest full-mesh vertex.

Chains are cached as ``props-<sha256>.npz`` (key: the mesh arrays, the build
parameters and :data:`FORMAT_VERSION`) written atomically
(:func:`sim.atomic_io.atomic_open`); an unreadable entry is rebuilt.
"""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.atomic_io import atomic_open

#: bump when the cached layout or its meaning changes
FORMAT_VERSION = 2  # 2: centroids and edge midpoints among the error samples
#: environment variable naming the cache folder (shared with the other hierarchies)
CACHE_ENV = "CROWD_CACHE_DIR"
#: most levels in a chain (level 0 included)
MAX_LEVELS = 8
#: triangles of each level as a fraction of the previous level's
LEVEL_RATIO = 0.5
#: the chain stops below this many triangles
MIN_TRIANGLES = 8
#: the chain stops when a level keeps more than this fraction of the previous one
STALL_FRACTION = 0.9
#: a level whose error exceeds this fraction of the bounding radius is not kept
MAX_ERROR_FRACTION = 0.5
#: samples per surface for the Hausdorff error
ERROR_SAMPLES = 4000
#: candidate triangles of each sample's point-to-surface distance (those of its nearest surface samples)
NEAREST_TRIANGLES = 12
#: area-uniform surface samples locating the candidate triangles
TARGET_SAMPLES = 20000
#: factor on a level's sampled Hausdorff distance: samples miss the exact maximum inside faces
#: (on a 1280-triangle icosphere 64,000 samples found up to 1.29x what 4,000 found), and the
#: pixels-of-error rule needs an upper bound
ERROR_SAFETY = 1.5
#: seed of the error sampling (chains are deterministic)
ERROR_SEED = 7


@dataclass
class PropChainRep:
    """A prop's chain, ready to upload (``render.world.draw``).

    key : str, representation key (``"props:<name>"``)
    positions : (V, 3) float32 model space; normals : (V, 3) float32; colors : (V, 4) float32
    indices : (T, 3) uint32, every level's triangles back to back
    level_first, level_count : (L,) int64 first triangle and triangle count of each level
    level_error : (L,) float64 metres (model space), monotone, level_error[0] = 0
    sphere : (4,) float64 model-space bounding sphere (cx, cy, cz, r)
    """

    key: str
    positions: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    indices: np.ndarray
    level_first: np.ndarray
    level_count: np.ndarray
    level_error: np.ndarray
    sphere: np.ndarray = field(default_factory=lambda: np.zeros(4))

    kind = "world"

    @property
    def n_levels(self) -> int:
        return int(self.level_count.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.level_count[0])

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in (self.positions, self.normals, self.colors, self.indices)))


def bounding_sphere(positions: np.ndarray) -> np.ndarray:
    """(4,) float64 sphere about the bounding-box centre enclosing every position."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    if not len(p):
        return np.zeros(4)
    c = 0.5 * (p.min(0) + p.max(0))
    return np.array([*c, float(np.sqrt(((p - c) ** 2).sum(1)).max())])


def sample_surface(v: np.ndarray, f: np.ndarray, n: int, rng) -> np.ndarray:
    """(n + V + 4 F, 3) float64: ``n`` area-uniform points on triangles ``f`` of ``v`` plus the used
    vertices, the triangles' centroids and edge midpoints (where a flat level deviates most from a
    curved surface)."""
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    tot = float(area.sum())
    pick = rng.choice(len(f), n, p=area / tot) if tot > 0 else rng.integers(0, len(f), n)
    r1, r2 = rng.random(n), rng.random(n)
    flip = r1 + r2 > 1.0
    r1, r2 = np.where(flip, 1 - r1, r1), np.where(flip, 1 - r2, r2)
    t = tri[pick]
    pts = t[:, 0] + r1[:, None] * (t[:, 1] - t[:, 0]) + r2[:, None] * (t[:, 2] - t[:, 0])
    mids = 0.5 * (tri + tri[:, [1, 2, 0]])
    return np.concatenate([pts, v[np.unique(f)], tri.mean(1), mids.reshape(-1, 3)])


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(n, 3) closest points to ``p`` (n, 3) on triangles (a, b, c) (n, 3 each), by the Voronoi-region
    tests of Ericson, *Real-Time Collision Detection*, §5.1.5 (vectorised; degenerate triangles give a
    corner or edge point, never NaN)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    safe = lambda x: np.where(np.abs(x) > 1e-300, x, 1.0)  # noqa: E731
    den = safe(va + vb + vc)
    out = a + ab * (vb / den)[:, None] + ac * (vc / den)[:, None]  # inside the face
    # edges (checked before corners so that corners win where both hold)
    m = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    w = (d4 - d3) / safe((d4 - d3) + (d5 - d6))
    out = np.where(m[:, None], b + w[:, None] * (c - b), out)
    m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    out = np.where(m[:, None], a + (d2 / safe(d2 - d6))[:, None] * ac, out)
    m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    out = np.where(m[:, None], a + (d1 / safe(d1 - d3))[:, None] * ab, out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, out)
    return out


def distance_to_mesh(points: np.ndarray, v: np.ndarray, f: np.ndarray, k: int = NEAREST_TRIANGLES,
                     seed: int = ERROR_SEED) -> np.ndarray:
    """(n,) distance from each point to the triangles ``f`` of ``v``: the exact point-triangle distance
    to candidate triangles, those of the ``k`` nearest of a dense area-uniform sample of the surface
    (plus every centroid) found with a k-d tree (scipy ``cKDTree``). An upper bound of the true
    distance, equal to it whenever the nearest triangle is among the candidates."""
    from scipy.spatial import cKDTree

    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    rng = np.random.default_rng(seed)
    n = TARGET_SAMPLES
    tot = float(area.sum())
    ids = np.concatenate([np.arange(len(f)), rng.choice(len(f), n, p=area / tot) if tot > 0 else
                          rng.integers(0, len(f), n)])
    r1, r2 = rng.random(len(ids)), rng.random(len(ids))
    r1[:len(f)] = r2[:len(f)] = 1.0 / 3.0
    flip = r1 + r2 > 1.0
    r1, r2 = np.where(flip, 1 - r1, r1), np.where(flip, 1 - r2, r2)
    t = tri[ids]
    targets = t[:, 0] + r1[:, None] * (t[:, 1] - t[:, 0]) + r2[:, None] * (t[:, 2] - t[:, 0])
    k = min(int(k), len(ids))
    _, near = cKDTree(targets).query(points, k=k)
    cand = ids[np.asarray(near).reshape(len(points), k)]
    p = np.repeat(points, k, axis=0)
    t = tri[cand.reshape(-1)]
    q = closest_on_triangles(p, t[:, 0], t[:, 1], t[:, 2])
    return np.sqrt(((q - p) ** 2).sum(1)).reshape(-1, k).min(1)


def hausdorff(va, fa, vb, fb, samples: int = ERROR_SAMPLES, seed: int = ERROR_SEED,
              k: int = NEAREST_TRIANGLES) -> float:
    """Sampled symmetric Hausdorff distance (metres) between two triangle meshes: the largest
    point-to-surface distance (:func:`distance_to_mesh`) of area-uniform samples of either surface
    (and its vertices) to the other surface."""
    rng = np.random.default_rng(seed)
    a, b = sample_surface(va, fa, samples, rng), sample_surface(vb, fb, samples, rng)
    return float(max(distance_to_mesh(a, vb, fb, k).max(), distance_to_mesh(b, va, fa, k).max()))


def _flat(v: np.ndarray, f: np.ndarray, colors_of) -> tuple:
    """Unshared corners of triangles ``f``: positions, face normals and colours (V = 3 F)."""
    corners = v[f].reshape(-1, 3)
    t = v[f]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 1e-30, n / np.where(ln > 1e-30, ln, 1.0), np.array([0.0, 1.0, 0.0]))
    return corners, np.repeat(n, 3, axis=0), colors_of(corners)


def build_chain(mesh, key: str, max_levels: int = MAX_LEVELS, ratio: float = LEVEL_RATIO) -> PropChainRep:
    """The triangle chain of a ``sim.props.PropMesh`` (module docstring)."""
    import fast_simplification
    from scipy.spatial import cKDTree

    v0 = np.asarray(mesh.positions, np.float64)
    f0 = np.asarray(mesh.faces, np.int64)
    cols = np.asarray(mesh.colors, np.float32)
    # drop degenerate triangles (repeated corner): they hold no surface and upset the simplifier
    f0 = f0[(f0[:, 0] != f0[:, 1]) & (f0[:, 1] != f0[:, 2]) & (f0[:, 0] != f0[:, 2])]
    if not len(f0):
        f0 = np.asarray(mesh.faces, np.int64)[:1]
    sphere = bounding_sphere(v0[np.unique(f0)])
    tree = cKDTree(v0)
    colors_of = lambda p: cols[tree.query(p)[1]]  # noqa: E731
    levels = [(v0, f0)]
    errors = [0.0]
    for lvl in range(1, max_levels):
        target = 1.0 - ratio ** lvl
        if len(f0) * (1.0 - target) < MIN_TRIANGLES:
            break
        try:
            v, f = fast_simplification.simplify(v0.astype(np.float32), f0.astype(np.int32), target_reduction=target)
        except Exception:  # the simplifier gives up on some inputs: keep the levels so far
            break
        v, f = np.asarray(v, np.float64), np.asarray(f, np.int64).reshape(-1, 3)
        if not len(f) or len(f) > STALL_FRACTION * len(levels[-1][1]) or not np.isfinite(v).all():
            break
        err = max(ERROR_SAFETY * hausdorff(v0, f0, v, f), errors[-1], 1e-9 * max(sphere[3], 1e-9))
        if err > MAX_ERROR_FRACTION * sphere[3]:
            break
        levels.append((v, f))
        errors.append(err)
    pos, nrm, col, idx, first, count, base = [], [], [], [], [], [], 0
    for v, f in levels:
        p, n, c = _flat(v, f, colors_of)
        pos.append(p)
        nrm.append(n)
        col.append(c)
        idx.append(np.arange(base, base + len(p), dtype=np.uint32).reshape(-1, 3))
        first.append(sum(count))
        count.append(len(f))
        base += len(p)
    return PropChainRep(key=key, positions=np.concatenate(pos).astype(np.float32),
                        normals=np.concatenate(nrm).astype(np.float32), colors=np.concatenate(col).astype(np.float32),
                        indices=np.concatenate(idx), level_first=np.asarray(first, np.int64),
                        level_count=np.asarray(count, np.int64),
                        level_error=np.maximum.accumulate(np.asarray(errors, np.float64)), sphere=sphere)


def cache_dir() -> Path:
    """``$CROWD_CACHE_DIR`` or ``~/.cache/crowd``."""
    d = os.environ.get(CACHE_ENV, "")
    return Path(d).expanduser() if d else Path.home() / ".cache" / "crowd"


def chain_key(mesh, max_levels: int, ratio: float) -> str:
    """sha256 hex of everything a chain depends on."""
    h = hashlib.sha256(f"props-format-{FORMAT_VERSION}-{max_levels}-{ratio!r}-{ERROR_SAMPLES}-{ERROR_SEED}-{NEAREST_TRIANGLES}-{TARGET_SAMPLES}-{ERROR_SAFETY}".encode())
    for a in (mesh.positions, mesh.faces, mesh.colors):
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


_ARRAYS = ("positions", "normals", "colors", "indices", "level_first", "level_count", "level_error", "sphere")


def cached_chain(mesh, key: str, cache: bool = True, directory: Path | None = None, max_levels: int = MAX_LEVELS,
                 ratio: float = LEVEL_RATIO) -> PropChainRep:
    """:func:`build_chain`, loaded from / stored to the content-addressed cache."""
    if not cache:
        return build_chain(mesh, key, max_levels, ratio)
    path = (directory or cache_dir()) / f"props-{chain_key(mesh, max_levels, ratio)}.npz"
    if path.is_file():
        try:
            with np.load(path) as z:
                arrays = {k: z[k] for k in _ARRAYS}
            rep = PropChainRep(key=key, **arrays)
            if (rep.indices.ndim == 2 and rep.indices.shape[1] == 3 and rep.level_count.sum() == len(rep.indices)
                    and rep.indices.size and int(rep.indices.max()) < len(rep.positions)
                    and np.isfinite(rep.level_error).all() and np.isfinite(rep.positions).all()):
                return rep
        except Exception:  # truncated or corrupt entry: rebuild it
            pass
    rep = build_chain(mesh, key, max_levels, ratio)
    try:
        with atomic_open(path) as f:
            np.savez(f, **{k: getattr(rep, k) for k in _ARRAYS})
    except OSError:  # a read-only cache folder costs a rebuild next time, nothing else
        pass
    return rep
