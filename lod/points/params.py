"""The ``[lod]`` keys of mode points (``lod.modes``' ``PARAMS`` of :mod:`lod.points.mode`, which re-exports
them) and the values two of them accept. Below every module that reads them: the memory estimate
(:mod:`lod.points.sizes`, :mod:`lod.points.memory`), the path rule (:mod:`lod.points.paths`) and the mode."""
from __future__ import annotations

from lod.points import config as C
from sim.params import Param

#: ``[lod] animation`` values
ANIMATION_PATHS = ("auto", "follow", "baked")
#: renderer paths of the point splats
RENDERERS = ("compute", "gl_points")

#: ``[lod]`` keys of mode "points"
PARAMS: dict = {
    "splat_size": Param("int", 2, min=1, max=3, doc="splat size in pixels (§3.2): a node is drawn as points "
                                                    "when its projected spacing is at most this"),
    "keyframes": Param("int", 0, min=0, max=256,
                       doc="poses baked per clip of a skinned character, evenly spaced; 0 = per clip the fewest "
                           "that keep the pose error within pose_error (lod.points.poses)"),
    "pose_error": Param("float", C.POINTS_POSE_ERROR, min=1e-4, max=1.0,
                        doc="largest vertex distance between the interpolated baked poses and the skinned "
                            "animation, as a fraction of the character's largest rest extent (keyframes = 0)"),
    "max_keyframes": Param("int", C.POINTS_MAX_POSES, min=2, max=4096,
                           doc="cap on the poses baked per clip when keyframes = 0"),
    "intervals": Param("int", C.POINTS_TIME_INTERVALS, min=1, max=16,
                       doc="stratification time intervals per keyframe pair (§3.4.2)"),
    "spacing_fraction": Param("float", C.POINTS_SPACING_FRACTION, min=1.0 / 64.0, max=1.0,
                              doc="sample spacing as a fraction of a node's side (§3.1, 1/8-1/16)"),
    "coarse": Param("bool", True, doc="representations coarser than a hierarchy's root: the smallest "
                                      "farthest-point prefix of the root's points whose spacing projects within "
                                      "the splat size, down to one splat per agent (lod.points.coarse)"),
    "splat_blend": Param("float", C.POINTS_SPLAT_BLEND, min=0.0, max=8.0,
                         doc="the compute splat's colour: the mean of the points within this many splat "
                             "footprints (depth) of a pixel's nearest, weighted by projected area; 0 = the "
                             "nearest point alone (cheaper, noisier; scripts/bench_splat_quality.md)"),
    "renderer": Param("str", "compute", choices=RENDERERS,
                      doc="point splat path: compute-shader splats (the points nearest the surface blended by "
                          "projected area, splat_blend) or the GL_POINTS reference (the nearest point per pixel)"),
    "far_pixels": Param("float", 0.0, min=0.0, max=8.0,
                        doc="the far tier (lod.far): an agent whose whole bounding sphere projects to at most this "
                            "many pixels across is drawn as one pre-filtered splat of its measured footprint, "
                            "without a traversal; 0 = off (scenes without instancing groups)"),
    "occlusion": Param("bool", False, doc="occlusion culling of hierarchy nodes against a depth pyramid of the "
                                          "likely occluders (render.points.occlusion; not in Wand & Strasser)"),
    "animation": Param("str", "auto", choices=ANIMATION_PATHS,
                       doc="how the samples move: \"follow\" = one hierarchy of rest-pose samples per character, "
                           "placed with the animation at draw time (memory independent of the clips' length); "
                           "\"baked\" = one octree per keyframe pair (Wand & Strasser 3.3; grows with the clips); "
                           "\"auto\" = per character by a measured rule (lod.points.paths)"),
}
