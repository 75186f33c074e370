"""Animation evaluated once per frame: the pose cache and what reads it (issue 29; the LOD side is ``lod.poses``).

Every draw path of a frame (full detail, the compute rasteriser, follow points) takes its poses from here: per
character the joint palette of each distinct pose and, where a path asks, each distinct pose's posed vertices;
the frame's pose passes are counted (``frames.csv`` column ``pose_passes``).

Modules in data-flow order:

- ``render.poses.targets``: GPU tables of skinned characters' morph targets (glTF 2.0 §3.7.2.2) the skinning
  blends before the joints.
- ``render.poses.palette``: the per-frame palette pre-pass of copies that do not share poses (transform feedback,
  in chunks that fit a texture).
- ``render.poses.skin``: the CPU side of the pose cache: numba kernels beside numpy references.
- ``render.poses.cache``: ``Renderer.poses``, the pose cache: palettes and posed vertices per distinct pose in
  windowed ``[slot][vertex]`` textures (compute pass ``shaders/poses/pose_skin.comp`` or numba).
- ``render.poses.draw``: the renderer's draws of skinned batches from the pose cache.
- ``render.poses.capture``: transform-feedback capture of a representation's skinned vertices (tests).
"""
