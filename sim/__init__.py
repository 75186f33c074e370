"""Simulation layer: characters, crowd state, systems (effects). Knows nothing of LOD or rendering.

Modules in data-flow order (asset -> character -> world -> systems stepping the state):

- Characters: ``sim.mesh`` (triangle meshes, skin attributes, morph targets), ``sim.skeleton`` (joint
  hierarchies, forward kinematics), ``sim.clip`` (skeletal clips, morph weights), ``sim.skin_weights``
  (weights checked and repaired), ``sim.keyframes`` (keyframe animations of meshes, Wand & Straßer §3),
  ``sim.character`` (skinned or keyframed), ``sim.procedural`` (generated humanoids and quadrupeds),
  ``sim.gltf`` (glTF 2.0 import and export, a package), ``sim.skinning`` (CPU linear-blend skinning and
  skin ∘ morph, the GPU path's reference), ``sim.describe`` (``crowd info``).
- World: ``sim.state`` (``CrowdState``, structure of arrays), ``sim.placement`` (``[[placement]]`` groups),
  ``sim.terrain`` (heightfields), ``sim.world``, ``sim.math3d``, ``sim.grid`` (neighbour grid).
- Systems (effects, each imported only when a scene lists it): ``sim.systems`` (registry and fixed-step
  schedule), ``sim.params`` (their parameter schemas), ``sim.animation``, ``sim.boids``, ``sim.goals``,
  ``sim.obstacles``, ``sim.terrain_follow``, ``sim.instancing`` (hierarchical instantiation, Wand & Straßer
  §3.6), ``sim.replay`` (recorded crowds: a recording read through PedPy, the people of a trajectories
  placement as agents, the step that moves them; installed by a trajectories placement, a package).
- ``sim.config`` (tunable constants), ``sim.errors``, ``sim.atomic_io`` (atomic file writes: every cache and
  output of the sandbox, from ``sim``'s own to ``crowd``'s, is written through it).
"""
