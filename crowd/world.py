"""The world around the crowd, made drawable: props, obstacle solids and the ground.

Builds (once per engine) the representations of ``lod.props`` from the scene:
each ``[[props]]`` table's triangle chain (``lod.props.chain``, cached) with its
placements' model rows, the solids of the ``obstacles`` effect's visible shapes
(on the terrain when there is one) and the ground plane (unless ``[render]
ground = false``, and not with a ``[terrain]``: the terrain is the ground).
Each frame :meth:`Scenery.add` appends the world's batches to the DrawList and
its counts to the DrawList's stats (``props``: triangles of props and solids).
"""
from __future__ import annotations

import dataclasses

import numpy as np


class Scenery:
    """The world's representations and their per-frame selector (``lod.props.select.WorldSelector``)."""

    def __init__(self, selector):
        self.selector = selector

    @property
    def reps(self) -> list:
        return self.selector.reps

    @property
    def keys(self) -> frozenset:
        return frozenset(r.key for r in self.reps)

    def add(self, drawlist, camera, size, poe: float, lod_mode: str):
        """Append this frame's world batches to ``drawlist`` (returned); level 0 in LOD mode ``none``.

        The world is selected from the DrawList's own camera (its ``origin`` and view rotation), which a
        keyframed selection in "delayed" mode takes from an earlier frame than ``camera``."""
        origin = np.asarray(drawlist.origin, np.float64)
        if not np.array_equal(origin, camera.position):
            from lod.view import Camera

            rot = np.asarray(drawlist.view, np.float64)[:3, :3].T
            camera = Camera(origin, rot, camera.fov_y, camera.near, camera.far)
        batches, stats = self.selector.select(camera, size, poe=poe, full_detail=(lod_mode == "none"))
        drawlist.batches.extend(batches)
        drawlist.stats.update(stats)
        return drawlist


def build_scenery(scene, world, cache: bool = True) -> Scenery:
    """The :class:`Scenery` of a validated scene and its built ``sim.world.World``."""
    from lod.props.chain import cached_chain
    from lod.props.select import WorldSelector
    from lod.props.solids import GroundRep, obstacle_solids
    from sim.props import load_prop_mesh, model_rows, prop_instances

    groups = []
    for p in scene.props:
        mesh = load_prop_mesh(p.file, p.params["up"])
        if p.params["color"] is not None:
            colors = np.ones_like(mesh.colors)
            colors[:, :3] = p.params["color"]
            mesh = dataclasses.replace(mesh, colors=colors)
        rep = cached_chain(mesh, f"props:{p.index}:{p.name}", cache=cache)
        groups.append((rep, model_rows(*prop_instances(p.params))))
    terrain = world.resources.get("terrain")
    obs = world.resources.get("obstacles")
    if obs is not None:
        solids = obstacle_solids(obs, ground=terrain.height if terrain is not None else None)
        if solids is not None:
            groups.append(solids)
    ground = GroundRep() if scene.render.ground and terrain is None else None
    return Scenery(WorldSelector(groups, ground))


def props_bytes(scene) -> int:
    """Estimated bytes of the scene's props: chains (at most twice the full mesh's triangles, three
    unshared 40-byte corners each, on the CPU and the GPU) and per-instance rows."""
    tris = sum(int(p.triangles) for p in scene.props)
    inst = sum(int(p.instances) for p in scene.props)
    return 2 * (2 * tris * 3 * 40 + tris * 2 * 12) + inst * (96 + 64)
