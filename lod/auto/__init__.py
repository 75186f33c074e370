"""LOD mode ``"auto"``: per instance the cheapest representation whose projected error stays within a bound.

Modules in data-flow order:

- ``lod.auto.cost_model``: a linear model of a frame's rendering cost fitted to measured frames (after
  Funkhouser & Séquin 1993, §4.1), calibrated per machine by ``crowd calibrate``.
- ``lod.auto.online``: that model fitted online to the frames mode auto draws (recursive least squares).
- ``lod.auto.projected``: the projected error of each triangle chain level per instance (numba).
- ``lod.auto.candidates``: one plug-in per representation family (chains, clusters, points): options, their
  projected errors and costs.
- ``lod.auto.plans``: per instance group the cheapest option under the bound, reduced in blocks (numba).
- ``lod.auto.flat_points``: the point candidate over flat arrays of all instances: segments located, instances
  sorted by bin, one pass of the job writer (``lod.points.jobs``) over a forest of every segment's hierarchy.
- ``lod.auto.flat``: the candidates' options over flat arrays of all instances in a few parallel numba passes (a
  million agents); the per-group path of ``lod.auto.mode`` is the reference it is tested equal to.
- ``lod.auto.flat_plans``: the frame plans priced from those flat rows in one parallel pass.
- ``lod.auto.budget``: the per-instance choice at a bound and the controller that moves the bound towards a
  frame-time budget.
- ``lod.auto.control``: which frame plan is drawn (hysteresis, bounded exploration, faded switches).
- ``lod.auto.delegate``: held pure plans drawn by the single mode's own selector.
- ``lod.auto.params``: the mode's ``[lod]`` keys and candidates.
- ``lod.auto.mode``: ``AutoSelector``.
- ``lod.auto.build``: the mode as ``lod.modes`` names it: its build and memory estimate (imports the selector's
  module; nothing imports it back).
"""
