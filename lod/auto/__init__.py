"""LOD mode ``"auto"``: per instance the cheapest representation whose projected error stays within a bound.

Modules in data-flow order:

- ``lod.auto.cost_model``: a linear model of a frame's rendering cost fitted to measured frames (after
  Funkhouser & Séquin 1993, §4.1), calibrated per machine by ``crowd calibrate``.
- ``lod.auto.candidates``: one plug-in per representation family (chains, clusters, points): options, their
  projected errors and costs.
- ``lod.auto.plans``: per instance group the cheapest option under the bound, reduced in blocks (numba).
- ``lod.auto.flat``, ``lod.auto.flat_points``: the candidates' options and the frame plans over flat arrays of
  all instances in a few parallel numba passes (a million agents); the per-group path of ``lod.auto.mode`` is the
  reference they are tested equal to.
- ``lod.auto.budget``: the per-instance choice at a bound and the controller that moves the bound towards a
  frame-time budget.
- ``lod.auto.mode``: ``AutoSelector`` and the mode protocol; ``lod.auto.build``: the mode's build and memory estimate.
"""
