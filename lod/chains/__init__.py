"""Triangle LOD chains (LOD mode ``"triangles"``): a discrete chain of simplified meshes per skinned character.

Modules in data-flow order:

- ``lod.chains.chain``: ``build_chain`` (multi-pose QEM, ``lod.simplify``, on VDR-AM's representative poses,
  ``lod.clusters.poses``), every vertex's collapse kept as geomorph target (Friedrich, Polthier & Schmies §3),
  ``TrianglesRep`` and the content-addressed cache.
- ``lod.chains.mode``: per instance the coarsest level whose projected error stays under ``poe`` pixels
  (``TrianglesSelector``) and the mode protocol.

Morph targets (glTF 2.0 §3.7.2.2): a chain keeps the full-detail rep's ``TargetTable``; every level indexes the
original vertices, so each is drawn ``skin ∘ morph`` like level 0 (the simplification itself sees the skeletal
poses only).
"""
