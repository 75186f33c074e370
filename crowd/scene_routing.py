"""The ``routing`` effect's scene checks (``sim/routing``), run by :mod:`crowd.scene` once the effects and props
are parsed: everything is checked before anything is built, every problem one line naming the key.

With ``routing`` listed:

- exactly one of ``walkable`` (polygons with holes), ``bounds`` and ``walkable_file`` (a floor plan, WKT or
  GeoJSON, relative to the scene file: read by ``sim.routing.floor_plan`` into ``walkable`` and checked as typed
  polygons are); the area minus the obstacles (and the footprints of ``obstacle = true`` props, already added to
  ``obstacles``) must not be empty;
- ``clearance = 0`` becomes the largest body radius the scene states (the ``avoidance`` radius, else the largest
  ``[[characters]] radius`` times its scale, else 0.25 m, the generated humanoid's footprint), and at least the
  ``obstacles`` effect's ``agent_radius`` (its hard projection keeps agents that far from walls: a route through a
  gap it blocks would be no route); a ``clearance`` below ``agent_radius`` is an error;
- the walls of the walkable polygons (or bounds) join the ``obstacles`` effect (listed for them with
  ``agent_radius`` = the clearance when the scene has none), so they are drawn and hard for every model;
- every ``goals`` waypoint must lie in the walkable area (not outside it, not inside an obstacle);
- the effects are reordered: ``obstacles``, ``routing``, then the others in their listed order (the routing's
  movers find the router at their install). Agents are checked at install (their positions exist then).

:func:`walkable_of` gives other parsers (journeys' stages) the area to check their shapes against with
``sim.routing.geometry.shape_problem``.
"""
from __future__ import annotations

import dataclasses

from crowd.scene_types import EffectSpec
from sim.config import AVOIDANCE_DEFAULT_RADIUS


def _find(effects: list, name: str):
    return next((k for k, e in enumerate(effects) if e.name == name), None)


def body_radius(effects: list, characters: list) -> float:
    """The largest body radius the scene states (module docstring)."""
    av = _find(effects, "avoidance")
    if av is not None and effects[av].params.get("radius", 0.0) > 0:
        return float(effects[av].params["radius"])
    given = [c.radius * c.scale for c in characters if c.radius is not None]
    return float(max(given)) if given else AVOIDANCE_DEFAULT_RADIUS


def walkable_of(effects: list):
    """The scene's walkable area (``sim.routing.geometry.Walkable``, obstacles subtracted) or None without
    ``routing``. Call after :func:`apply_routing`."""
    at = _find(effects, "routing")
    if at is None:
        return None
    from sim.routing.effect import walkable_of as _walkable

    ob = _find(effects, "obstacles")
    return _walkable(effects[at].params, effects[ob].params if ob is not None else None)


def _obstacles_file(effects: list, key: str, layer_key: str, fail, base):
    """``(index, spec, cfg copy, where, path, areas)`` of the ``obstacles`` effect's floor-plan key ``key`` (read
    with ``sim.routing.floor_plan.load_walkable``, relative to ``base``; ``layer_key`` its DXF layer), or None
    when the effect or the key is absent; problems go to ``fail(key, message)``."""
    at = _find(effects, "obstacles")
    if at is None:
        return None
    ob = effects[at]
    cfg = dict(ob.params)
    where = f"effects[{ob.index}]"
    if cfg.get(layer_key) is not None and cfg.get(key) is None:
        fail(f"{where}.{layer_key}", f"only with `{key}` (a DXF drawing's layer)")
    if cfg.get(key) is None:
        return None
    from pathlib import Path

    from sim.routing.floor_plan import FloorPlanError, load_walkable

    path = (Path(base or ".") / cfg[key]).resolve()
    try:
        areas = load_walkable(path, cfg.get(layer_key))
    except FloorPlanError as e:
        fail(f"{where}.{key}", str(e))
    cfg[key] = str(path)
    return at, ob, cfg, where, path, areas


def apply_obstacle_file(effects: list, fail, base=None) -> None:
    """The ``obstacles`` effect's ``file`` (a floor plan relative to the scene's folder ``base``): its areas join
    the effect's ``polygons`` (each outer ring a solid; an area with a hole is refused: its hole would be a
    walkable pocket inside a solid), in place on ``effects``; problems go to ``fail(key, message)``."""
    got = _obstacles_file(effects, "file", "layer", fail, base)
    if got is None:
        return
    at, ob, cfg, where, path, areas = got
    from sim.obstacles import PARAMS as OBSTACLE_PARAMS
    from sim.params import ParamError

    for k, a in enumerate(areas):
        if a["holes"]:
            fail(f"{where}.file", f"{path}: area {k} has a hole; an obstacle is solid (draw the hole's inside as "
                                  f"walkable area instead)")
    try:
        extra = OBSTACLE_PARAMS["polygons"].check(f"{where}.file", [{"points": a["points"]} for a in areas])
    except ParamError as e:
        fail(e.key, f"{path}: {e.message}")
    cfg["polygons"] = list(cfg.get("polygons", [])) + extra
    effects[at] = dataclasses.replace(ob, params=cfg)


def apply_obstacle_walls(effects: list, fail, base=None) -> None:
    """The ``obstacles`` effect's ``walls_file`` (a floor plan relative to the scene's folder ``base``): walls
    ``wall_thickness`` thick around its walkable area's outline and holes (``sim.routing.effect.with_walls``, as
    routing's ``walkable_file`` gives them) join the effect's ``polygons``, in place on ``effects``; problems go to
    ``fail(key, message)``."""
    got = _obstacles_file(effects, "walls_file", "walls_layer", fail, base)
    if got is None:
        return
    at, ob, cfg, where, path, areas = got
    from sim.params import ParamError
    from sim.routing.effect import PARAMS as ROUTING_PARAMS
    from sim.routing.effect import with_walls

    try:
        walkable = ROUTING_PARAMS["walkable"].check(f"{where}.walls_file", areas)
    except ParamError as e:
        fail(e.key, f"{path}: {e.message}")
    cfg = with_walls({"walkable": walkable, "wall_thickness": cfg["wall_thickness"],
                      "wall_height": cfg["wall_height"]}, cfg)
    effects[at] = dataclasses.replace(ob, params=cfg)


def apply_routing(effects: list, characters: list, fail, base=None) -> None:
    """The checks and changes of the module docstring, in place on ``effects`` (a list of ``EffectSpec``);
    problems go to ``fail(key, message)``; ``base``: the scene file's folder (``walkable_file`` is relative to it)."""
    at = _find(effects, "routing")
    if at is None:
        return
    from sim.obstacles import PARAMS as OBSTACLE_PARAMS
    from sim.params import validate
    from sim.routing.effect import walkable_of as _walkable
    from sim.routing.effect import with_walls
    from sim.routing.geometry import shape_problem

    r = effects[at]
    where = f"effects[{r.index}]"
    cfg = dict(r.params)
    given = [k for k in ("walkable", "bounds", "walkable_file") if cfg.get(k) is not None]
    if len(given) != 1:
        fail(where, "expected exactly one of `walkable` (polygons with holes), `bounds` ([x0, z0, x1, z1]) or "
                    "`walkable_file` (a floor plan: .wkt, .geojson)" + (f"; got {', '.join(given)}" if given else ""))
    if cfg.get("walkable_layer") is not None and cfg.get("walkable_file") is None:
        fail(f"{where}.walkable_layer", "only with `walkable_file` (a DXF drawing's layer)")
    if cfg.get("walkable_file") is not None:  # the polygons from the file, checked as typed ones are
        from pathlib import Path

        from sim.params import ParamError
        from sim.routing.effect import PARAMS as ROUTING_PARAMS
        from sim.routing.floor_plan import FloorPlanError, load_walkable

        path = (Path(base or ".") / cfg["walkable_file"]).resolve()
        try:
            cfg["walkable"] = ROUTING_PARAMS["walkable"].check(f"{where}.walkable_file",
                                                               load_walkable(path, cfg.get("walkable_layer")))
        except FloorPlanError as e:
            fail(f"{where}.walkable_file", str(e))
        except ParamError as e:
            fail(e.key, f"{path}: {e.message}")
        cfg["walkable_file"] = str(path)
    ob = _find(effects, "obstacles")
    body = body_radius(effects, characters)
    if ob is None:
        clearance = cfg["clearance"] or body
        obstacles = validate(OBSTACLE_PARAMS, {"agent_radius": clearance}, "obstacles")
    else:
        obstacles = effects[ob].params
        ar = float(obstacles.get("agent_radius", OBSTACLE_PARAMS["agent_radius"].default))
        if cfg["clearance"] and cfg["clearance"] < ar:
            fail(f"{where}.clearance", f"expected >= the obstacles' agent_radius {ar:g} m (walls keep agents that "
                                       f"far), got {cfg['clearance']:g}")
        clearance = cfg["clearance"] or max(ar, body)
    cfg["clearance"] = float(clearance)
    walkable = _walkable(cfg, obstacles)
    if walkable.area.is_empty or walkable.area.area <= 1e-9:
        fail(where, "the walkable area is empty: the obstacles cover all of it")
    obstacles = with_walls(cfg, obstacles)
    g = _find(effects, "goals")
    if g is not None:
        for p, path in enumerate(effects[g].params.get("paths", [])):
            for k, (x, z) in enumerate(path):
                why = shape_problem(walkable, ("point", (x, z)))
                if why:
                    fail(f"effects[{effects[g].index}].paths[{p}][{k}]", f"waypoint ({x:g}, {z:g}) {why}")
    if ob is None:
        obs_spec = EffectSpec("obstacles", obstacles, len(effects))
    else:
        obs_spec = dataclasses.replace(effects[ob], params=obstacles)
    rest = [e for k, e in enumerate(effects) if k not in (at, ob)]
    effects[:] = [obs_spec, dataclasses.replace(r, params=cfg), *rest]
