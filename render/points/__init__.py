"""The drawer of ``lod.points`` hierarchies (Wand & Straßer 2002 §3.2 rendering; compute splatting after Schütz,
Kerbl and Wimmer 2021), kind ``"points"``.

Modules in data-flow order:

- ``render.points.samples``: the sample words (positions in a box, RGBA8 colours, octahedral normals).
- ``render.points.occlusion``: occlusion culling of hierarchy nodes against a max-depth pyramid of the likely
  occluders (Wand & Straßer have none).
- ``render.points.jobs``: CPU job helpers (indexed triangle jobs, GL_POINTS expansion).
- ``render.points.pack``: the per-frame packing in numba (folded instance rows, colour words, job tables).
- ``render.points.frame``: the instance windows that keep every storage-buffer binding within the GL limit.
- ``render.points.follow``: the GPU side of samples that follow the animation (``lod.points.follow``): their
  placement per pose from the pose cache's palettes.
- ``render.points.blend``: the compute splat's colour rule (the points on the nearest surface blended, or the
  nearest alone) and its uniforms.
- ``render.points.draw``: the ``Drawer``: uploads, the splat passes (depth, colour, resolve), GL_POINTS.
"""
