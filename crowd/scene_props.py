"""``[[props]]``: static meshes placed in a scene (sim/props.py reads them), parsed for :mod:`crowd.scene`.

The footprints of ``obstacle = true`` props are added to the ``obstacles`` effect here, before anything is
built; every problem is reported through the parser's ``fail(key, message)`` as one line naming the key.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from crowd.scene_types import EffectSpec
from sim.params import validate


@dataclass(frozen=True)
class PropSpec:
    """One ``[[props]]`` table (``sim.props.PROP_PARAMS``), its file read and checked.

    file : absolute Path of the mesh file; params : validated dict; triangles : int of the file
    """

    name: str
    file: Path
    params: dict
    triangles: int
    instances: int
    index: int = 0


def parse_props(tables: list, effects: list, base: Path, fail) -> list:
    """Validate ``[[props]]``, read their files; the footprints of ``obstacle = true`` props are
    added to the ``obstacles`` effect (listed for them with its defaults when the scene has none)."""
    if not tables:
        return []
    import sim.props as sp
    from sim.errors import AssetError

    out, extra = [], {"circles": [], "boxes": [], "polygons": []}
    for i, t in enumerate(tables):
        where = f"props[{i}]"
        cfg = sp.validate_prop(t, where)
        file = (base / cfg["file"]).resolve()
        if file.suffix.lower() not in sp.PROP_SUFFIXES:
            fail(f"{where}.file", f"expected a mesh file ({', '.join(sp.PROP_SUFFIXES)}), got {cfg['file']!r}")
        try:
            mesh = sp.load_prop_mesh(file, cfg["up"])
        except AssetError as e:
            fail(f"{where}.file", str(e))
        pos, yaw, scale = sp.prop_instances(cfg)
        if cfg["obstacle"]:
            try:
                fp = sp.footprint(mesh, cfg["footprint"], file.name)
            except AssetError as e:
                fail(f"{where}.footprint", str(e))
            for k, v in sp.placed_obstacles(fp, pos, yaw, scale).items():
                extra[k] += v
        out.append(PropSpec(name=cfg["name"] or f"props[{i}]", file=file, params=cfg,
                            triangles=mesh.n_triangles, instances=len(pos), index=i))
    if any(extra.values()):
        from sim.obstacles import PARAMS as OBSTACLE_PARAMS

        at = next((k for k, e in enumerate(effects) if e.name == "obstacles"), None)
        if at is None:
            effects.append(EffectSpec("obstacles", validate(OBSTACLE_PARAMS, {}, "effects"), len(effects)))
            at = len(effects) - 1
        e = effects[at]
        params = {**e.params, **{k: list(e.params.get(k, [])) + v for k, v in extra.items()}}
        effects[at] = dataclasses.replace(e, params=params)
    return out
