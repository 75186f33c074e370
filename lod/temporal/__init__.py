"""Smooth view-dependent rendering in animations (Friedrich, Polthier & Schmies).

Selection only every n-th frame (a keyframe), interpolation in between, so nothing pops. Modules in data-flow
order:

- ``lod.temporal.bisection``: Rivara/Bänsch bisection of conforming triangulations (Definition 1, Fig. 2).
- ``lod.temporal.interpolating``: interpolating hierarchies, keyframes blended on their union (Definition 2,
  Theorem 1, eq. (1)).
- ``lod.temporal.terrain``: the terrain's bisection hierarchy over the heightfield and its view-dependent
  section (§4).
- ``lod.temporal.terrain_keyframes``: terrain selection every n-th frame with the union hierarchy interpolated
  in between, camera extrapolation (§3, §5).
- ``lod.temporal.selection``: the same for the crowd: any mode's selector run at keyframes, fades and
  geomorphs between (``[lod] keyframe_every``; chain levels and cluster cuts geomorph, §3).
"""
