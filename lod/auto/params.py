"""The ``[lod]`` keys of mode auto (``lod.modes``' ``PARAMS`` of the mode, read by :mod:`lod.auto.build`) and the
candidates ``[lod] candidates`` names."""
from __future__ import annotations

from lod.auto.control import SWITCH_FRAMES
from lod.chains import mode as tm
from lod.clusters.config import CLUSTERS_LEAF_TRIANGLES
from lod.points.config import POINTS_MAX_POSES, POINTS_POSE_ERROR
from lod.points.params import PARAMS as POINTS_PARAMS
from sim.params import Param

#: candidate representations mode "auto" can choose among (``[lod] candidates``)
CANDIDATES = ("triangles", "clusters", "points")

#: ``[lod]`` keys of mode "auto"
PARAMS: dict = {
    "poe": Param("float", 1.0, min=0.0, max=1000.0,
                 doc="pixels of error: each instance gets the cheapest representation whose error projects below "
                     "this (the start value of the bound in budget mode)"),
    "budget_ms": Param("float", 0.0, min=0.0, max=10000.0,
                       doc="frame-time budget in ms; 0 = fixed bound poe, > 0 = the bound adapts to the budget"),
    "candidates": Param("str", ",".join(CANDIDATES),
                        doc="comma-separated representations to choose among: triangles (always), clusters, points"),
    "max_splat": Param("int", 3, min=1, max=3, doc="largest splat size (pixels) of the point candidate"),
    "points_error": Param("str", "splat+keyframes", choices=("splat", "splat+keyframes"),
                          doc="error of the point candidate: its splat size (issue 7's definition), or the splat "
                              "size plus the projected keyframe-interpolation deviation of the baked poses "
                              "(bounds the image error against the skinned mesh)"),
    "cluster_error_scale": Param("float", 1.0, min=1.0, max=100.0,
                                 doc="the cluster candidate cuts at poe / this: VDR-AM's per-cluster error "
                                     "under-estimates the image error about 2-3x against the triangle chains' "
                                     "(scripts/bench_auto.md); 1 keeps the paper's measure"),
    "adapt": Param("bool", True, doc="fit the per-unit costs online to the measured frames, the calibration as "
                                     "prior (lod.auto.online), and choose the frame plan with hysteresis "
                                     "(lod.auto.control); false prices with the stored calibration alone and "
                                     "draws the cheapest plan every frame"),
    "explore": Param("bool", True, doc="try a frame plan the online fit is unsure about and that could win: a cut "
                                       "to it for 2 measured frames (a warm-up frame, whose draw compiled, "
                                       "replaced by another) and back; at most a tenth of the frames after an "
                                       "allowance of 8 at the start (with adapt)"),
    "switch_frames": Param("int", SWITCH_FRAMES, min=0, max=120,
                           doc="frames over which a change of frame plan fades the instances that change "
                               "representation (screen-door, as keyframe blends); 0 switches at once"),
    "levels": tm.PARAMS["levels"],
    "ratio": tm.PARAMS["ratio"],
    "leaf_triangles": Param("int", CLUSTERS_LEAF_TRIANGLES, min=8, max=1_000_000,
                            doc="§4.2 s of the cluster candidate's hierarchies (mode clusters' leaf_triangles)"),
    "keyframes": Param("int", 0, min=0, max=256,
                       doc="poses baked per clip for the point candidate's hierarchies, evenly spaced; 0 = the "
                           "fewest within pose_error (mode points' keyframes)"),
    "pose_error": Param("float", POINTS_POSE_ERROR, min=1e-4, max=1.0,
                        doc="pose error bound of the point candidate's baked poses, a fraction of the "
                            "character's largest rest extent (mode points' pose_error)"),
    "max_keyframes": Param("int", POINTS_MAX_POSES, min=2, max=4096,
                           doc="cap on the poses baked per clip (mode points' max_keyframes)"),
    "far_pixels": POINTS_PARAMS["far_pixels"],
}


def parse_candidates(value) -> tuple:
    """``[lod] candidates`` as a tuple of names in :data:`CANDIDATES` order
    ("triangles" always included); ValueError naming the key otherwise."""
    names = [v.strip() for v in str(value).split(",") if v.strip()]
    bad = [n for n in names if n not in CANDIDATES]
    if bad or not names:
        raise ValueError(f"[lod] candidates: expected a comma-separated subset of {', '.join(CANDIDATES)}, "
                         f"got {value!r}")
    return tuple(c for c in CANDIDATES if c in names or c == "triangles")


__all__ = ["CANDIDATES", "PARAMS", "parse_candidates"]
