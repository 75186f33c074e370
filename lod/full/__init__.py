"""Full detail (LOD mode ``"none"``): every visible instance drawn with its complete mesh.

The fair baseline every LOD speed-up is measured against. Modules in data-flow order:

- ``lod.full.targets``: a skinned mesh's animated morph targets (glTF 2.0 §3.7.2.2) as sparse deltas and weights
  baked at the joint table's frames (``TargetTable``), blended before skinning; bounds of the morphed mesh.
- ``lod.full.reps``: ``SkinnedRep`` (mesh + skin + every clip's joint matrices baked at a fixed rate, linear
  blend skinning, and its ``TargetTable``), ``KeyframedRep`` (keyframe segments, Wand & Straßer §3),
  ``StaticRep``; ``build_rep``.
- ``lod.full.bounds``: per-frame skinned boxes and spheres that bound the whole animation (for culling).
- ``lod.full.frames``: a rep's frames (baked rows, keyframes) and its vertices posed at them (numba, numpy
  reference), for the measurements of ``lod.points.deform`` and ``lod.far``.
- ``lod.full.pack``: per-frame culling and packing of instances into instanced batches (numba, numpy reference).
- ``lod.full.mode``: ``NoLodSelector`` and the mode protocol (``PARAMS``, ``build``); every other mode's
  selector reuses its cull-and-pack pass.
"""
