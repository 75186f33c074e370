"""``crowd report``: frame-time and accuracy reports over scenes and swept settings.

Modules, in data-flow order (scene + sweeps -> settings -> timed and reference runs -> image metrics -> plots ->
HTML/table):

- :mod:`crowd.report.settings`: ``--sweep`` arguments and the validated settings (sweep combinations) of a scene
- :mod:`crowd.report.runs`: one headless run (``run_task``), timed (aliased full detail among them); frames.csv, frame time
- :mod:`crowd.report.cluster`: ``ClusterPool``, where runs and image-error work execute (dask or this process)
- :mod:`crowd.report.metrics`: image error of the sampled frames against the reference, aggregates, Pareto front
- :mod:`crowd.report.compare`: ``--compare``, frame-time regressions against a baseline report
- :mod:`crowd.report.plots`: the matplotlib figures
- :mod:`crowd.report.pedestrian`: PedPy density, speed, flow and fundamental diagram of ``[[measurement]]`` areas
- :mod:`crowd.report.page`: the self-contained index.html (tables, plots, sample frames)
- :mod:`crowd.report.pipeline`: ``build_report``, all of the above; writes the report directory atomically
"""
