"""The world a crowd stands in: light, shadows, the ground, obstacle solids and props.

Modules in data-flow order:

- ``render.world.light``: the scene's directional light, one for every shader.
- ``render.world.blobs``: the blob shadows' instance rows in numba, only those that can cover a pixel.
- ``render.world.shadows``: ``Renderer.lighting``: the light's uniforms, blob-shadow decals and the shadow map.
- ``render.world.draw``: the ``Drawer`` of kind ``"world"``: ground with its grid, obstacle solids, props.
"""
