"""The crowd application: scene schema, engine loop, CLI, telemetry, reports.

The only package that imports sim, lod and render; nothing imports it. Modules in data-flow order:

- ``crowd.cli`` (and ``__main__``): the ``crowd`` command line; ``crowd.errors``: one-sentence user errors.
- ``crowd.scene``: scene files loaded and validated in full; ``crowd.characters``: the characters they name.
- ``crowd.memory``: the memory estimate and guard.
- ``crowd.plan``: a scene's characters built and agents placed (no GL); ``crowd.start_check``: where they start.
- ``crowd.engine``: builds the world, the LOD mode and the renderer, runs the frame loop.
- ``crowd.telemetry``, ``crowd.output``: per-frame timings and counts, written atomically; ``crowd.video``: the
  run as an H.264 MP4 (imageio-ffmpeg).
- ``crowd.fly``: the interactive fly-through; ``crowd.inspect``: a character's cluster hierarchy (pyvista).
- ``crowd.build``: LOD hierarchies built ahead of time on dask; ``crowd.calibrate``: the cost model's machine
  coefficients.
- ``crowd.reference``: the true reference, full detail with K x K samples per pixel, box-filtered (tiled where the
  GL limits ask); ``crowd.reference_cache``: its frames cached by content.
- ``crowd.image_metrics``: image error against the reference; ``crowd.report``: reports over scenes and swept
  settings (a package).
"""
import os as _os

# numba's parallel kernels run on an OpenMP pool whose threads, by default, spin for milliseconds after every
# parallel region; on a 2-core machine they take the cores llvmpipe's rasteriser threads and the main thread
# need next (a frame runs dozens of regions). Passive waiting: 25-40 % less CPU per frame at a million agents,
# measured (scripts/bench_million.md, notes). A value the user set is kept.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
