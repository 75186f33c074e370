"""Which instances the compute rasteriser (render/raster/) takes (Nanite's split of hardware and software rasterisation,
made per instance here: an instance whose triangles are all small on screen is rasterised in compute, the
others by the hardware path; inside the compute path every triangle is tested again, and one whose window
box exceeds the threshold, or that crosses the near plane, goes to the hardware path after all).

A representation's triangle size is summarised once (:func:`triangle_extent`: a high percentile of its
triangles' largest model-space extent, over the bind or first-keyframe pose); an instance's estimate is that
size scaled by the instance's scale and projected at the distance of the nearest point of its bounding sphere.

It lives in ``lod`` (plain numpy, no GL) so that the LOD layer can predict the split the renderer will make
(mode auto's cost model prices the two paths' triangles apart; ``DrawList.stats["raster_triangles"]`` is the
renderer's count after the draw).
"""
from __future__ import annotations

import numpy as np

#: default [render] raster_threshold (pixels): copies whose triangles' 90th-percentile window extent is at most
#: this go to the compute rasteriser. Measured (scripts/bench_raster_sizes.md, a static 3,000-triangle humanoid,
#: both paths alternately, loaded 2-core machine): compute / hardware CPU 1.76x faster at 0.5 px, 1.53x at 1 px,
#: 1.15x at 2 px, 0.81x at 4 px, 0.42x at 8 px: the crossover lies between 2 and 4 px
DEFAULT_THRESHOLD = 2.0
#: inside the compute path a triangle goes back to the hardware when its window box is wider or taller than
#: this many thresholds (a few larger triangles of a small copy cost less rasterised in compute than drawn by
#: the vertex-pulling hardware draw)
ASIDE_FACTOR = 4.0
#: largest threshold (pixels): the edge functions of a triangle within it stay below 2^31 (raster_tri.glsl)
MAX_THRESHOLD = 64.0
#: percentile of the triangles' extents that must fall below the threshold for an instance to go to compute
EXTENT_PERCENTILE = 90.0


def triangle_extent(positions, indices, percentile: float = EXTENT_PERCENTILE) -> tuple[float, float, np.ndarray]:
    """(extent, radius, centre) of a mesh: the ``percentile`` of its triangles' largest axis-aligned extent
    (model units), the radius and centre of a sphere holding every vertex (finite ones)."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    ok = np.isfinite(p).all(axis=1)
    if not ok.any() or not t.shape[0]:
        return 0.0, 0.0, np.zeros(3)
    p = np.where(ok[:, None], p, 0.0)
    lo, hi = p[ok].min(axis=0), p[ok].max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = float(np.sqrt(((p[ok] - centre) ** 2).sum(axis=1).max()))
    c = p[t]
    ext = (c.max(axis=1) - c.min(axis=1)).max(axis=1)
    return float(np.percentile(ext, percentile)), radius, centre


def compute_mask(rows, extent: float, radius: float, centre, proj, height: int, threshold: float,
                 near: float) -> np.ndarray:
    """(k,) bool: instances (rows of lod.drawlist instance data, camera-relative) whose triangles are
    estimated below ``threshold`` pixels (the ``extent`` of :func:`triangle_extent`, projected at the nearest
    point of the instance's bounding sphere) and whose sphere stays beyond twice the ``near`` distance."""
    d = np.asarray(rows, np.float64).reshape(-1, 16)
    m = d[:, :12].reshape(-1, 3, 4)
    scale = np.linalg.norm(m[:, :, :3], axis=1).max(axis=1)
    c = m[:, :, :3] @ np.asarray(centre, np.float64) + m[:, :, 3]
    dist = np.linalg.norm(c, axis=1) - radius * scale
    focal = 0.5 * float(height) * abs(float(np.asarray(proj)[1, 1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        px = extent * scale * focal / dist
    return np.isfinite(px) & np.isfinite(dist) & (dist > 2.0 * near) & (px <= threshold)


def near_distance(proj) -> float:
    """Near-plane distance of a GL perspective projection (0 when it is not one)."""
    p = np.asarray(proj, np.float64)
    a, b = p[2, 2], p[2, 3]
    if p[3, 2] == 0.0 or a == 1.0:
        return 0.0
    return float(abs(b / (a - 1.0)))
