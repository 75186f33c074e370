"""Where the agents start: placements that put agents inside an obstacle or outside the walkable area.

With the ``routing`` effect an agent must start in its walkable area (outside the polygons or inside an obstacle
is an error of the scene: the routing effect's install refuses it, and :func:`check_walkable` makes the same check
when the scene's agents are planned, so ``crowd validate`` refuses what ``crowd run`` would). With ``obstacles``
alone a grid of agents may be placed across a wall: the effect pushes them out on the first step
(``sim.obstacles``, the projection), but frame 0 shows them overlapping the wall and the crowd's first moves are a
jolt. ``crowd validate`` warns of it and ``crowd run`` says it once: one line per placement, with counts
(:func:`start_warnings`; inside: the obstacles' signed distance is negative at the agent's floor point).
"""
from __future__ import annotations

import numpy as np


def _effect(scene, name: str):
    return next((e for e in scene.effects if e.name == name), None)


def check_walkable(scene, state) -> None:
    """With ``routing``: every agent of ``state`` starts in the walkable area (``sim.routing.effect.check_agents``).

    Raises
    ------
    crowd.errors.SceneError
        The placement and the first agent outside the area or inside an obstacle, and how many more.
    """
    if _effect(scene, "routing") is None:  # a scene without routing imports none of it
        return
    from crowd.scene_routing import walkable_of

    area = walkable_of(list(scene.effects))
    if area is None:
        return
    from crowd.errors import SceneError
    from sim.params import ParamError
    from sim.routing.effect import check_agents

    try:
        check_agents(area, state)
    except ParamError as e:
        raise SceneError(scene.path, e.key, e.message) from None


def start_warnings(scene, state, agents_per_placement) -> list:
    """One sentence per placement of ``scene`` with agents of ``state`` (its placements back to back, as
    :func:`crowd.plan.plan` builds it) starting inside an obstacle of the ``obstacles`` effect, and per recording
    (a trajectories placement) whose rows leave the walkable area (:func:`recording_notes`)."""
    notes = recording_notes(scene)
    obstacles = _effect(scene, "obstacles")
    if int(state.n) == 0 or obstacles is None:
        return notes
    from sim.obstacles import ObstacleSet

    obs = ObstacleSet.from_config(dict(obstacles.params))
    if not obs.count:
        return notes
    xz = np.asarray(state.position, np.float64)[:, [0, 2]]
    inside = obs.sdf(xz[:, 0], xz[:, 1])[0] < 0.0
    out, first = [], 0
    for p, count in zip(scene.placements, agents_per_placement):
        k = int(inside[first:first + int(count)].sum()) if p.kind != "trajectories" else 0
        if k:
            out.append(f"warning: {scene.path}: placement[{p.index}]: {k} of its {int(count)} agents start inside "
                       "an obstacle (the obstacles effect pushes them out on the first step)")
        first += int(count)
    return out + notes


def recording_notes(scene) -> list:
    """One sentence per trajectories placement (``sim.replay``) whose recorded rows lie outside the walkable area
    (the routing effect's) or inside an obstacle (the obstacles effect's, the walls of a ``walls_file`` included):
    how many rows, of how many people, and how far at most. Recorded people are replayed as recorded all the same."""
    recs = [p for p in scene.placements if p.kind == "trajectories" and p.params.get("recording") is not None]
    obstacles, routing = _effect(scene, "obstacles"), _effect(scene, "routing")
    if not recs or (obstacles is None and routing is None):
        return []
    import shapely

    area = None
    if routing is not None:
        from crowd.scene_routing import walkable_of

        area = walkable_of(list(scene.effects))
    obs = None
    if obstacles is not None:
        from sim.obstacles import ObstacleSet

        obs = ObstacleSet.from_config(dict(obstacles.params))
    out = []
    for p in recs:
        rec = p.params["recording"]
        xz = rec.xy
        depth = np.zeros(rec.rows)  # how far each row lies outside the area or inside an obstacle, metres
        if obs is not None and obs.count:
            depth = np.maximum(depth, -obs.sdf(xz[:, 0], xz[:, 1])[0])
        if area is not None:
            off = area.where(xz) != 0
            if off.any():
                pts = shapely.points(xz[off])
                depth[off] = np.maximum(depth[off], np.maximum(shapely.distance(area.area, pts), 1e-9))
        bad = depth > 0
        if bad.any():
            people = np.unique(np.repeat(np.arange(rec.persons), np.diff(rec.start))[bad]).shape[0]
            out.append(f"note: {scene.path}: placement[{p.index}]: {int(bad.sum()):,} of the recording's "
                       f"{rec.rows:,} rows ({people} of {rec.persons} people) lie outside the walkable area or "
                       f"inside an obstacle, up to {depth.max():.2f} m; replayed as recorded")
    return out
