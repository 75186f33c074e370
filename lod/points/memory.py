"""Memory of mode points' representations before they are built (``crowd.memory``'s hooks): the estimate per
character (the hierarchy that follows the animation: independent of the clips' length; the per-keyframe-pair
octrees of Wand & Strasser §3.3: poses x triangles; the sizes of both in :mod:`lod.points.sizes`, the path each
character takes by :mod:`lod.points.paths`) and, when the guard refuses a scene, each character's share named
with its path and the setting that would shrink it. Re-exported by :mod:`lod.points.mode`."""
from __future__ import annotations

from lod.points.params import PARAMS
from lod.points.paths import animation_path
from lod.points.poses import clip_poses
from lod.points.sizes import baked_size, follow_bytes


def memory_estimate(characters, params: dict) -> int:
    """Bytes of the point hierarchies mode "points" will build (``crowd.memory``'s hook): per character
    the follow hierarchy (:func:`lod.points.sizes.follow_bytes`) where it takes that path, else its baked
    octrees (:func:`lod.points.sizes.baked_size`: triangles x the keyframe segments x the bytes per
    triangle and segment, :data:`lod.points.config.POINTS_SEGMENT_BYTES_COEF`, growing with the mesh).

    characters : built characters (the segments are counted: for a skinned one the poses
        :func:`lod.points.poses.clip_poses` chooses, as :func:`lod.points.mode.build` will) or scene
        character specs (before building: ``GENERATOR_SEGMENTS`` segments of the spec's triangles; a glTF
        spec counts 0 here and is estimated once built)."""
    p = {k: v.default for k, v in PARAMS.items()} | dict(params)
    total = 0
    for ch in characters:
        kind = getattr(ch, "kind", None)
        if p["animation"] != "baked" and (kind == "skinned" or (kind is None and getattr(ch, "generator", None))
                                         or (kind == "keyframed" and animation_path(ch, p)[0] == "follow")):
            total += follow_bytes(ch)  # independent of the clips' length (lod.points.follow)
            continue
        total += baked_size(ch, p)
    return int(total)


def memory_causes(characters, params: dict, names) -> list:
    """(bytes, clause) per character of :func:`memory_estimate`, each naming the character, the path and
    the ``[lod]`` setting that changes it (``crowd.memory``'s refusal)."""
    p = {k: v.default for k, v in PARAMS.items()} | dict(params)
    out = []
    for ch, name in zip(characters, names):
        b = memory_estimate([ch], p)
        if not b:
            continue
        kind = getattr(ch, "kind", None)
        baked = p["animation"] == "baked" or (kind == "keyframed" and animation_path(ch, p)[0] == "baked")
        if not baked:
            out.append((b, f"mode points' hierarchy of character {name!r} (one, whatever its clips' length): fewer "
                           "triangles"))
        elif kind == "skinned":
            poses = clip_poses(ch, int(p["keyframes"]), float(p["pose_error"]), int(p["max_keyframes"]))
            longest = max(poses, key=lambda c: float(ch.clip(c).duration))
            out.append((b, f"mode points' octrees of character {name!r}, one per keyframe pair: "
                           f"{sum(len(cp.times) for cp in poses.values())} poses, {len(poses[longest].times)} of them "
                           f"for its {float(ch.clip(longest).duration):.3g} s clip {longest!r}; set [lod] animation "
                           "= \"follow\" (samples placed with the animation, memory independent of the clips' "
                           "length) or a larger pose_error"))
        else:
            out.append((b, f"mode points' octrees of character {name!r}, one per keyframe pair of its keyframe "
                           "animations: fewer keyframes" + ("" if kind is None else
                                                           ", or [lod] animation = \"follow\" when they share one "
                                                           "triangle list")))
    return out


__all__ = ["memory_causes", "memory_estimate"]
