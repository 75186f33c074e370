"""Rendering layer: GL context, GPU resources, shaders, draws, timing, pixels read back. Imports ``lod`` types only.

The core modules at the top, in data-flow order (representations and DrawList in, pixels and timings out):

- ``render.context``: the OpenGL context (headless EGL by default).
- ``render.shaders``: GLSL sources by name, in one folder per family under ``render/shaders/`` (``core``,
  ``poses``, ``points``, ``raster``, ``clusters``, ``world``, ``far``); ``prog_name``, the program of a representation kind.
- ``render.vertex_format``: the vertex attributes of the triangle representations, packed.
- ``render.tint``: per-instance colour words (an agent's colour variation, the debug colour of its batch) that
  every draw path applies through ``shaders/core/tint.glsl``, so LOD modes agree on colours.
- ``render.screen``: screen-space helpers of the compute passes (pixel rays, resolve rectangles).
- ``render.renderer``: uploads representations, draws a DrawList's triangle batches (full detail and the chain
  levels of ``lod.full`` and ``lod.chains``), hands the other kinds to their families' drawers.
- ``render.timing``: which GPU timer-query readings to believe (llvmpipe).
- ``render.window``: the glfw window of the fly-through.

The families, each a package whose ``__init__`` lists its modules in data-flow order:

- ``render.poses``: the one place animation is evaluated per frame: the pose cache (per distinct pose its joint
  palette and, on request, its posed vertices), its skinning pass, the morph-target tables, the per-frame palette
  pre-pass, the posed draws, and the transform-feedback capture of tests.
- ``render.points``: the drawer of ``lod.points`` hierarchies (compute-shader splats and GL_POINTS) with its
  samples, occlusion culling, jobs, packing and the placement of samples that follow the animation.
- ``render.raster``: the compute rasteriser of small triangles and the split of instances between it and the
  hardware path.
- ``render.clusters``: the drawer of ``lod.clusters`` cuts (VDR-AM) and the geomorph tables.
- ``render.world``: the ground, obstacle solids and props; the light, blob shadows and the shadow map.
- ``render.far``: the drawer of the far tier (``lod.far``): one pre-filtered splat per far agent.
"""
