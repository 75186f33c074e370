"""Debug colourings of a DrawList: by representation or by LOD level.

After VDR-AM (Claudio et al.), Fig. 11, which colours each part of a crowd by
the resolution the view selected. Only the tint of each batch changes; what is
drawn does not.
"""
from __future__ import annotations

#: colouring modes accepted by :func:`apply_tints`
COLOR_BY = ("none", "representation", "level")

#: RGB per representation family (the prefix of DrawBatch.rep)
REPRESENTATION_COLORS = {
    "none": (0.85, 0.85, 0.85),
    "static": (0.55, 0.55, 0.55),
    "triangles": (0.20, 0.55, 0.95),
    "points": (0.95, 0.35, 0.20),
    "clusters": (0.25, 0.85, 0.35),
    "far": (0.80, 0.30, 0.90),  # the far tier (lod.far): one splat per agent
}
#: RGB per LOD level, finest first (a perceptual ramp); deeper levels reuse the last
LEVEL_COLORS = (
    (0.19, 0.30, 0.86), (0.12, 0.62, 0.85), (0.15, 0.78, 0.55), (0.55, 0.85, 0.25),
    (0.95, 0.80, 0.15), (0.97, 0.50, 0.10), (0.90, 0.20, 0.15), (0.60, 0.10, 0.35),
)
#: weight of the tint against the vertex colour (shading is kept)
TINT_WEIGHT = 0.75


def apply_tints(drawlist, by: str, statics: frozenset = frozenset()):
    """Set ``tint`` on every batch of ``drawlist`` for colouring ``by``; returns it.

    by : one of COLOR_BY. statics : representation keys drawn as scenery, never tinted.
    """
    if by not in COLOR_BY:
        raise ValueError(f"colour by {by!r}: expected one of {', '.join(COLOR_BY)}")
    for b in drawlist.batches:
        if by == "none" or b.rep in statics:
            b.tint = None
        elif by == "representation":
            rgb = REPRESENTATION_COLORS.get(b.representation, (1.0, 0.0, 1.0))
            b.tint = (*rgb, TINT_WEIGHT)
        else:
            rgb = LEVEL_COLORS[min(max(int(b.level), 0), len(LEVEL_COLORS) - 1)]
            b.tint = (*rgb, TINT_WEIGHT)
    return drawlist
