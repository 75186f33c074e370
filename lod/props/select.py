"""Per-frame selection of the world: prop levels by pixels of error, culling, batches.

Every prop instance is frustum-culled by its bounding sphere
(:func:`lod.cull.cull_spheres`, camera-relative centres) and drawn at the
coarsest level of its chain whose error projects to at most ``poe`` pixels:
the rule of the characters' chains (``lod.chains.mode.choose_levels``; VDR-AM
§5's pixels of error): with the sphere's nearest distance ``d`` to the camera,
the scale ``s`` and ``k = height / (2 tan(fov / 2))`` pixels per metre at unit
distance, level ``l`` passes when ``error_l * s * k / d <= poe``; an instance
whose sphere holds the camera gets level 0. LOD mode ``none`` draws level 0.

Model rows are made camera-relative in float64 before they become float32, so
props a million metres from the origin draw as precisely as near ones.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lod.cull import cull_spheres
from lod.drawlist import INSTANCE_FLOATS, DrawBatch


@dataclass
class WorldBatch(DrawBatch):
    """A DrawBatch of a world representation (``render.world.draw``): ``index_range`` =
    (first index, index count) of the drawn chain level; None for the ground."""

    index_range: tuple | None = None


def pixels_per_metre(height_px: float, fov_y: float) -> float:
    """``height / (2 tan(fov_y / 2))``: pixels per metre at unit distance."""
    return float(height_px) / (2.0 * np.tan(np.radians(float(fov_y)) * 0.5))


def choose_prop_levels(errors, rows, sphere, scale_px: float, poe: float) -> np.ndarray:
    """(k,) int64 coarsest level per instance within ``poe`` pixels (module docstring).

    errors : (L,) monotone metres; rows : (k, 3, 4) camera-relative model rows;
    sphere : (4,) model-space bounding sphere; scale_px : pixels per metre at unit distance.
    """
    rows = np.asarray(rows, np.float64).reshape(-1, 3, 4)
    s = np.linalg.norm(rows[:, :, :3], axis=1).max(axis=1)
    c = rows[:, :, :3] @ np.asarray(sphere[:3], np.float64) + rows[:, :, 3]
    d = np.linalg.norm(c, axis=1) - float(sphere[3]) * s
    inside = ~(d > 0.0)
    px = np.asarray(errors, np.float64)[None, :] * (s * scale_px / np.where(inside, 1.0, d))[:, None]
    lvl = np.maximum((px <= float(poe)).sum(axis=1) - 1, 0)
    lvl[inside] = 0
    return lvl.astype(np.int64)


def instance_data(rows_rel: np.ndarray) -> np.ndarray:
    """(k, 16) float32 instance data of camera-relative model rows (k, 3, 4) (``lod.drawlist``)."""
    out = np.zeros((len(rows_rel), INSTANCE_FLOATS), np.float32)
    out[:, :12] = np.asarray(rows_rel, np.float64).reshape(-1, 12)
    return out


class WorldSelector:
    """Selects the world's batches each frame.

    Parameters
    ----------
    groups : list of (PropChainRep, (n, 3, 4) float64 world model rows)
    ground : lod.props.solids.GroundRep or None
    """

    def __init__(self, groups, ground=None):
        self.groups = []
        for rep, rows in groups:
            rows = np.asarray(rows, np.float64).reshape(-1, 3, 4)
            if not np.isfinite(rows).all():
                raise ValueError(f"world representation {rep.key!r}: placements hold NaN or Inf")
            s = np.linalg.norm(rows[:, :, :3], axis=1).max(axis=1)
            centers = rows[:, :, :3] @ rep.sphere[:3] + rows[:, :, 3]
            self.groups.append((rep, rows, centers, rep.sphere[3] * s))
        self.ground = ground

    @property
    def reps(self) -> list:
        return [g[0] for g in self.groups] + ([self.ground] if self.ground is not None else [])

    def select(self, camera, size, poe: float = 1.0, full_detail: bool = False) -> tuple[list, dict]:
        """(batches, stats) of this frame; stats: ``props`` (triangles), ``props_instances``, ``props_culled``."""
        w, h = int(size[0]), int(size[1])
        planes = camera.frustum_planes(w / h)
        k_px = pixels_per_metre(h, camera.fov_y)
        eye = camera.position
        batches, tris, shown, culled = [], 0, 0, 0
        for rep, rows, centers, radii in self.groups:
            vis = np.flatnonzero(cull_spheres(centers - eye, radii, planes))
            culled += len(rows) - len(vis)
            if not len(vis):
                continue
            rel = rows[vis].copy()
            rel[:, :, 3] -= eye
            lvl = np.zeros(len(vis), np.int64) if full_detail else \
                choose_prop_levels(rep.level_error, rel, rep.sphere, k_px, poe)
            data = instance_data(rel)
            for level in np.unique(lvl):
                sel = lvl == level
                count = int(rep.level_count[level])
                n = int(sel.sum())
                batches.append(WorldBatch(rep=rep.key, part=0, instance_ids=vis[sel].astype(np.int32),
                                          instance_data=data[sel], triangles=n * count, level=int(level),
                                          index_range=(3 * int(rep.level_first[level]), 3 * count)))
                tris += n * count
                shown += n
        if self.ground is not None:
            d = np.zeros((1, INSTANCE_FLOATS), np.float32)
            d[0, [0, 5, 10]] = 1.0
            d[0, 7] = float(self.ground.height - eye[1])  # camera-relative height of the plane
            d[0, 12] = float(camera.far)  # half extent of the quad: to the far plane
            d[0, 13:15] = np.mod(eye[[0, 2]], 100.0)  # grid phase (float64 mod: exact far from the origin)
            batches.insert(0, WorldBatch(rep=self.ground.key, part=0, instance_ids=np.zeros(1, np.int32),
                                         instance_data=d, triangles=2))
        return batches, {"props": tris, "props_instances": shown, "props_culled": culled}
