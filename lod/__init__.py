"""Level-of-detail layer: representations of characters and per-frame selection.

Imports ``sim`` types only; produces DrawLists (plain arrays) for ``render``. One package per representation
family around a small shared core. Import the concrete modules (``from lod.points.mode import ...``); the package
``__init__`` files hold only these maps.

Shared core, in data-flow order (scene ``[lod]`` -> mode -> selection -> DrawList):

- ``lod.modes``: the registry of LOD modes (``[lod] mode`` -> the family's ``mode`` module, imported on demand).
- ``lod.view``: the camera, projection, frustum planes and projected pixel sizes.
- ``lod.camera_path``: keyed camera paths (non-uniform Catmull-Rom in time, Barry & Goldman).
- ``lod.cull``: sphere-against-frustum culling of camera-relative instances.
- ``lod.drawlist``: ``DrawList`` and ``DrawBatch``, the plain-array contract with ``render``.
- ``lod.poses``: pose sharing: each frame's distinct poses per skinned character and every drawn copy's pose
  slot (``[lod] pose_rate``; ``DrawList.poses``), which the renderer's pose cache animates once per pose.
- ``lod.debug_colors``: tints of a DrawList by representation or level (VDR-AM Fig. 11).
- ``lod.variation``: the agents' colour-variation words and their arithmetic (the renderer applies them per
  instance; representations that stand for many agents bake them in).

Representation families (each package's docstring lists its modules):

- ``lod.full``: full detail, mode ``none`` (the baseline every LOD mode is measured against).
- ``lod.simplify``: multi-pose quadric simplification (VDR-AM §4.3 after DeCoro & Rusinkiewicz), used by
  ``chains`` and ``clusters``.
- ``lod.chains``: discrete triangle LOD chains, mode ``triangles``.
- ``lod.clusters``: VDR-AM cluster hierarchies and cuts, mode ``clusters``.
- ``lod.points``: Wand & Straßer point-sample hierarchies and hierarchical instantiation, mode ``points``.
- ``lod.temporal``: Friedrich, Polthier & Schmies: keyframed view-dependent selection, bisection hierarchies,
  terrain LOD.
- ``lod.far``: the far tier (``[lod] far_pixels`` of modes points and auto): an agent within a pixel or two is one
  pre-filtered splat of its measured footprint, taken before the mode's own selection.
- ``lod.auto``: mode ``auto``, the cheapest representation per instance under an error bound or a frame budget.

Dependencies run one way: ``full`` and ``simplify`` use the core only; ``clusters`` uses them; ``chains`` uses
``clusters`` (poses, cache key, geomorph tables); ``points`` uses ``full`` and ``far``; ``far`` uses ``full``;
``temporal`` uses ``full`` and ``clusters``; ``auto`` uses every family. No two modules import each other.
"""
