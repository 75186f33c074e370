"""Triangle LOD chains (LOD mode ``"triangles"``): a discrete chain of simplified meshes per skinned character.

Modules in data-flow order:

- ``lod.chains.chain``: ``build_chain`` (multi-pose QEM, ``lod.simplify``, on VDR-AM's representative poses,
  ``lod.clusters.poses``), every vertex's collapse kept as geomorph target (Friedrich, Polthier & Schmies §3),
  ``TrianglesRep`` and the content-addressed cache.
- ``lod.chains.mode``: per instance the coarsest level whose projected error stays under ``poe`` pixels
  (``TrianglesSelector``) and the mode protocol.
"""
