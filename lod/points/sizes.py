"""Bytes of each of mode points' two representations of one character, before it is built: the hierarchy that
follows the animation (:func:`follow_bytes`, independent of the clips' length, ``lod.points.follow``) and the
per-keyframe-pair octrees of Wand & Strasser §3.3 (:func:`baked_bytes`: poses x triangles). The path rule
(:mod:`lod.points.paths`) and the memory guard's hooks (:mod:`lod.points.memory`) both read them."""
from __future__ import annotations

import numpy as np

from lod.points import config as C
from lod.points.params import PARAMS
from lod.points.poses import clip_poses

#: bytes of follow hierarchy per character triangle (measured on generated humanoids, lod.points.follow)
FOLLOW_BYTES_PER_TRIANGLE = 300


def follow_bytes(character) -> int:
    """Estimated bytes of a character's follow hierarchy: about ``FOLLOW_BYTES_PER_TRIANGLE`` per triangle,
    whatever its clips' length (measured: ``scripts/bench_points_follow.py``)."""
    if getattr(character, "kind", None) == "skinned":
        tris = int(character.mesh.n_triangles)
    elif getattr(character, "kind", None) == "keyframed":
        tris = max((int(np.asarray(k.indices).reshape(-1, 3).shape[0]) for a in character.animations.values()
                    for k in a.keyframes), default=0)
    else:
        tris = int(getattr(character, "triangles", 0) or (5000 if getattr(character, "generator", None) else 0))
    return int(FOLLOW_BYTES_PER_TRIANGLE * tris)


def baked_size(character, p: dict) -> float:
    """Bytes (unrounded) of the per-keyframe-pair octrees of one character under the complete ``[lod]`` keys
    ``p``: its triangles x the keyframe segments x the bytes per triangle and segment
    (:data:`lod.points.config.POINTS_SEGMENT_BYTES_COEF`, growing with the mesh); 0 for a character points
    cannot bake.

    character : a built character (the segments are counted: for a skinned one the poses
        :func:`lod.points.poses.clip_poses` chooses, as the build will) or a scene character spec (before
        building: ``GENERATOR_SEGMENTS`` segments of the spec's triangles; a glTF spec counts 0 here and is
        estimated once built)."""
    kind = getattr(character, "kind", None)
    if kind == "skinned" and character.mesh.is_skinned:
        tris = character.mesh.n_triangles
        poses = clip_poses(character, int(p["keyframes"]), float(p["pose_error"]), int(p["max_keyframes"]))
        segs = sum(len(cp.times) for cp in poses.values())
    elif kind == "keyframed":
        segs, tris = 0, 0
        for a in character.animations.values():
            segs += len(a.segments)
            tris = max(tris, max((int(np.asarray(k.indices).reshape(-1, 3).shape[0]) for k in a.keyframes),
                                 default=0))
    elif kind is not None:  # a character points cannot bake: nothing built for it
        return 0
    else:  # a spec: only generators say their size before building
        tris = int(getattr(character, "triangles", 0) or (5000 if getattr(character, "generator", None) else 0))
        segs = C.GENERATOR_SEGMENTS
    return tris * segs * C.POINTS_SEGMENT_BYTES_COEF * max(tris, 1) ** C.POINTS_SEGMENT_BYTES_EXP


def baked_bytes(character, params: dict) -> int:
    """Estimated bytes of the per-keyframe-pair octrees of one character (:func:`baked_size` with the defaults
    of :data:`lod.points.params.PARAMS` under ``params``)."""
    return int(baked_size(character, {k: v.default for k, v in PARAMS.items()} | dict(params)))


__all__ = ["FOLLOW_BYTES_PER_TRIANGLE", "baked_bytes", "baked_size", "follow_bytes"]
