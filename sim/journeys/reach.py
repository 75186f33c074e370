"""Which agents cannot reach their stages: the check a scene with journeys passes before it runs.

For every journey: its agents' start positions against every stage its first entry may choose, every stage
against every stage of the entry after it (and the last against the first when it loops), and every source's
spawn area against the first entry. "Reachable" is the router's ``reachable(goal, xz)`` (``sim.routing``:
components of the walkable area); the straight router has none, so :class:`FreeSpace` answers for it:
the floor rasterised at a few centimetres, cells free where a body of the clearance radius fits between the
``obstacles`` (their signed distance), 4-connected components labelled by ``scipy.ndimage.label``; outside the
obstacles' bounds everything is free, so crowds walk round them. Problems come back as (key, message) lines.
"""
from __future__ import annotations

import math

import numpy as np

#: largest raster of the free-space check (cells); the cell side grows to stay within it
FREE_SPACE_MAX_CELLS = 4_000_000
#: margin of free floor around everything the check looks at, metres
FREE_SPACE_MARGIN = 2.0


class FreeSpace:
    """Connected components of the floor free of obstacles for a body of radius ``clearance``."""

    def __init__(self, obstacles, clearance: float, points: np.ndarray):
        from scipy import ndimage

        self.obs = obstacles
        pts = [np.asarray(points, np.float64).reshape(-1, 2)]
        if obstacles.circles.size:
            c = obstacles.circles
            pts += [c[:, :2] - c[:, 2:], c[:, :2] + c[:, 2:]]
        if obstacles.verts.size:
            pts.append(obstacles.verts)
        allp = np.concatenate(pts, 0)
        lo = allp.min(0) - FREE_SPACE_MARGIN - clearance
        hi = allp.max(0) + FREE_SPACE_MARGIN + clearance
        h = max(clearance / 2.0, 0.02, math.sqrt(float(np.prod(hi - lo)) / FREE_SPACE_MAX_CELLS))
        self.lo, self.h = lo, h
        self.shape = (int(math.ceil((hi[0] - lo[0]) / h)) + 1, int(math.ceil((hi[1] - lo[1]) / h)) + 1)
        gx = lo[0] + h * np.arange(self.shape[0])
        gz = lo[1] + h * np.arange(self.shape[1])
        X, Z = np.meshgrid(gx, gz, indexing="ij")
        d = obstacles.sdf(X.ravel(), Z.ravel())[0].reshape(self.shape)
        self.free = d >= clearance
        self.label, _ = ndimage.label(self.free)
        # every cell's nearest free cell (an agent standing in a wall's clearance belongs to the space beside it)
        _, self.near = ndimage.distance_transform_edt(~self.free, return_indices=True)

    def cells(self, xz: np.ndarray) -> tuple:
        xz = np.asarray(xz, np.float64).reshape(-1, 2)
        i = np.clip(np.rint((xz[:, 0] - self.lo[0]) / self.h).astype(np.int64), 0, self.shape[0] - 1)
        j = np.clip(np.rint((xz[:, 1] - self.lo[1]) / self.h).astype(np.int64), 0, self.shape[1] - 1)
        return i, j

    def labels(self, xz: np.ndarray) -> np.ndarray:
        """(m,) component of each point (its nearest free cell's)."""
        i, j = self.cells(xz)
        return self.label[self.near[0][i, j], self.near[1][i, j]]

    def goal_labels(self, kind: str, pts: np.ndarray) -> set:
        """Components a shape touches: its free cells (a point: its nearest free cell)."""
        pts = np.asarray(pts, np.float64).reshape(-1, 2)
        if kind == "point":
            return {int(x) for x in self.labels(pts)}
        if kind == "line":
            n = max(2, int(math.ceil(math.dist(pts[0], pts[1]) / self.h)) + 1)
            s = pts[0] + np.linspace(0, 1, n)[:, None] * (pts[1] - pts[0])
        else:
            from sim.journeys.geometry import POLYGON, nearest_one

            lo, hi = pts.min(0), pts.max(0)
            gx = np.arange(lo[0], hi[0] + self.h, self.h)
            gz = np.arange(lo[1], hi[1] + self.h, self.h)
            X, Z = np.meshgrid(gx, gz, indexing="ij")
            k, st = np.array([POLYGON]), np.array([0, pts.shape[0]])
            s = np.array([(x, z) for x, z in zip(X.ravel(), Z.ravel()) if nearest_one(k, st, pts, 0, x, z)[2]]
                         + [tuple(p) for p in pts]).reshape(-1, 2)
        i, j = self.cells(s)
        f = self.free[i, j]
        return {int(x) for x in self.label[i[f], j[f]]} if f.any() else set()

    def reachable(self, kind: str, pts: np.ndarray, xz: np.ndarray) -> np.ndarray:
        goal = self.goal_labels(kind, pts)
        return np.isin(self.labels(xz), list(goal)) if goal else np.zeros(len(np.asarray(xz).reshape(-1, 2)), bool)


def _stage_points(stage) -> np.ndarray:
    """Where agents stand when they are done with ``stage`` (the start of the way to the next one)."""
    if stage.slots.shape[0]:
        return stage.slots[:1] if stage.kind == 3 else stage.slots
    if stage.point is not None:
        return stage.point.reshape(1, 2)
    return np.zeros((0, 2))


def _which(state, rows: np.ndarray, most: int = 6) -> str:
    """``agents 3, 4, 9 of placement[1]`` (ids, the first few, and their placement groups when known)."""
    ids = state.ids[rows]
    shown = ", ".join(str(int(i)) for i in ids[:most]) + (f", ... ({ids.size} in all)" if ids.size > most else "")
    groups = getattr(state, "groups", None) or []
    of = [f"placement[{g}]" for g, (a, n) in enumerate(groups) if np.any((rows >= a) & (rows < a + n))]
    return f"agent{'s' if ids.size > 1 else ''} {shown}" + (f" of {', '.join(of)}" if of else "")


def problems(journeys, world) -> list:
    """(key, message) of every journey leg some agents cannot walk (module docstring); [] when all can."""
    router = world.resources.get("routing")
    shapes = journeys.shapes
    if router is not None:
        if journeys.router is not router:
            journeys.use_router(router)

        def reach(shape, xz):
            return np.asarray(router.reachable(int(journeys.goals_of(np.array([shape]))[0]), xz), bool)
    else:
        obs = world.resources.get("obstacles")
        if obs is None or obs.count == 0:
            return []
        every = [np.asarray(shapes.shape(k)[1]) for k in range(len(shapes))]
        every.append(world.state.position[:, [0, 2]])
        every += [s.polygon if s.polygon is not None else s.line for s in journeys.sources]
        clear = max(float(world.resources.get("obstacles.agent_radius", 0.0)), 0.0)
        fs = FreeSpace(obs, clear, np.concatenate(every, 0))

        def reach(shape, xz):
            return fs.reachable(*shapes.shape(shape), xz)

    out = []
    st = journeys.stages
    for j, jr in enumerate(journeys.journeys):
        first = jr.entries[0][0]
        agents = np.flatnonzero(journeys.journey == j)
        if agents.size:
            xz = world.state.position[agents][:, [0, 2]]
            for s in first:
                ok = reach(st[s].shape, xz)
                if not ok.all():
                    bad = agents[~ok]
                    p = xz[int(np.flatnonzero(~ok)[0])]
                    out.append((f"journeys[{j}]", f"{bad.size} of {agents.size} agents of journey {jr.name!r} cannot "
                                f"reach stage {st[s].name!r}: {_which(world.state, bad)} (the first at "
                                f"({p[0]:.2f}, {p[1]:.2f}))"))
        legs = list(zip(jr.entries, jr.entries[1:])) + ([(jr.entries[-1], jr.entries[0])] if jr.loop else [])
        for a, b in legs:
            for sa in a[0]:
                pts = _stage_points(st[sa])
                for sb in b[0]:
                    if pts.shape[0] and not reach(st[sb].shape, pts).all():
                        out.append((f"journeys[{j}]", f"stage {st[sb].name!r} cannot be reached from stage "
                                    f"{st[sa].name!r} (journey {jr.name!r})"))
    for i, src in enumerate(journeys.sources):
        area = src.polygon if src.polygon is not None else src.line
        samples = np.concatenate([area, area.mean(0, keepdims=True)], 0)
        jr = journeys.journeys[int(src.cfg["journey"])]
        for s in jr.entries[0][0]:
            ok = reach(st[s].shape, samples)
            if not ok.any():
                out.append((f"sources[{i}]", f"agents entering at source {src.name!r} cannot reach stage "
                            f"{st[s].name!r} (journey {jr.name!r})"))
    return out
