"""Effect ``routing``: its scene keys, the walls it adds, and its install.

Install order: ``obstacles`` (holding the walkable area's walls, :func:`with_walls`), then ``routing``, then the
movers (``goals``, ``journeys``): the scene loader (``crowd.scene_routing``) orders a scene's effects so, and
resolves ``clearance = 0`` to the largest body radius the scene states. Worlds built by hand install in that order.

``install`` builds the :class:`sim.routing.Router` (``world.resources["routing"]``), checks that every agent
stands in the walkable area (a :class:`sim.params.ParamError` naming the placement group and the agent
otherwise), and binds the movers already installed (``world.resources["routing.clients"]``: callables taking the
router, queued by movers installed before it; none are in scenes, whose loader installs routing first).
"""
from __future__ import annotations

from sim.params import Param, ParamError, validate

STEERING = ("corners", "gradient")


class _Walkable(Param):
    """``[{points = [[x, z], ...], holes = [[[x, z], ...], ...]}, ...]``: polygons with holes."""

    def check(self, key, value):
        from sim.routing.geometry import polygon_problem

        if not isinstance(value, list) or not value:
            raise ParamError(key, f"expected a non-empty list of tables {{points = [[x, z], ...], holes = [...]}}, "
                                  f"got {value!r}")
        out = []
        for i, t in enumerate(value):
            w = f"{key}[{i}]"
            if not isinstance(t, dict) or "points" not in t or not set(t) <= {"points", "holes"}:
                raise ParamError(w, f"expected a table {{points = [[x, z], ...]}} (optional holes = [[[x, z], ...], "
                                    f"...]), got {t!r}")
            pts = _ring(f"{w}.points", t["points"])
            holes_raw = t.get("holes", [])
            if not isinstance(holes_raw, list):
                raise ParamError(f"{w}.holes", f"expected a list of rings [[[x, z], ...], ...], got {holes_raw!r}")
            holes = [_ring(f"{w}.holes[{k}]", h) for k, h in enumerate(holes_raw)]
            for k, h in enumerate(holes):
                why = polygon_problem(h)
                if why:
                    raise ParamError(f"{w}.holes[{k}]", f"the hole {why}")
            why = polygon_problem(pts, holes)
            if why:
                raise ParamError(w if holes else f"{w}.points", f"the walkable polygon {why}")
            out.append({"points": pts, "holes": holes})
        return out


def _ring(key, value) -> list:
    if not isinstance(value, list) or len(value) < 3:
        raise ParamError(key, f"expected at least 3 points [x, z], got {value!r}")
    return [Param("vec2").check(f"{key}[{j}]", p) for j, p in enumerate(value)]


class _Bounds(Param):
    def check(self, key, value):
        if (not isinstance(value, list) or len(value) != 4
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
            raise ParamError(key, f"expected [x0, z0, x1, z1] (metres), got {value!r}")
        x0, z0, x1, z1 = (float(v) for v in value)
        import math

        if not all(math.isfinite(v) for v in (x0, z0, x1, z1)) or not (x0 < x1 and z0 < z1):
            raise ParamError(key, f"expected finite x0 < x1 and z0 < z1, got {value!r}")
        return [x0, z0, x1, z1]


PARAMS: dict[str, Param] = {
    "walkable": _Walkable("list", None, doc="the walkable area: polygons with holes, "
                                            "[{points = [[x, z], ...], holes = [[[x, z], ...], ...]}, ...], metres; "
                                            "exactly one of walkable / bounds / walkable_file"),
    "bounds": _Bounds("list", None, doc="the walkable area as the rectangle [x0, z0, x1, z1], metres"),
    "walkable_file": Param("str", None, doc="the walkable area from a floor-plan file, relative to the scene file: "
                                            "WKT (.wkt), GeoJSON (.geojson, .json), DXF (.dxf), or the geometry "
                                            "of a recording (JuPedSim .sqlite, Vadere .scenario), its (x, y) the "
                                            "floor's (x, z) (sim.routing.floor_plan); in place of walkable / bounds"),
    "walkable_layer": Param("str", None, doc="walkable_file a DXF: read the entities of this layer only; default "
                                             "every layer"),
    "clearance": Param("float", 0.0, min=0.0, max=100.0,
                       doc="distance routes keep from walls, metres; 0 = the largest body radius of the scene "
                           "(at least the obstacles' agent_radius)"),
    "cell": Param("float", 0.0, min=0.0, max=100.0,
                  doc="grid spacing of the distance fields, metres; 0 = half the clearance (coarser when a field "
                      "would exceed 4 M nodes)"),
    "steering": Param("str", "corners", choices=STEERING,
                      doc="corners: straight at the next corner of the shortest path (exact routes); gradient: "
                          "down the distance field only (rounder, 2-6 % longer around walls)"),
    "wall_thickness": Param("float", 0.5, min=0.01, max=100.0,
                            doc="thickness of the walls around the walkable polygons (obstacles), metres"),
    "wall_height": Param("float", 1.0, min=0.0, max=1e4, doc="drawn height of those walls, metres; 0 = not drawn"),
}


def walkable_of(cfg: dict, obstacles: dict | None):
    """The :class:`sim.routing.geometry.Walkable` of a validated routing table and obstacles table."""
    from sim.routing.geometry import Walkable

    return Walkable.from_config(cfg, obstacles)


def with_walls(cfg: dict, obstacles: dict | None) -> dict:
    """The ``obstacles`` table (validated, or None) with the walls of the routing table ``cfg``'s walkable area
    added as polygons (``sim.routing.geometry.wall_polygons``), drawn ``wall_height`` tall."""
    from sim.obstacles import PARAMS as OBSTACLE_PARAMS
    from sim.routing.geometry import Walkable, wall_polygons

    obs = dict(obstacles) if obstacles is not None else validate(OBSTACLE_PARAMS, {}, "obstacles")
    outline = Walkable.from_config(cfg, None)
    h = float(cfg.get("wall_height", 1.0))
    walls = [{"points": p, "height": h if h > 0 else 1.0, "visible": h > 0}
             for p in wall_polygons(outline, float(cfg.get("wall_thickness", 0.5)))]
    obs["polygons"] = list(obs.get("polygons", [])) + walls
    return obs


def obstacles_table(world) -> dict | None:
    """The installed ``obstacles`` effect's shapes as a table (``sim.obstacles.ObstacleSet`` arrays)."""
    obs = world.resources.get("obstacles")
    if obs is None or obs.count == 0:
        return None
    polys = [{"points": obs.verts[obs.pstart[k]:obs.pstart[k + 1]].tolist()} for k in range(obs.pstart.shape[0] - 1)]
    return {"circles": [{"center": [x, z], "radius": r} for x, z, r in obs.circles], "polygons": polys}


def check_agents(walkable, state) -> None:
    """ParamError naming the placement group and the first agent standing outside the walkable area. Recorded
    people (a trajectories placement, ``sim.replay``) are replayed where they were recorded: not checked here
    (``crowd.start_check`` reports a recording that leaves the area)."""
    import numpy as np

    from sim.routing.geometry import describe_where

    if state.n == 0:
        return
    code = walkable.where(state.position[:, [0, 2]])
    for first, count, *_ in getattr(state, "tracks", None) or []:
        code[first:first + count] = 0
    bad = np.nonzero(code)[0]
    if bad.size == 0:
        return
    i = int(bad[0])
    group = 0
    for g, (first, count) in enumerate(getattr(state, "groups", None) or []):
        if first <= i < first + count:
            group = g
    x, z = state.position[i, 0], state.position[i, 2]
    more = f" (and {bad.size - 1} more)" if bad.size > 1 else ""
    raise ParamError(f"placement[{group}]", f"agent {i} at ({x:.6g}, {z:.6g}) {describe_where(code[i])}{more}")


def install(world, cfg: dict) -> None:
    """Effect ``routing`` (module docstring)."""
    from sim.config import AVOIDANCE_DEFAULT_RADIUS
    from sim.routing.router import Router, RoutingError

    c = {k: p.default for k, p in PARAMS.items()}
    c.update(cfg)
    if (c["walkable"] is None) == (c["bounds"] is None):
        raise ParamError("effects", "routing: expected exactly one of `walkable` (polygons with holes) or `bounds`")
    clearance = c["clearance"] or float(world.resources.get("obstacles.agent_radius", AVOIDANCE_DEFAULT_RADIUS))
    walkable = walkable_of(c, obstacles_table(world))
    if walkable.area.is_empty:
        raise ParamError("effects", "routing: the walkable area is empty (the obstacles cover it)")
    check_agents(walkable, world.state)
    try:
        router = Router(walkable, clearance, c["cell"], steering=c["steering"])
    except RoutingError as e:
        raise ParamError(e.key or "effects", e.message) from None
    world.resources["routing"] = router
    for bind in world.resources.pop("routing.clients", []):
        bind(router)
