"""Multi-pose quadric error simplification (VDR-AM §4.3 after DeCoro & Rusinkiewicz 2005; Garland & Heckbert 1997).

Shared by the triangle chains (``lod.chains``) and the cluster hierarchies (``lod.clusters``); imports neither.
Modules in data-flow order:

- ``lod.simplify.quadrics``: per-pose plane quadrics of every vertex.
- ``lod.simplify.kernels``: the compiled greedy collapse loop (edge heap, link and normal-flip tests).
- ``lod.simplify.collapse``: ``simplify`` (subset placement, locked vertices: open and non-manifold edges are
  locked automatically, ``open_edge_vertices``; triangles with a repeated index dropped, ``drawable_triangles``)
  and its plain-Python reference; ``FLIP_DOT``.
- ``lod.simplify.distance``: the error of the result in every pose: vertex-to-surface and collapse distances,
  the normal-compatible cluster Hausdorff distance (VDR-AM §5.1).
"""
