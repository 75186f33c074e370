"""The drawer of ``lod.clusters`` cuts (Claudio, Kim, Kim, Yoon, *VDR-AM*, §3.1, §5.1), kind ``"clusters"``, and
the geomorph tables that it and the triangle chains (``lod.chains``) follow.

Modules in data-flow order:

- ``render.clusters.morph``: GPU tables of geomorphs, the collapse chains the morph shaders follow.
- ``render.clusters.cuts``: the CPU side: grouping of instance cuts, gathering of their triangles, multi-draw
  ranges, geomorph rows, palette-chunk pieces.
- ``render.clusters.draw``: the ``Drawer`` (occlusion culling §5.2).
"""
