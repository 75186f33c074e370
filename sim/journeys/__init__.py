"""Journeys (effect ``journeys``): goals as stages, exits where agents leave, sources where they enter.

After JuPedSim's journeys and stages: every agent follows the journey of its placement group (or of the
source it entered from), a sequence of stages -- waypoints, waiting areas, queues, exits -- with weighted,
seeded choices between stages; an exit removes the agent from the simulation, a source adds agents at a
rate. The agent count changes through :mod:`sim.population` (compaction with stable ids), which every other
layer follows.

Modules in data-flow order: :mod:`sim.journeys.geometry` (floor shapes and their kernels),
:mod:`sim.journeys.stages` (the stage and journey tables, seeded choices and times),
:mod:`sim.journeys.sources` (arrival processes, placement with room), :mod:`sim.journeys.steer` (desired
velocity, kinematic move, the straight router standing in for routing), :mod:`sim.journeys.reach`
(which agents cannot reach their stages), :mod:`sim.journeys.effect` (``PARAMS``, ``install``, the steps).

A scene without the effect imports none of it and pays nothing.
"""
