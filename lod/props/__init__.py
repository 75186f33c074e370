"""World geometry around the crowd: props (static meshes with triangle LOD chains),
the solids of the ``obstacles`` effect and the ground, as representations of kind
``"world"`` that ``render.world.draw`` draws.

- :mod:`lod.props.chain`: a prop's triangle chain (fast-simplification levels with
  a sampled Hausdorff error each) and its content-addressed cache.
- :mod:`lod.props.solids`: prisms of the obstacle shapes; the ground representation.
- :mod:`lod.props.select`: per frame, frustum culling and the pixels-of-error level
  choice of every prop instance; the world's DrawBatches.
"""
