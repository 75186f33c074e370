"""DrawList: the plain-array contract between ``lod`` and ``render``."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: floats per instance in DrawBatch.instance_data
INSTANCE_FLOATS = 16
#: ``DrawBatch.fade`` roles: the outgoing and the incoming batch of a transition
FADE_OUT = 1
FADE_IN = -1


def fade_uniform(fade) -> tuple:
    """``(t, role)`` as the float pair of the shaders' ``u_fade`` uniform;
    (0, 0) draws every fragment (no fade). ``t`` is clamped to [0, 1]; a
    non-finite ``t`` or an unknown role is a ValueError."""
    if fade is None:
        return (0.0, 0.0)
    t, role = float(fade[0]), int(fade[1])
    if role not in (FADE_OUT, FADE_IN) or t != t or t in (float("inf"), float("-inf")):
        raise ValueError(f"DrawBatch.fade: expected (t in [0, 1], +1 or -1), got {fade!r}")
    return (min(1.0, max(0.0, t)), float(role))


@dataclass
class DrawBatch:
    """Instances drawn with one representation part in one (instanced) draw.

    rep : str
        Key of a representation the renderer has uploaded (e.g. "none:walker").
    part : int
        Which part of the representation: clip index for skinned meshes,
        segment index for keyframe animations.
    instance_ids : (k,) int32
        Agent indices into CrowdState (for telemetry, picking, tests).
    instance_data : (k, 16) float32
        Per instance: rows 0..2 of the camera-relative model matrix (12 floats,
        row-major 3x4: rotation*scale | translation relative to DrawList.origin),
        then 4 animation floats whose meaning the representation defines
        (skinned: [frame coordinate in the baked joint table, 0, 0, 0];
        keyframed: [u in [0, 1] within the segment, 0, 0, 0]).
    triangles : int
        Triangles this batch submits (all instances).
    points : int
        Points this batch submits.
    level : int
        LOD level drawn (0 = full detail); for colouring by level.
    tint : (4,) float or None
        Debug colouring (VDR-AM Fig. 11): RGB mixed into the vertex colour
        with weight A; None draws the true colours.
    fade : (t, role) or None
        Screen-door (dither) transition between two selections of the same
        instances (Friedrich, Polthier & Schmies §3, applied to discrete
        representations; see ``lod.temporal.selection``): ``t`` in [0, 1] is
        the frame's transition weight and ``role`` is :data:`FADE_OUT` (+1, the
        outgoing batch: drawn where ``dither(pixel) >= t``) or :data:`FADE_IN`
        (-1, the incoming batch: drawn where ``dither(pixel) < t``). The two
        patterns are complementary, so a pixel both cover is drawn by exactly
        one of them. None (default) draws every fragment.
    """

    rep: str
    part: int
    instance_ids: np.ndarray
    instance_data: np.ndarray
    triangles: int = 0
    points: int = 0
    level: int = 0
    tint: tuple | None = None
    fade: tuple | None = None

    @property
    def representation(self) -> str:
        """Representation family, the prefix of ``rep`` ("none", "points", ...)."""
        return self.rep.split(":", 1)[0]

    @property
    def n_instances(self) -> int:
        return int(self.instance_ids.shape[0])


@dataclass
class DrawList:
    """What to draw this frame.

    origin : (3,) float64
        World point all positions are made relative to (the camera position) so
        that float32 on the GPU never sees large coordinates.
    view : (4, 4) float32, camera-relative view matrix (camera at origin)
    proj : (4, 4) float32
    size : (width, height) pixels
    batches : list[DrawBatch]
    stats : dict of counts ("instances", "culled", "triangles", "points", ...)
    options : dict of per-frame drawing options the selector chose, read by
        the renderer's drawers (e.g. "splat_size" in pixels for point splats)
    poses : lod.poses.PoseTable or None: the frame's distinct poses per skinned
        character, each drawn copy's slot in its instance float 13
        (``lod.poses.PoseSharing.assign``); None draws every copy skinned
        on its own (the per-instance palette path)
    """

    origin: np.ndarray
    view: np.ndarray
    proj: np.ndarray
    size: tuple
    batches: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)
    poses: object = None

    @property
    def n_instances(self) -> int:
        return sum(b.n_instances for b in self.batches)

    @property
    def warm_up(self) -> bool:
        """The draw made GL objects (``stats["gl_created"]``, set by the renderer: a program compiled on first use, a
        buffer allocated or grown): its time carries a one-time cost, and what learns costs from frame times
        (mode auto's fit, a frame budget) leaves it out (issue 50, item 3)."""
        try:
            return int(self.stats.get("gl_created", 0) or 0) > 0
        except (TypeError, ValueError):
            return False

    @property
    def triangles(self) -> int:
        return sum(b.triangles for b in self.batches)

    @property
    def points(self) -> int:
        return sum(b.points for b in self.batches)
