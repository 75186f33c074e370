"""DrawList: the plain-array contract between ``lod`` and ``render``."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: floats per instance in DrawBatch.instance_data
INSTANCE_FLOATS = 16


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
    """

    rep: str
    part: int
    instance_ids: np.ndarray
    instance_data: np.ndarray
    triangles: int = 0
    points: int = 0
    level: int = 0
    tint: tuple | None = None

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
    """

    origin: np.ndarray
    view: np.ndarray
    proj: np.ndarray
    size: tuple
    batches: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)

    @property
    def n_instances(self) -> int:
        return sum(b.n_instances for b in self.batches)

    @property
    def triangles(self) -> int:
        return sum(b.triangles for b in self.batches)

    @property
    def points(self) -> int:
        return sum(b.points for b in self.batches)
