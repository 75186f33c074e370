"""Which point representation a character gets in mode points, and building the one that follows the animation.

Two paths (``[lod] animation``):

- ``"follow"`` (``lod.points.follow``): one hierarchy of rest-pose samples per character, placed with the
  animation at draw time. Memory and build time do not grow with the clips' length (the clips' frames are
  only measured, for the bounds and spacing); the samples follow the skinned animation exactly (morph
  targets included), with no pose error.
- ``"baked"`` (``lod.points.mode``, Wand & Straßer §3.3 as the paper has it): skinned clips baked to
  keyframes (``lod.points.poses``) and one octree per keyframe pair. Its memory grows as poses x triangles
  (a 30 s clip of a 3,000-triangle humanoid: 567 poses, 1,054 MB; a 35 s dance of a 62 K-triangle one: an
  estimated 144 GB); it draws stored samples, with no pose or placement pass.

``"auto"`` (the default) chooses, per character, by :func:`animation_path`:

* a keyframe animation whose segments do not share one triangle list (triangles appear or vanish between
  keyframes, §3) can only be baked;
* a skinned character follows: exact poses, memory independent of the clip, and measured no slower to draw
  on the crowds points serves (``scripts/bench_points_follow.py``);
* a keyframed character with one triangle list is baked while its per-keyframe-pair octrees are estimated
  below :data:`BAKED_BUDGET_BYTES` (short flip-books such as the Horse and the Flamingo: 14-15 pairs of
  about a thousand triangles, a few MB; their linear interpolation is the animation itself, so baking loses
  nothing and draws stored samples), else it follows.

``crowd info`` states the path and the reason (:func:`path_reason`).
"""
from __future__ import annotations

import numpy as np

from lod.points import config as C
from lod.points.sizes import baked_bytes, follow_bytes

#: a keyframed character with one triangle list is baked while its octrees are estimated below this
BAKED_BUDGET_BYTES = 64_000_000


def shared_topology(kf) -> tuple | None:
    """(vbase (S,) int64, V, local indices (T, 3) int64) when every segment of a ``KeyframedRep`` draws the
    same local triangle list over its own V vertices, else None."""
    idx_all = np.asarray(kf.indices, np.int64).reshape(-1, 3)
    tris, vbase, V = None, [], 0
    for s in range(kf.n_parts):
        f, c = int(kf.seg_first[s]) // 3, int(kf.seg_count[s]) // 3
        idx = idx_all[f:f + c]
        if idx.size == 0:
            return None
        lo = int(idx.min())
        loc = idx - lo
        if tris is None:
            tris, V = loc, int(loc.max()) + 1
        elif loc.shape != tris.shape or not np.array_equal(loc, tris):
            return None
        vbase.append(lo)
    if tris is None:
        return None
    return np.asarray(vbase, np.int64), V, tris


def animation_path(character, params: dict) -> tuple[str, str]:
    """(``"follow"`` or ``"baked"``, one sentence why) for ``character`` under the ``[lod]`` keys ``params``
    (module docstring)."""
    want = str(dict(params).get("animation", "auto"))
    kind = getattr(character, "kind", None)
    if kind == "keyframed":
        from lod.full.reps import build_keyframed_rep

        shared = shared_topology(build_keyframed_rep(character, key="probe")) is not None
        if not shared:
            if want == "follow":
                raise ValueError("points mode: animation = \"follow\" needs keyframes that share one triangle list; "
                                 f"character {getattr(character, 'name', '?')!r} changes triangles between keyframes "
                                 "(use animation = \"baked\" or \"auto\")")
            return "baked", "its keyframes change triangles, so each keyframe pair gets its own octree"
        if want in ("follow", "baked"):
            return want, f"[lod] animation = \"{want}\""
        est = baked_bytes(character, params)
        if est <= BAKED_BUDGET_BYTES:
            return "baked", (f"a short keyframe animation: one octree per keyframe pair, an estimated "
                             f"{est / 1e6:.1f} MB, draws stored samples")
        return "follow", (f"its keyframe pairs would need an estimated {est / 1e6:.0f} MB as octrees "
                          f"(above {BAKED_BUDGET_BYTES / 1e6:.0f} MB): one rest-pose hierarchy instead")
    if want in ("follow", "baked"):
        return want, f"[lod] animation = \"{want}\""
    return "follow", "skinned: rest-pose samples placed with the animation (exact poses, memory independent of " \
                     "the clips' length)"


def describe_path(character, params: dict) -> list:
    """Lines for ``crowd info``: the path mode points takes for ``character`` and why, and what it costs (the
    baked path's poses per clip, ``lod.points.poses``; the follow path's estimate, whatever the clips' length)."""
    kind = getattr(character, "kind", None)
    if kind not in ("skinned", "keyframed") or (kind == "skinned" and not character.mesh.is_skinned):
        return []
    path, why = animation_path(character, params)
    out = [f"points: {path} ({why})"]
    if path == "follow":
        out.append(f"  one hierarchy of rest-pose samples, an estimated {follow_bytes(character) / 1e6:.1f} MB "
                   "(independent of the clips' length); [lod] animation = \"baked\" would bake poses per clip")
        return out
    if kind == "skinned":
        from lod.points.poses import character_extent, clip_poses

        p = {k: v for k, v in dict(params).items()}
        pe = float(p.get("pose_error", C.POINTS_POSE_ERROR))
        chosen = clip_poses(character, int(p.get("keyframes", 0)), pe, int(p.get("max_keyframes", C.POINTS_MAX_POSES)))
        ext = character_extent(character)
        out.append(f"  poses per clip (pose_error {100 * pe:g} % of the extent {ext:.4g}), an estimated "
                   f"{baked_bytes(character, params) / 1e6:.1f} MB:")
        for name, cp in chosen.items():
            d = float(character.clip(name).duration)
            out.append(f"    {name}: {len(cp.times)} poses over {d:.3g} s, pose error {cp.error:.3g} "
                       f"({100 * cp.error / ext:.2g} %)" + (" (capped: above the bound)" if cp.capped else ""))
    else:
        out.append(f"  an estimated {baked_bytes(character, params) / 1e6:.1f} MB")
    return out


def build_follow_rep(character, name: str, params: dict, fps: float = 30.0, cache=None, progress=None):
    """The :class:`lod.points.follow.FollowRep` of a skinned or keyframed character (hierarchy cached in
    ``cache``, a ``lod.points.rep.HierarchyCache``)."""
    from lod.full.reps import build_keyframed_rep, build_rep
    from lod.full import frames as full_frames
    from lod.points.follow import FollowRep, build_follow, cached_follow
    from lod.points.rep import HierarchyCache

    cache = cache if cache is not None else HierarchyCache()
    key = f"points:{name}"
    bp = {"spacing_fraction": float(params.get("spacing_fraction", C.POINTS_SPACING_FRACTION))}
    say = None
    if getattr(character, "kind", None) == "keyframed":
        kf = build_keyframed_rep(character, key=key)
        shared = shared_topology(kf)
        if shared is None:
            raise ValueError(f"points mode: character {name!r}: its keyframes change triangles between segments; "
                             "only the baked path (animation = \"baked\") can draw it")
        vbase, V, tris = shared
        frames = full_frames.KeyframedFrames(kf.positions0, kf.positions1, vbase, V, tris)
        sl = slice(int(vbase[0]), int(vbase[0]) + V)
        cols, nrms = np.asarray(kf.colors0[sl], np.float64), np.asarray(kf.normals0[sl], np.float64)
        arrays = (kf.positions0, kf.positions1, kf.colors0, kf.normals0, tris, vbase)
        tree = cached_follow(cache, arrays, bp, lambda: build_follow(frames, cols, nrms, progress=say, **bp))
        return FollowRep(key, kf, tree, vbase, int(params.get("splat_size", 2)), str(params.get("renderer", "compute")),
                         bool(params.get("coarse", True)))
    base = build_rep(character, fps=float(fps), key=key)
    if getattr(base, "kind", None) != "skinned":
        raise TypeError(f"points mode: expected a skinned or keyframed character, got {type(character).__name__}")
    frames = full_frames.SkinnedFrames.of(base)
    t = base.targets
    arrays = (base.positions, base.normals, base.colors, base.joints, base.weights, base.indices, base.joint_table) + \
        ((t.first, t.count, t.column, t.dpos, t.weights) if t is not None else ())
    clips = [np.arange(int(o), int(o) + int(n)) for o, n in zip(base.clip_offset, base.clip_frames)]
    tree = cached_follow(cache, arrays, bp, lambda: build_follow(
        frames, base.colors, base.normals, joints=base.joints, weights=base.weights,
        n_joints=int(base.joint_table.shape[1]), clips=clips, progress=say, **bp))
    return FollowRep(key, base, tree, None, int(params.get("splat_size", 2)), str(params.get("renderer", "compute")),
                     bool(params.get("coarse", True)))


__all__ = ["BAKED_BUDGET_BYTES", "animation_path", "build_follow_rep", "describe_path", "shared_topology"]
