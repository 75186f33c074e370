"""The camera ray through a window pixel, for fragment shaders that light by view direction without a
camera-relative position varying (``shaders/lit.frag`` compiled with ``PIXEL_RAY``).

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
