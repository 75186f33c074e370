"""Screen-space helpers of the compute passes (points' splats, the compute rasteriser): the camera ray
through a window pixel, and the resolve rectangles that copy a compute pass's filled tiles to the frame.

The camera ray through a window pixel, for fragment shaders that light by view direction without a
camera-relative position varying (``shaders/core/lit.frag`` compiled with ``PIXEL_RAY``).

Why: on llvmpipe every vertex output is a vec4 slot that the vertex pipeline stores, clips and hands to
triangle setup, which computes interpolation planes per fragment input; on heavy characters that is a large
share of the frame (scripts/bench_full_detail.md). The only use ``lit.frag`` made of the interpolated
camera-relative position was the headlight direction ``-normalize(v_world)``, and for a perspective camera at
the origin of that space the direction to the surface point seen at pixel centre (x, y) is the direction of
the pixel's ray, affine in (x, y): ``ray = A @ (x, y, 1)`` with A from the inverse view-projection. Without
the varying, Mesa's linker drops the position output from the draw programs (the transform-feedback capture
programs, which record it, are compiled separately and keep it).
"""
from __future__ import annotations

import numpy as np


def pixel_ray_matrix(view_proj: np.ndarray, size) -> np.ndarray:
    """(3, 3) float64 A such that ``A @ (x, y, 1)`` points from the camera (the origin of the camera-relative
    world ``view_proj`` maps) through window position (x, y) (pixels, origin bottom-left, as gl_FragCoord).

    ``view_proj`` must be a perspective projection times a rigid view (the clip w of a point then depends on
    its depth only): the ray's homogeneous point at NDC depth 0 has the same w for every (x, y).
    """
    w, h = float(size[0]), float(size[1])
    inv = np.linalg.inv(np.asarray(view_proj, np.float64))
    cols = []
    for x, y in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)):
        p = inv @ np.array([2.0 * x / w - 1.0, 2.0 * y / h - 1.0, 0.0, 1.0])
        cols.append(p[:3] / p[3])
    d00, d10, d01 = cols
    return np.stack([d10 - d00, d01 - d00, d00], axis=1)


def write_pixel_ray(prog, view_proj: np.ndarray, size) -> None:
    """Set ``u_pixel_ray`` of ``prog`` (when it has one)."""
    if "u_pixel_ray" in prog:
        a = pixel_ray_matrix(view_proj, size)
        if np.all(np.isfinite(a)):
            prog["u_pixel_ray"].write(np.ascontiguousarray(a.T, np.float32).tobytes())  # GLSL: column-major
    if "u_pixel_inv" in prog:  # the shadow map's lookup position (lit.frag with shadows on)
        inv = np.linalg.inv(np.asarray(view_proj, np.float64))
        if np.all(np.isfinite(inv)):
            prog["u_pixel_inv"].write(np.ascontiguousarray(inv.T, np.float32).tobytes())
            prog["u_pixel_size"].value = (float(size[0]), float(size[1]))


def resolve_rects(flags: np.ndarray, size, tile: int, margin: int, splat: int) -> np.ndarray:
    """(R, 4) int64 pixel rectangles (x0, y0, x1, y1), half-open, that hold
    every pixel a filled anchor can cover.

    flags : (ty, tx) bool, the anchor-slot tiles the depth pass filled (slot
        (sx, sy) = pixel anchor + margin, tile (sy // tile, sx // tile))
    size : (width, height) pixels; splat : footprint side s (1..3 <= margin + 1)

    Pixel p reads the slots p + margin - d for 0 <= d < s, so a block of
    tile x tile pixels is needed when a flagged tile meets its slot range; the
    blocks of a row are merged into runs (few, wide rectangles).
    """
    w, h = int(size[0]), int(size[1])
    f = np.asarray(flags, bool)
    ty, tx = f.shape
    s = int(splat)
    # summed-area table of the flags: any flag in a tile range in O(1)
    sat = np.zeros((ty + 1, tx + 1), np.int64)
    sat[1:, 1:] = f.astype(np.int64).cumsum(0).cumsum(1)

    def ranges(n_px, n_tiles):
        p0 = np.arange(0, n_px, tile)
        p1 = np.minimum(p0 + tile, n_px)
        lo = np.clip((p0 + margin - s + 1) // tile, 0, n_tiles - 1)
        hi = np.clip((p1 - 1 + margin) // tile, 0, n_tiles - 1)
        return p0, p1, lo, hi + 1

    x0, x1, lx, hx = ranges(w, tx)
    y0, y1, ly, hy = ranges(h, ty)
    cnt = sat[np.ix_(hy, hx)] - sat[np.ix_(ly, hx)] - sat[np.ix_(hy, lx)] + sat[np.ix_(ly, lx)]
    need = cnt > 0  # (pixel tile rows, pixel tile columns)
    pad = np.zeros((need.shape[0], need.shape[1] + 2), np.int8)
    pad[:, 1:-1] = need
    d = np.diff(pad, axis=1)
    rows, starts = np.nonzero(d == 1)
    _, ends = np.nonzero(d == -1)  # same row order: each run's start then end
    if not rows.shape[0]:
        return np.zeros((0, 4), np.int64)
    return np.stack([x0[starts], y0[rows], x1[ends - 1], y1[rows]], axis=1).astype(np.int64)


def rect_vertices(rects: np.ndarray, size) -> np.ndarray:
    """(6 R, 2) float32 NDC corners of two triangles per pixel rectangle."""
    r = np.asarray(rects, np.float64).reshape(-1, 4)
    w, h = float(size[0]), float(size[1])
    xa, ya, xb, yb = (2.0 * r[:, 0] / w - 1.0, 2.0 * r[:, 1] / h - 1.0, 2.0 * r[:, 2] / w - 1.0,
                      2.0 * r[:, 3] / h - 1.0)
    v = np.stack([np.stack([xa, ya], 1), np.stack([xb, ya], 1), np.stack([xa, yb], 1),
                  np.stack([xb, yb], 1), np.stack([xa, yb], 1), np.stack([xb, ya], 1)], axis=1)
    return v.reshape(-1, 2).astype(np.float32)
