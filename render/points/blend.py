"""The compute splat's colour rule (issue 43): blend the points that lie on the nearest surface, or keep the nearest.

After Schütz, Kerbl and Wimmer 2021 (high-quality compute splatting): the colour pass of ``points_splat.glsl``
adds, per anchor, every point within a depth tolerance of the anchor's nearest (eye depth ``w <= w_min (1 +
tol)``), its lit colour times its weight and the weight, into integer accumulators; the resolve
(``points_resolve.frag``) takes the weighted mean of the anchors within the tolerance of a pixel's nearest. The
tolerance is a number of splat footprints: one spans ``s * w / f`` metres at eye depth w (s the splat size, f the
pixels per metre at depth 1), so ``tol = footprints * s / f`` relative to w. Weights: the point's projected area
``|n . v|`` (default) or ``flat``. The rule before it, the nearest point alone, stays as ``NEAREST``
(``[lod] splat_blend = 0``). The measurements behind the default are at ``lod.points.config.POINTS_SPLAT_BLEND``.
"""
from __future__ import annotations

import numpy as np

from lod.points import config as C

#: the splat footprints the colour pass blends within unless the DrawList names its own (``splat_blend``)
BLEND_FOOTPRINTS = C.POINTS_SPLAT_BLEND
#: blend weights: the point's projected area, or every point alike
WEIGHTS = ("area", "flat")


def rule_defines(blend: bool, weight: str = "area") -> tuple:
    """Shader defines of a colour rule (points_splat.glsl, points_resolve.frag, points_clear.glsl)."""
    if not blend:
        return ("NEAREST",)
    return ("FLAT_WEIGHT",) if weight == "flat" else ()


def blend_uniforms(proj, height: int, splat: int, footprints: float) -> dict:
    """``u_depth_ab`` and ``u_tol`` of a frame: from the projection ``proj`` (4 x 4, row-major) the eye depth of
    a window depth d, ``B / (A - (2 d - 1))`` with A = -P[2, 2], B = -P[2, 3], and the relative tolerance
    ``footprints * splat / f`` (f = |P[1, 1]| * height / 2 pixels per metre at depth 1). A projection that is not
    perspective, or non-finite numbers, give ``u_tol = -1``: the nearest point's ties alone."""
    P = np.asarray(proj, np.float64).reshape(4, 4)
    a, b = -P[2, 2], -P[2, 3]
    f = abs(P[1, 1]) * 0.5 * float(height)
    ok = bool(np.isfinite([a, b, f]).all() and abs(P[3, 2]) > 0.0 and f > 0.0)
    tol = float(footprints) * float(splat) / f if ok else -1.0
    return {"u_depth_ab": (float(a), float(b)) if ok else (1.0, 1.0),
            "u_tol": max(tol, -1.0) if np.isfinite(tol) else -1.0}


__all__ = ["BLEND_FOOTPRINTS", "WEIGHTS", "blend_uniforms", "rule_defines"]
