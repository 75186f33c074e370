"""Point-sample hierarchies of keyframe animations (Wand & Straßer 2002), LOD mode ``"points"``.

Modules in data-flow order:

- ``lod.points.config``: the tunable constants, each naming its section.
- ``lod.points.params``: the ``[lod]`` keys of mode points (``PARAMS``) and the values they accept.
- ``lod.points.poses``: the skinned poses each clip is baked to, the fewest within a pose-error bound (§3
  keyframe animations from skinned clips).
- ``lod.points.sampling``: candidate samples of moving triangles, area-weighted over a keyframe interval (§3.4.1).
- ``lod.points.stratify``: stratification of the moving candidates per octree level (§3.4.2).
- ``lod.points.filter``: prefiltered attributes of the representative samples (§3.5).
- ``lod.points.octree``: the octree of samples and triangles of one keyframe pair, saved and loaded (§3.1, §3.3).
- ``lod.points.coarse``: representations coarser than a hierarchy's root (farthest-point prefixes of its points).
- ``lod.points.traverse``: the per-instance traversal: points where they are small enough, triangles where not
  (§3.2, §3.3).
- ``lod.points.jobs``: the one job writer: many instances traversed at once into ``(row, start, count)`` jobs
  (one numba kernel; each root decided in line as an option; a forest of hierarchies with bins for mode
  auto's flat pass), and its per-instance reference.
- ``lod.points.rep``: ``PointsRep`` (a hierarchy per segment), ``PointsBatch`` and the hierarchy cache.
- ``lod.points.instancing``: hierarchical instantiation, super-hierarchies of instance groups (§3.6).
- ``lod.points.deform``: how a character's surface moves over its clips' frames: posing, largest areas, the
  stratification poses, the covering radius at every frame, node boxes in joint frames (issue 27).
- ``lod.points.follow``: one hierarchy of rest-pose samples per character that follows the animation
  (``FollowHierarchy``, ``FollowRep``, build and cache; memory independent of the clips' length).
- ``lod.points.follow_select``: per frame, the copies' shared poses, the traversal at them (the job writer, roots
  decided in line) and each pose's prefixes.
- ``lod.points.sizes``: the bytes of each representation of a character before it is built.
- ``lod.points.paths``: which path a character takes ([lod] animation: follow or baked) and why.
- ``lod.points.memory``: the memory guard's hooks (the estimate per character, the causes of a refusal).
- ``lod.points.mode``: the builder and ``PointsSelector``; the mode protocol.

Morph targets of skinned characters (glTF 2.0 §3.7.2.2) are baked into the keyframes (``skin ∘ morph`` at every
key time, ``lod.points.mode.keyframed_character``) on the baked path, and blended before skinning in the pose pass
on the follow path (``render/points/follow.py``).
"""
