"""Rendering layer: GL context, GPU resources, shaders, draws, timing, images. Imports ``lod`` types only.

Modules in data-flow order (representations and DrawList in, pixels and timings out):

- ``render.context``: the OpenGL context (headless EGL by default).
- ``render.shaders``: GLSL sources under ``render/shaders/`` by name.
- ``render.renderer``: uploads representations, draws a DrawList's triangle batches (GPU skinning, the
  full-detail and chain levels of ``lod.full`` and ``lod.chains``), hands the other kinds to their drawers.
- ``render.pose_cache``: ``Renderer.poses``: per frame the joint palette of each distinct pose (``lod.poses``)
  and, on request, each distinct pose's posed vertices (compute pass ``shaders/pose_skin.comp`` or numba,
  ``render.pose_skin``), in windowed ``[slot][vertex]`` textures; ``render.posed_draw`` draws copies from them.
- ``render.tint``: per-instance colour words (an agent's colour variation, the debug colour of its batch) that
  every draw path applies through ``shaders/tint.glsl``, so LOD modes agree on colours.
- ``render.capture``: transform-feedback capture of a representation's skinned vertices (tests).
- ``render.light``: the scene's directional light (``u_light_dir``, ``u_light_color``, ``u_ambient``).
- ``render.shadows``: ``Renderer.lighting``: the light's uniforms, blob-shadow decals and the shadow map;
  ``render.blobs`` the blobs' rows in numba and the test that drops quads covering no pixel centre.
- ``render.targets``: the morph-target tables (glTF §3.7.2.2) the ``MORPH_TARGETS`` variants of the skinned
  shaders blend before skinning (``lod.full.targets``); not the geomorphs below.
- ``render.morph``: the geomorph tables the morph shaders follow (``lod.chains``, ``lod.clusters``).
- ``render.clusters``: the drawer of ``lod.clusters`` cuts (VDR-AM; occlusion culling §5.2).
- ``render.points``: the drawer of ``lod.points`` hierarchies (compute-shader splats and GL_POINTS);
  ``render.points_jobs`` its CPU job helpers, ``render.points_pack`` its per-frame packing in numba (folded
  instance rows, colour words, job tables); ``render.occlusion`` its occlusion culling of hierarchy nodes
  (max-depth pyramid of the likely occluders; Wand & Straßer have none).
- ``render.timing``: which GPU timer-query readings to believe (llvmpipe).
- ``render.image``: PNG output written atomically.
- ``render.window``: the glfw window of the fly-through.
"""
