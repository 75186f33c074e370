"""A compute rasteriser for small triangles (issue 29; the split Nanite makes between hardware and software
rasterisation, Karis, *Nanite*, SIGGRAPH 2021 course).

Modules, in data-flow order: ``route`` (which instances the compute path takes), ``tables`` (the CPU side of
its textures), ``poses`` (posed vertices of skinned instances: the adapter standing for the pose cache),
``frame`` (the ``Raster``: uploaded meshes, the per-frame passes, windows), ``hook`` (the renderer's side:
splitting built-in batches between the paths).
"""
