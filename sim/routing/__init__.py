"""Routing through a walkable area (effect ``routing``; design and measurements: docs/routing.md).

Every goal (a point, a line or a polygon) gets, once, a distance field over a grid of the walkable area kept
``clearance`` from its walls (fast marching, Sethian 1996) and, per grid node, the first corner of its shortest
path (the visibility graph of the free space's corners): every agent heading to that goal reads four nodes and
steers straight at the best corner, the exact string-pulled route at a cost per agent and step that does not depend
on the geometry (Treuille, Cooper & Popović 2006 share one field per goal among its agents; the next corner is what
a navigation mesh's funnel would give).

Modules, in data-flow order:

- :mod:`sim.routing.geometry`: the walkable area (polygons with holes or bounds, minus obstacles), its walls, the
  checks of goal shapes and agents against it, its raster;
- :mod:`sim.routing.fmm`: fast marching on a grid (first and second order);
- :mod:`sim.routing.field`: a goal's distance field, its clearance band, and the per-agent steering kernel;
- :mod:`sim.routing.corners`: the free space's corners, their visibility graph and distances, the nodes' vias;
- :mod:`sim.routing.cache`: content-addressed disk cache of goal fields;
- :mod:`sim.routing.router`: :class:`Router`, what movers use (``goal``, ``directions``, ``distance``,
  ``reachable``);
- :mod:`sim.routing.follow`: the ``goals`` effect's routed step in one numba pass;
- :mod:`sim.routing.effect`: the effect's scene keys and install.
"""
from sim.routing.router import Router, RoutingError  # noqa: F401
