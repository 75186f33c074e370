"""LOD mode ``"points"``: point-sample hierarchies of keyframe animations
(Wand & Straßer 2002, §3) selected per instance and frame.

Build (:func:`build`): every character becomes a keyframe animation (skinned
characters are baked with ``sim.keyframes.bake_skinned``, §3 "keyframe
animations", at per-clip times :mod:`lod.points.poses` chooses: by default the
fewest poses whose interpolation stays within ``pose_error`` of the skinned
animation, or ``keyframes`` evenly spaced ones); every segment
(keyframe pair) gets its own point/triangle octree (``lod.points.octree``,
§3.1, §3.3-§3.5), kept in a content-addressed on-disk cache
(:class:`HierarchyCache`).

Selection (:class:`PointsSelector`): whole-animation sphere culling and
segment/u location are those of the full-detail selector
(``lod.full.mode.NoLodSelector``) run on the keyframed form of the characters;
then for each visible instance the octree of its segment is traversed at its
u with its camera-relative model matrix (§3.2, the job writer
:func:`lod.points.jobs.traverse_instances` over all instances of a segment, beside
the per-instance reference :func:`lod.points.jobs.traverse_instances_reference`). The result is
one :class:`PointsBatch` per (character, segment): the instances, and two job
lists ``(instance row, start, count)``: point ranges into the segment's points
and triangle ranges into its ``tri_order``. ``render.points.draw`` draws both.

§3.6 hierarchical instantiation: when the engine hands over the
simulation's instancing groups (``build(..., instancing=...)``), every group
whose clip has one triangle list over all its segments gets a super-hierarchy
per tree depth (``lod.points.instancing``), uploaded as extra point reps; per
frame the tree is walked top-down (:class:`lod.points.instancing.InstancingPlan`)
and only the instances of refined nodes go through the per-instance path
above. Their super-hierarchy draws are ordinary :class:`PointsBatch` es whose
instances are tree nodes (model matrix of the node, u within the node's
super-segment; ``instance_ids`` the node's first agent).

Morph targets (glTF 2.0 §3.7.2.2) of a skinned character are baked into the
keyframes: each keyframe is the pose ``skin ∘ morph`` at its time
(``sim.skinning.skin_morph`` through ``bake_skinned``), so faces and correctives
move with the points and triangles, exactly at the key times and linearly in
between (as every other vertex motion of §3).
"""
from __future__ import annotations

import numpy as np

from lod.drawlist import DrawList
from lod.far.build import build_far_split, merge
from lod.full.mode import NoLodSelector
from lod.full.reps import KeyframedRep, build_keyframed_rep
from lod.points import config as C
from lod.points.coarse import add_coarse
from lod.points.follow_select import follow_batch
from lod.points.jobs import traverse_instances
from lod.points.memory import memory_causes, memory_estimate  # noqa: F401 (the mode interface)
from lod.points.octree import PointHierarchy
from lod.points.params import PARAMS
from lod.points.paths import animation_path, build_follow_rep
from lod.points.poses import clip_poses
from lod.points.rep import HierarchyCache, PointsBatch, PointsRep
from lod.points.traverse import viewport_scale


# ---------------------------------------------------------------------------- build
def keyframed_character(character, keyframes: int, pose_error: float = C.POINTS_POSE_ERROR,
                        max_keyframes: int = C.POINTS_MAX_POSES, poses: dict | None = None):
    """The character as a ``KeyframedCharacter``: skinned characters get every
    clip baked (``sim.keyframes.bake_skinned``: skin ∘ morph when the mesh has
    morph targets) at the times of
    :func:`lod.points.poses.clip_poses` (``keyframes`` evenly spaced poses, or
    with ``keyframes = 0`` the fewest within ``pose_error``), clip order kept so
    that ``CrowdState.clip`` indices stay valid. ``poses``: a dict the chosen
    :class:`lod.points.poses.ClipPoses` are stored in (per clip name)."""
    if getattr(character, "kind", None) == "keyframed":
        return character
    if getattr(character, "kind", None) != "skinned":
        raise TypeError(f"points mode: expected a skinned or keyframed character, got {type(character).__name__}")
    from sim.character import KeyframedCharacter
    from sim.keyframes import bake_skinned

    chosen = clip_poses(character, int(keyframes), float(pose_error), int(max_keyframes))
    if poses is not None:
        poses.update(chosen)
    anims = {name: bake_skinned(character, name, chosen[name].times) for name in character.clips}
    return KeyframedCharacter(name=getattr(character, "name", "character"), animations=anims,
                              source=getattr(character, "source", ""))  # messages name the file


def segment_arrays(kf: KeyframedRep, s: int) -> tuple:
    """(p0, p1, indices, c0, c1, n0, n1) of segment s of a KeyframedRep, local
    vertex numbering (the inputs of ``build_hierarchy``)."""
    a, b = int(kf.seg_first[s]) // 3, int(kf.seg_first[s] + kf.seg_count[s]) // 3
    idx = kf.indices[a:b].astype(np.int64)
    if idx.size == 0:
        z3 = np.zeros((0, 3), np.float32)
        return z3, z3, np.zeros((0, 3), np.int64), np.zeros((0, 4), np.float32), np.zeros((0, 4), np.float32), z3, z3
    lo, hi = int(idx.min()), int(idx.max()) + 1
    sl = slice(lo, hi)
    return (kf.positions0[sl], kf.positions1[sl], idx - lo, kf.colors0[sl], kf.colors1[sl], kf.normals0[sl],
            kf.normals1[sl])


def triangle_hierarchy(p0, p1, indices) -> PointHierarchy:
    """A one-node hierarchy holding every triangle of a segment and no points
    (``build_hierarchy`` with a leaf as large as the segment): the traversal
    draws it as triangles at every distance, like mode "none". Stands in for
    the segments of clips a scene does not play (:func:`build_points_rep`).
    Not cached (no sampling: one node), so it is called through the module
    rather than as the cache's build entry point (``lod.points.rep.build_hierarchy``)."""
    from lod.points import octree as points_octree

    idx = np.asarray(indices).reshape(-1, 3)
    return points_octree.build_hierarchy(p0, p1, idx, leaf_triangles=max(1, idx.shape[0]), progress=False)


def played_segments(kf: KeyframedRep, clips) -> np.ndarray:
    """(n_parts,) bool, the segments of the clips in ``clips`` (None: all).

    clips : None or an iterable of clip indices (int) or names (str)
    Raises ValueError naming the clip for an unknown name or index.
    """
    if clips is None:
        return np.ones(kf.n_parts, bool)
    out = np.zeros(kf.n_parts, bool)
    for c in clips:
        if isinstance(c, str):
            if c not in kf.anim_names:
                raise ValueError(f"points mode: unknown clip {c!r}; accepted: {', '.join(map(repr, kf.anim_names))}")
            c = kf.anim_names.index(c)
        c = int(c)
        if not 0 <= c < kf.n_clips:
            raise ValueError(f"points mode: clip index {c} out of range 0..{kf.n_clips - 1}")
        a0 = int(kf.anim_first_seg[c])
        out[a0:a0 + int(kf.anim_n_segs[c])] = True
    return out


def build_points_rep(character, name: str, params: dict, cache: HierarchyCache | None = None,
                     progress=None, clips=None) -> PointsRep:
    """Bake (if skinned), then build or load one hierarchy per segment.

    params : validated ``[lod]`` table (see :data:`PARAMS`); cache : default
    :class:`HierarchyCache` at :func:`cache_dir`; progress : None or
    ``progress(iterable, description)``.
    clips : None (every clip) or the clips (indices or names) the scene
        plays: only their segments get point hierarchies; the others get a
        :func:`triangle_hierarchy` (drawn as full-detail triangles if an agent
        switches to them after all), so the data structure holds what is used.
    """
    p = {k: v.default for k, v in PARAMS.items()} | dict(params)
    cache = cache if cache is not None else HierarchyCache()
    poses: dict = {}
    kfc = keyframed_character(character, int(p["keyframes"]), float(p["pose_error"]), int(p["max_keyframes"]),
                              poses=poses)
    kf = build_keyframed_rep(kfc, key=f"points:{name}")
    bp = dict(intervals=int(p["intervals"]), spacing_fraction=float(p["spacing_fraction"]))
    played = played_segments(kf, clips)
    segs = [s for s in range(kf.n_parts) if played[s]]
    if progress is not None:
        segs = progress(segs, f"point hierarchies {name}")
    built = {s: cache.get_or_build(segment_arrays(kf, s), bp) for s in segs}
    if bool(p.get("coarse", True)):
        for h in built.values():  # prefixes coarser than the root (lod.points.coarse); in memory, the cache as built
            add_coarse(h)
    hs = [built[s] if s in built else triangle_hierarchy(*segment_arrays(kf, s)[:3]) for s in range(kf.n_parts)]
    return PointsRep(f"points:{name}", kf, hs, int(p["splat_size"]), str(p["renderer"]), poses=poses)


#: longest clip an instancing group's super-hierarchies bake when the character's samples follow the animation
SUPER_CLIP_SECONDS = 10.0


def group_keyframes(rep, clip: int, params: dict) -> tuple:
    """(KeyframedRep, clip index in it) of a character's clip for the super-hierarchies of §3.6 (a keyframe
    animation of the whole group, as the paper has it): a baked rep's own; for a rep that follows the
    animation, the keyframed rep itself (keyframed) or the one clip baked to poses (``lod.points.poses``;
    (None, -1) when it is longer than :data:`SUPER_CLIP_SECONDS`)."""
    if not getattr(rep, "follow", False):
        return rep.keyframed, int(clip)
    if not rep.skinned:
        return rep.base, int(clip)
    ch = rep.character
    names = list(ch.clips)
    short = [n for n in names if float(ch.clip(n).duration) <= SUPER_CLIP_SECONDS]
    if names[int(clip)] not in short:
        return None, -1
    kf = rep.__dict__.get("_super_keyframes")
    if kf is None:  # the short clips baked as the baked path bakes them (same arrays: its cached super-hierarchies)
        import dataclasses

        some = dataclasses.replace(ch, clips={n: ch.clip(n) for n in short})
        kfc = keyframed_character(some, int(params["keyframes"]), float(params["pose_error"]),
                                  int(params["max_keyframes"]))
        kf = rep.__dict__["_super_keyframes"] = build_keyframed_rep(kfc, key=rep.key)
    return kf, short.index(names[int(clip)])


def _node_words(variation, first: int, m: int):
    """(m,) uint32 variation words of agents ``first .. first + m - 1``, or None (no table, or none varies)."""
    if variation is None:
        return None
    w = np.asarray(variation, np.uint32).reshape(-1)[int(first):int(first) + int(m)]
    return np.ascontiguousarray(w) if w.shape[0] == int(m) and w.any() else None


def build_instancing(instancing, reps, names, params: dict, cache: HierarchyCache | None = None, progress=None,
                     variation=None):
    """Super-hierarchies (§3.6) of every instancing group, as an
    :class:`lod.points.instancing.InstancingPlan`, or None without groups.

    instancing : sim.instancing.Instancing or None; reps : the characters'
    PointsReps (index = CrowdState.character); names : their names.
    variation : None or (n agents,) uint32 colour-variation words (``lod.variation``): a super-hierarchy
    of depth d takes the words of the group's first node (agents ``first .. first + m_d - 1``), so every
    node shows that mix of colours.
    A group is left to the per-instance path (and named in the plan's
    ``skipped``) when its clip does not loop, changes triangles between
    segments, or its period is not a multiple of the clip's duration.
    Identical trees of the same character share one super-hierarchy.
    """
    from lod.points import instancing as pi

    if instancing is None or not getattr(instancing, "groups", None):
        return None
    p = {k: v.default for k, v in PARAMS.items()} | dict(params)
    groups, skipped, memo = [], [], {}
    items = list(enumerate(instancing.groups))
    if progress is not None:
        items = progress(items, "super-hierarchies")
    for gi, (first, h) in items:
        if not 0 <= h.character < len(reps):
            skipped.append((gi, "character index out of range"))
            continue
        rep = reps[h.character]
        kf, ci = group_keyframes(rep, h.clip, p)
        if kf is None:
            skipped.append((gi, f"its clip is longer than {SUPER_CLIP_SECONDS:g} s: baking it for a super-hierarchy "
                                "would grow with the clip"))
            continue
        surf = pi.clip_surface(kf, ci)
        dur = float(kf.anim_duration[ci]) if surf is not None else 0.0
        ratio = h.period / dur if dur > 0 else 0.0
        if surf is None or not bool(kf.anim_loop[ci]) or ratio < 0.5 or abs(ratio - round(ratio)) > 1e-6:
            skipped.append((gi, "clip is not a looping one-topology animation with the tree's period"))
            continue
        a0, ns = int(kf.anim_first_seg[ci]), int(kf.anim_n_segs[ci])
        if getattr(rep, "follow", False):
            r_root = float(rep.view(int(h.clip) if rep.skinned else a0).spacing[0])
        else:
            r_root = max(float(rep.hierarchies[s].spacing[0]) for s in range(a0, a0 + ns))
        if r_root <= 0.0:  # a character small enough to be one leaf: its own box sets the scale
            box = kf.seg_aabb[a0:a0 + ns]
            r_root = float(C.POINTS_SPACING_FRACTION * (box[:, 1] - box[:, 0]).max())
        supers = []
        r_stop = r_root * float(np.abs(h.levels[0].scale).max())
        for d in range(1, h.depth + 1):
            words = _node_words(variation, first, h.instances_per_node(d))
            key = (h.character, h.clip, d,
                   tuple((lv.translation.tobytes(), lv.yaw.tobytes(), lv.scale.tobytes(), lv.time_offset.tobytes())
                         for lv in h.levels[:d]), h.period, r_stop, None if words is None else words.tobytes())
            sup = memo.get(key)
            if sup is None:
                sup = pi.build_super(surf, h.levels, d, h.period, r_stop, group=gi, name=names[h.character],
                                     spacing_fraction=float(p["spacing_fraction"]),
                                     cache=cache, splat_size=int(p["splat_size"]), renderer=str(p["renderer"]),
                                     variation=words)
                memo[key] = sup
                if bool(p.get("coarse", True)):  # a far tree node coarser than its root too (lod.points.coarse)
                    for sh in sup.rep.hierarchies:
                        add_coarse(sh)
            supers.append(sup)
            if d < h.depth:  # (a root of a few coincident sources has spacing 0: keep the finer stop then)
                r_stop = max(sup.r_root, r_stop) * float(np.abs(h.levels[d].scale).max())
        groups.append((first, h, supers))
    plan = pi.InstancingPlan(groups)
    plan.skipped = skipped
    return plan


def build(characters, names, fps, params, static_reps=(), progress=None, cache: HierarchyCache | None = None,
          instancing=None, clips=None, variation=None):
    """Mode "points" for ``lod.modes``: a :class:`PointsRep` per character
    (then one per super-hierarchy, §3.6, when ``instancing`` holds groups)
    and a :class:`PointsSelector`.

    clips : None (every clip of every character gets point hierarchies) or a
        sequence aligned with ``characters``, each None (all clips) or the
        clip indices / names the scene can play (see :func:`build_points_rep`;
        the clips of ``instancing`` groups are always added).
    variation : None or the agents' colour-variation words (``lod.variation``), which the
        super-hierarchies carry (:func:`build_instancing`)
    """
    p = {k: v.default for k, v in PARAMS.items()} | dict(params)
    p.pop("mode", None)
    if progress is False:
        progress = None  # quiet: no progress output
    elif progress is None:
        from tqdm.auto import tqdm

        def progress(it, desc):
            return tqdm(it, desc=desc, leave=False, disable=None)
    cache = cache if cache is not None else HierarchyCache()
    if clips is None:
        clips = [None] * len(characters)
    clips = [None if c is None else list(c) for c in clips]
    if len(clips) != len(characters):
        raise ValueError(f"points mode: clips must list one entry per character ({len(characters)}), got {len(clips)}")
    for _, h in (getattr(instancing, "groups", None) or []):  # super-hierarchies sample the group's clip
        if 0 <= h.character < len(clips) and clips[h.character] is not None:
            clips[h.character].append(int(h.clip))
    fps = list(fps) if fps is not None else [30] * len(characters)
    reps = []
    for ch, n, c, f in zip(characters, names, clips, fps):
        path, _ = animation_path(ch, p)
        if path == "follow":
            r = build_follow_rep(ch, n, p, fps=float(f), cache=cache)
            r.character = ch
        else:
            r = build_points_rep(ch, n, p, cache, progress, clips=c)
        reps.append(r)
    plan = build_instancing(instancing, reps, list(names), p, cache, progress, variation=variation)
    # the far tier (lod.far): footprints measured on the full-detail reps; not beside instancing groups
    far = build_far_split(characters, names, fps, clips, float(p["far_pixels"])) if plan is None else None
    sel = PointsSelector(reps, static_reps=static_reps, splat_size=int(p["splat_size"]), instancing=plan,
                         splat_blend=float(p["splat_blend"]), far=far)
    return reps + (plan.reps if plan is not None else []) + (far.uploads if far is not None else []), sel



# ---------------------------------------------------------------------------- selector
def super_batches(draws, planes, vscale: float, splat: float) -> list:
    """PointsBatches of the super-hierarchy draws of ``InstancingPlan.select`` (§3.6): per drawn
    node, its super-hierarchy traversed at the node's super-segment; ``represented`` on each batch
    counts the instances its nodes stand for."""
    out = []
    for sup, seg, data, ids, m in draws:
        for s in np.unique(seg).tolist():
            sel = np.flatnonzero(seg == s)
            pj, tj = traverse_instances(sup.rep.hierarchies[s], data[sel], planes, vscale, splat)
            npts = int(pj[:, 2].sum()) if pj.size else 0
            b = PointsBatch(sup.rep.key, int(s), ids[sel], data[sel], triangles=0, points=npts, point_jobs=pj,
                            tri_jobs=tj)
            b.represented = int(m[sel].sum())
            out.append(b)
    return out


class PointsSelector:
    """Per frame: cull and locate instances (as ``NoLodSelector`` on the
    keyframed form), then traverse each instance's segment octree (§3.2).

    Parameters
    ----------
    reps : list of PointsRep aligned with ``CrowdState.character``
    static_reps : StaticRep scenery drawn through ``statics``
    splat_size : pixels (1..3)
    splat_blend : splat footprints the drawer blends within (``[lod] splat_blend``), or None
    """

    def __init__(self, reps, static_reps=(), splat_size: int = 2, instancing=None, pose_rate="key",
                 splat_blend: float | None = None, far=None):
        if not 1 <= int(splat_size) <= 3:
            raise ValueError(f"[lod] splat_size: expected 1, 2 or 3 pixels, got {splat_size}")
        self.reps = list(reps)
        self.splat_size = int(splat_size)
        #: the splat's blend tolerance the DrawList names (``[lod] splat_blend``; None: the drawer's own)
        self.splat_blend = None if splat_blend is None else float(splat_blend)
        #: pose sharing of the representations that follow the animation (lod.points.follow_select)
        self.pose_rate = pose_rate
        self._base = NoLodSelector([r.base if getattr(r, "follow", False) else r.keyframed for r in self.reps],
                                   static_reps=static_reps)
        self._by_key = {r.key: r for r in self.reps}
        self.instancing = instancing
        if instancing is not None:
            for r in instancing.reps:
                self._by_key[r.key] = r
        #: the far tier's split (``lod.far.select.FarSplit``) or None
        self.far = far

    def select(self, state, camera, size, statics=()) -> DrawList:
        """DrawList of :class:`PointsBatch` (plus static batches); stats hold
        "points" and "triangles" actually submitted, "instances", "culled"."""
        w, h = int(size[0]), int(size[1])
        planes = camera.frustum_planes(w / max(1, h))
        vs = viewport_scale(h, camera.fov_y)
        supers, represented, far = [], 0, None
        if self.instancing is not None and state.n:
            origin = np.asarray(camera.position, np.float64)
            draws, flat = self.instancing.select(state, origin, planes, vs, self.splat_size)
            supers = super_batches(draws, planes, vs, self.splat_size)
            represented = sum(b.represented for b in supers)
            if not flat.all():
                dl = self._base.select(state, camera, size, statics, agents=np.flatnonzero(flat))
                dl.stats["instances"] += represented
                dl.stats["culled"] = int(state.n - dl.stats["instances"])
                dl.stats["super_nodes"] = int(sum(b.n_instances for b in supers))
            else:
                dl = self._base.select(state, camera, size, statics)
        elif self.far is not None and self.far.active:  # far agents first (lod.far), the rest as usual
            far = self.far.split(state, camera, size, vs, planes)  # (near agents, far batches, far culled)
            dl = self._base.select(state, camera, size, statics, agents=far[0])
        else:
            dl = self._base.select(state, camera, size, statics)
        out = []
        pts = tris = placed = poses = 0
        for b in dl.batches:
            rep = self._by_key.get(b.rep)
            if rep is None:
                out.append(b)
                continue
            if getattr(rep, "follow", False):  # samples placed with the animation (lod.points.follow_select)
                fb = follow_batch(rep, b, planes, vs, self.splat_size, self.pose_rate)
                pts += fb.points
                tris += fb.triangles
                placed += int(fb.pose_points.sum())
                poses += int(fb.pose.shape[0])
                out.append(fb)
                continue
            hier = rep.hierarchies[b.part]
            pj, tj = traverse_instances(hier, b.instance_data, planes, vs, self.splat_size)
            np_ = int(pj[:, 2].sum()) if pj.size else 0
            nt = int(tj[:, 2].sum()) if tj.size else 0
            pts += np_
            tris += nt
            out.append(PointsBatch(b.rep, b.part, b.instance_ids, b.instance_data, triangles=nt, points=np_,
                                   point_jobs=pj, tri_jobs=tj))
        for b in supers:
            pts += b.points
            out.append(b)
        dl.batches = out
        dl.stats["points"] = int(pts)
        if poses:  # the draw's placement work (render/points/follow.py): samples placed, one set per pose
            dl.stats["placed_points"] = int(placed)
            dl.stats["point_poses"] = int(poses)
        dl.options["splat_size"] = self.splat_size  # the drawer splats at the size the traversal assumed
        if self.splat_blend is not None:
            dl.options["splat_blend"] = self.splat_blend
        dl.stats["triangles"] = int(tris) + sum(b.triangles for b in out if not isinstance(b, PointsBatch))
        if far is not None:  # one splat per far agent (lod.far)
            merge(dl, state.n, far[0], far[1], remap=False)
        dl.stats["batches"] = len(dl.batches)
        return dl
