"""Collision avoidance for pedestrians (effect ``avoidance``).

Two models turn the preferred velocity (what ``goals``, ``boids`` and the
attractors asked for in this step) into a collision-free one:

- ``cfsm`` (:mod:`sim.avoidance.cfsm`): the collision-free speed model of
  Tordeux, Chraibi & Seyfried, *Collision-free speed model for pedestrian
  dynamics* (2016), as JuPedSim's ``CollisionFreeSpeedModel`` implements it;
- ``orca`` (:mod:`sim.avoidance.orca`): optimal reciprocal collision avoidance
  of van den Berg, Guy, Lin & Manocha, *Reciprocal n-body collision avoidance*
  (2011), static obstacles as ORCA half-planes.

A hard no-overlap pass (:mod:`sim.avoidance.resolve`) runs after the
obstacles' projection. The schedule of one step (``sim.systems``):

1. ``obstacles.record``, ``avoidance.record``: positions (and velocities,
   headings) at the start of the step;
2. ``goals`` then ``obstacles.steer`` then ``boids``: the preferred motion
   (they move the agents as if alone);
3. ``avoidance``: preferred velocity = the move of step 2 / dt; the model
   computes the new velocity from the start-of-step snapshot and re-integrates
   ``position = start + v dt`` (heading turned by the same angle, animation
   rate scaled by the speed ratio);
4. ``obstacles.project``: obstacles stay hard (swept, then projected out);
5. ``avoidance.resolve``: no two bodies overlap (position projection,
   alternating with the obstacles' projection; as a last resort agents still
   overlapping return to their start-of-step position: a velocity clamp);
6. ``terrain_follow``, ``animation``.

:mod:`sim.avoidance.effect` holds the effect (``PARAMS``, ``install``),
:mod:`sim.avoidance.reference` the plain numpy references of every kernel.
"""
