"""A plain-data summary of a character, as printed by ``crowd info ASSET``."""
from __future__ import annotations

import numpy as np

#: Sampling rate (frames per second) of the animated bounding box.
DESCRIBE_FPS = 30.0
#: At most this many samples per clip (long clips are sampled more sparsely).
DESCRIBE_MAX_SAMPLES = 600


def _box(lo: np.ndarray, hi: np.ndarray) -> dict:
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return {"min": [float(x) for x in lo], "max": [float(x) for x in hi], "size": [float(x) for x in hi - lo]}


def _sample_times(duration: float) -> np.ndarray:
    d = float(duration)
    if not (d > 0.0 and np.isfinite(d)):
        return np.zeros(1)
    n = int(min(max(np.ceil(d * DESCRIBE_FPS), 1), DESCRIBE_MAX_SAMPLES))
    return np.append(np.arange(n) * (d / n), d)


def describe(character) -> dict:
    """Summarise a character as JSON-ready plain data.

    Parameters
    ----------
    character : sim.character.SkinnedCharacter or KeyframedCharacter

    Returns
    -------
    dict with keys
        ``name``, ``kind`` ("skinned" | "keyframed"), ``source``,
        ``joints`` (int, 0 for keyframed), ``joint_names`` (list[str]),
        ``vertices``, ``triangles`` (of the rest mesh / first keyframe),
        ``morph_targets`` (names of a skinned mesh's morph targets, glTF 2.0
        §3.7.2.2; empty otherwise), ``clips`` (list of {name, duration (s), keys, loop}; ``keys`` counts
        distinct key times over all channels, or keyframes),
        ``bounds`` ({"rest": box, "animated": box}, box = {min, max, size},
        lists of 3 floats in metres). The rest box is the mesh at the
        skeleton's rest pose (skinned) or the first keyframe; the animated box
        covers every clip sampled at :data:`DESCRIBE_FPS` with CPU skinning
        (:func:`sim.skinning.skin`, ``skin_morph`` with morph targets), or every keyframe (keyframe animation
        interpolates linearly, so keyframes bound every in-between),
        ``notes`` (list[str], what the importer repaired or made up, e.g.
        "skin weights normalised on 12 vertices (sums 1.8)"; empty when nothing).
    """
    if character.kind == "skinned":
        return _describe_skinned(character)
    if character.kind == "keyframed":
        return _describe_keyframed(character)
    raise ValueError(f"describe: unknown character kind {character.kind!r}; expected 'skinned' or 'keyframed'")


def _describe_skinned(ch) -> dict:
    from sim import skinning

    sk, mesh = ch.skeleton, ch.mesh
    rest, _ = skinning.skin(mesh, sk.skinning_matrices(*sk.rest_pose()))
    lo, hi = rest.min(0), rest.max(0)
    alo, ahi = np.full(3, np.inf), np.full(3, -np.inf)
    clips = []
    for name, clip in ch.clips.items():
        keys = np.unique(np.concatenate([np.asarray(c.times, np.float64).ravel() for c in clip.channels])) if clip.channels else np.zeros(0)
        clips.append({"name": str(name), "duration": float(clip.duration), "keys": int(keys.size), "loop": bool(clip.loop)})
        times = _sample_times(clip.duration)
        mats = clip.skinning_matrices(sk, times)
        mw = clip.morph_weights(mesh.morph, times) if mesh.morph is not None else None
        for k, m in enumerate(mats):
            p, _ = skinning.skin(mesh, m) if mw is None else skinning.skin_morph(mesh, m, mw[k])
            alo = np.minimum(alo, p.min(0))
            ahi = np.maximum(ahi, p.max(0))
    if not ch.clips:
        alo, ahi = lo, hi
    return {
        "name": ch.name,
        "kind": "skinned",
        "source": ch.source,
        "joints": sk.n_joints,
        "joint_names": [str(n) for n in sk.names],
        "vertices": mesh.n_vertices,
        "triangles": mesh.n_triangles,
        "morph_targets": [str(x) for x in mesh.morph.names] if mesh.morph is not None else [],
        "clips": clips,
        "bounds": {"rest": _box(lo, hi), "animated": _box(alo, ahi)},
        "notes": [str(n) for n in getattr(ch, "notes", [])],
    }


def _describe_keyframed(ch) -> dict:
    anims = list(ch.animations.values())
    first = anims[0].keyframes[0] if anims and anims[0].keyframes else None
    clips = []
    lo = hi = alo = ahi = np.zeros(3)
    if first is not None:
        p = np.asarray(first.positions, np.float64)
        lo, hi = p.min(0), p.max(0)
        alo, ahi = lo.copy(), hi.copy()
    for an in anims:
        clips.append({"name": str(an.name), "duration": float(an.duration), "keys": len(an.keyframes), "loop": bool(an.loop)})
        for kf in an.keyframes:
            p = np.asarray(kf.positions, np.float64)
            if p.size:
                alo = np.minimum(alo, p.min(0))
                ahi = np.maximum(ahi, p.max(0))
    return {
        "name": ch.name,
        "kind": "keyframed",
        "source": ch.source,
        "joints": 0,
        "joint_names": [],
        "vertices": 0 if first is None else int(len(first.positions)),
        "triangles": 0 if first is None else int(len(first.indices)),
        "morph_targets": [],
        "clips": clips,
        "bounds": {"rest": _box(lo, hi), "animated": _box(alo, ahi)},
        "notes": [str(n) for n in getattr(ch, "notes", [])],
    }
