"""Static obstacles on the XZ plane (effect ``obstacles``).

Wand & Straßer 2002, §5.2: the boids are "controlled by local force fields
around each object and each obstacle". Every obstacle (circle, rotated box,
simple polygon) has a signed distance ``d(p)`` (negative inside) and an
outward unit normal ``n(p)``. Two steps:

``obstacles.steer`` (before ``boids``, only when boids is installed): the force
field. For the probes ``p`` and ``p + v * lookahead``, where
``d - agent_radius < margin``, an acceleration
``strength * (margin - (d - agent_radius)) / margin * n`` is added to
``world.resources["boids.accel"]``, plus the same magnitude times
``w_slide`` along the obstacle tangent that the velocity points to (agents
slide around obstacles instead of stopping in front of them).

``obstacles.project`` (after ``boids``): the hard constraint. The move of the
step (from the position recorded by ``obstacles.record`` before anything moved
agents) is swept by sphere tracing on the signed distance, and an agent stops
at its first contact, so even obstacles thinner than one step's travel are
never tunnelled through. An agent that still overlaps (spawned inside, pushed
by a neighbour-free corner case) is moved out along the normal; at contact it
loses its velocity component into the obstacle. An agent driven into an
obstacle at full speed therefore ends every step outside it: its penetration is
never deeper than the travel of one step.

Cost: O(agents x obstacles) with a bounding-circle early-out per polygon;
both kernels are parallel over agents, each agent writing only its own row
(deterministic for any thread count). :func:`sdf_numpy`, :func:`steer_numpy`
and :func:`project_numpy` are the plain numpy references the tests compare the
kernels with.

Departure from the paper: the paper has force fields only; the projection
guarantees no penetration whatever the weights.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.config import OBSTACLES_CCD_EPS, OBSTACLES_CCD_ITERATIONS, OBSTACLES_CONTACT, OBSTACLES_EPS
from sim.params import Param, ParamError, validate

#: drawing keys of every shape (render only: the simulation ignores them)
_DRAW = {"height": Param("float", 1.0, min=0.0, max=1e4, doc="height of the drawn solid, metres"),
         "visible": Param("bool", True, doc="draw the shape as a solid (false: it only stops agents)")}
_CIRCLE = {"center": Param("vec2", doc="centre [x, z], metres"),
           "radius": Param("float", min=1e-6, doc="metres"), **_DRAW}
_BOX = {"center": Param("vec2", doc="centre [x, z], metres"),
        "size": Param("vec2", doc="full extent [sx, sz], metres (> 0)"),
        "yaw": Param("float", 0.0, doc="rotation about +Y, degrees"), **_DRAW}


class _TableList(Param):
    """A list of tables, each validated against ``schema`` (kept in ``doc``)."""

    def __init__(self, schema, doc):
        super().__init__("list", [], doc=doc)
        object.__setattr__(self, "schema", schema)

    def check(self, key, value):
        if not isinstance(value, list):
            raise ParamError(key, f"expected a list of tables, got {value!r}")
        out = []
        for i, t in enumerate(value):
            if not isinstance(t, dict):
                raise ParamError(f"{key}[{i}]", f"expected a table, got {t!r}")
            out.append(validate(self.schema, t, f"{key}[{i}]"))
            if "size" in out[-1] and min(out[-1]["size"]) <= 0:
                raise ParamError(f"{key}[{i}].size", f"expected two numbers > 0, got {t['size']!r}")
        return out


class _Polygons(Param):
    def check(self, key, value):
        if not isinstance(value, list):
            raise ParamError(key, f"expected a list of tables {{points = [[x, z], ...]}}, got {value!r}")
        out = []
        for i, t in enumerate(value):
            w = f"{key}[{i}]"
            if not isinstance(t, dict) or "points" not in t or not set(t) <= {"points", *_DRAW}:
                raise ParamError(w, f"expected a table {{points = [[x, z], ...]}} (optional height, visible), "
                                 f"got {t!r}")
            pts = t["points"]
            if not isinstance(pts, list) or len(pts) < 3:
                raise ParamError(f"{w}.points", f"expected at least 3 points [x, z], got {pts!r}")
            pts = [Param("vec2").check(f"{w}.points[{j}]", p) for j, p in enumerate(pts)]
            if abs(_area(np.array(pts))) < 1e-12:
                raise ParamError(f"{w}.points", "expected a polygon of non-zero area")
            out.append({"points": pts, **validate(_DRAW, {k: v for k, v in t.items() if k != "points"}, w)})
        return out


PARAMS: dict[str, Param] = {
    "circles": _TableList(_CIRCLE, "[{center = [x, z], radius = r}, ...]"),
    "boxes": _TableList(_BOX, "[{center = [x, z], size = [sx, sz], yaw = deg}, ...]"),
    "polygons": _Polygons("list", [], doc="[{points = [[x, z], ...]}, ...] simple polygons, either winding "
                                          "(each shape also takes height = metres, visible = bool: its drawn solid)"),
    "file": Param("str", None, doc="more polygons: the areas of a floor-plan file (WKT, GeoJSON, DXF; "
                                   "sim.routing.floor_plan), relative to the scene file, each a solid of height 1 m"),
    "layer": Param("str", None, doc="file a DXF: read the entities of this layer only"),
    "walls_file": Param("str", None, doc="walls around the walkable area of a floor-plan file (WKT, GeoJSON, DXF; "
                                         "its outline and holes, as routing's walkable_file draws them), relative "
                                         "to the scene file: a recorded crowd's building (sim.replay)"),
    "walls_layer": Param("str", None, doc="walls_file a DXF: read the entities of this layer only"),
    "wall_thickness": Param("float", 0.3, min=0.01, max=100.0, doc="thickness of the walls_file walls, metres"),
    "wall_height": Param("float", 1.0, min=0.0, max=1e4, doc="drawn height of the walls_file walls, metres; "
                                                              "0 = not drawn"),
    "agent_radius": Param("float", 0.4, min=0.0, max=100.0, doc="agent body radius kept clear of obstacles, m"),
    "margin": Param("float", 2.0, min=1e-3, max=1000.0, doc="force-field reach beyond agent_radius, m"),
    "lookahead": Param("float", 1.0, min=0.0, max=60.0, doc="look-ahead time of the second probe, s"),
    "strength": Param("float", 8.0, min=0.0, max=1000.0, doc="force-field acceleration at contact, m/s^2"),
    "w_slide": Param("float", 0.5, min=0.0, max=10.0, doc="tangential (sliding) share of the force field"),
}


def _area(p: np.ndarray) -> float:
    x, z = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x * np.roll(z, -1) - np.roll(x, -1) * z))


class ObstacleSet:
    """Obstacles as flat arrays (boxes become 4-point polygons).

    circles : (C, 3) float64, rows (x, z, r)
    verts : (V, 2) float64, polygon vertices (x, z), polygons back to back
    pstart : (P + 1,) int64, polygon k is ``verts[pstart[k]:pstart[k+1]]``
    pbound : (P, 3) float64, bounding circle (x, z, r) of every polygon
    circle_draw, poly_draw : (C, 2) and (P, 2) float64, per shape (height m, visible 0/1) of its drawn
        solid (boxes first, then polygons, as in ``pstart``); the simulation ignores them
    """

    def __init__(self, circles=(), boxes=(), polygons=()):
        draw = lambda t: (float(t.get("height", 1.0)), float(bool(t.get("visible", True))))  # noqa: E731
        self.circle_draw = np.array([draw(c) for c in circles], np.float64).reshape(-1, 2)
        self.poly_draw = np.array([draw(t) for t in [*boxes, *polygons]], np.float64).reshape(-1, 2)
        self.circles = np.array([[c["center"][0], c["center"][1], c["radius"]] for c in circles],
                                np.float64).reshape(-1, 3)
        polys = []
        for b in boxes:
            (cx, cz), (sx, sz) = b["center"], b["size"]
            a = math.radians(b.get("yaw", 0.0))
            c, s = math.cos(a), math.sin(a)
            loc = np.array([[-sx, -sz], [sx, -sz], [sx, sz], [-sx, sz]]) / 2.0
            # yaw about +Y maps local +Z to (sin a, cos a)
            polys.append(np.stack([cx + c * loc[:, 0] + s * loc[:, 1], cz - s * loc[:, 0] + c * loc[:, 1]], 1))
        for p in polygons:
            polys.append(np.asarray(p["points"], np.float64).reshape(-1, 2))
        self.verts = np.concatenate(polys, 0) if polys else np.zeros((0, 2))
        self.pstart = np.zeros(len(polys) + 1, np.int64)
        self.pstart[1:] = np.cumsum([len(p) for p in polys]) if polys else []
        self.pbound = np.zeros((len(polys), 3))
        for k, p in enumerate(polys):
            c = p.mean(0)
            self.pbound[k] = (c[0], c[1], float(np.sqrt(((p - c) ** 2).sum(1)).max()))

    @classmethod
    def from_config(cls, cfg: dict) -> "ObstacleSet":
        return cls(cfg.get("circles", []), cfg.get("boxes", []), cfg.get("polygons", []))

    @property
    def count(self) -> int:
        return int(self.circles.shape[0] + self.pbound.shape[0])

    def sdf(self, x, z):
        """Signed distance (negative inside) and outward normal at points.

        x, z : (m,) float64 -> d : (m,) float64, nx, nz : (m,) float64 (unit).
        Far from every obstacle (none at all) d is +inf-free: 1e30.
        """
        x = np.ascontiguousarray(x, np.float64)
        z = np.ascontiguousarray(z, np.float64)
        d, nx, nz = np.empty_like(x), np.empty_like(x), np.empty_like(x)
        _sdf_many(x, z, self.circles, self.verts, self.pstart, self.pbound, d, nx, nz)
        return d, nx, nz


# ----------------------------------------------------------------- kernels
_FAR = 1e30


@njit(cache=True)
def _sdf_point(px, pz, circles, verts, pstart, pbound, cutoff):
    """(d, nx, nz) of the nearest obstacle; obstacles farther than ``cutoff``
    (by bounding circle) are skipped. d = 1e30 when none is near."""
    best, bnx, bnz = _FAR, 0.0, 1.0
    for c in range(circles.shape[0]):
        dx, dz = px - circles[c, 0], pz - circles[c, 1]
        r = math.sqrt(dx * dx + dz * dz)
        d = r - circles[c, 2]
        if d < best:
            best = d
            if r > OBSTACLES_EPS:
                bnx, bnz = dx / r, dz / r
            else:
                bnx, bnz = 0.0, 1.0
    for k in range(pbound.shape[0]):
        dx, dz = px - pbound[k, 0], pz - pbound[k, 1]
        if math.sqrt(dx * dx + dz * dz) - pbound[k, 2] > min(best, cutoff):
            continue
        s, e = pstart[k], pstart[k + 1]
        dmin2 = _FAR
        cx, cz = 0.0, 0.0
        inside = False
        ex_, ez_ = 0.0, 0.0
        for a in range(s, e):
            b = a + 1 if a + 1 < e else s
            ax_, az_ = verts[a, 0], verts[a, 1]
            bx_, bz_ = verts[b, 0], verts[b, 1]
            ux, uz = bx_ - ax_, bz_ - az_
            ll = ux * ux + uz * uz
            t = ((px - ax_) * ux + (pz - az_) * uz) / ll if ll > 0.0 else 0.0
            t = min(max(t, 0.0), 1.0)
            qx, qz = ax_ + t * ux, az_ + t * uz
            d2 = (px - qx) * (px - qx) + (pz - qz) * (pz - qz)
            if d2 < dmin2:
                dmin2, cx, cz, ex_, ez_ = d2, qx, qz, ux, uz
            if (az_ > pz) != (bz_ > pz):
                xc = ax_ + (pz - az_) / (bz_ - az_) * ux
                if px < xc:
                    inside = not inside
        dist = math.sqrt(dmin2)
        d = -dist if inside else dist
        if d < best:
            best = d
            if dist > OBSTACLES_EPS:
                nx, nz = (px - cx) / dist, (pz - cz) / dist
                if inside:
                    nx, nz = -nx, -nz
            else:  # on the boundary: perpendicular of the edge, pointing away from the centre
                ln = math.sqrt(ex_ * ex_ + ez_ * ez_)
                nx, nz = (ez_ / ln, -ex_ / ln) if ln > 0.0 else (0.0, 1.0)
                if nx * (px - pbound[k, 0]) + nz * (pz - pbound[k, 1]) < 0.0:
                    nx, nz = -nx, -nz
            bnx, bnz = nx, nz
    return best, bnx, bnz


@njit(cache=True, parallel=True)
def _sdf_many(x, z, circles, verts, pstart, pbound, d, nx, nz):
    for i in prange(x.shape[0]):
        d[i], nx[i], nz[i] = _sdf_point(x[i], z[i], circles, verts, pstart, pbound, _FAR)


@njit(cache=True, parallel=True)
def _steer_kernel(pos, vel, circles, verts, pstart, pbound, radius, margin, lookahead, strength, w_slide, acc):
    for i in prange(pos.shape[0]):
        px, pz = pos[i, 0], pos[i, 2]
        vx, vz = vel[i, 0], vel[i, 2]
        for probe in range(2):
            qx = px + (vx * lookahead if probe == 1 else 0.0)
            qz = pz + (vz * lookahead if probe == 1 else 0.0)
            d, nx, nz = _sdf_point(qx, qz, circles, verts, pstart, pbound, radius + margin)
            gap = d - radius
            if gap < margin:
                f = strength * min((margin - gap) / margin, 2.0)
                tx, tz = -nz, nx  # tangent; pick the side the velocity points to
                if tx * vx + tz * vz < 0.0:
                    tx, tz = -tx, -tz
                acc[i, 0] += f * (nx + w_slide * tx)
                acc[i, 2] += f * (nz + w_slide * tz)


def polygon_boxes(verts, pstart) -> np.ndarray:
    """(K, 4) float64 axis-aligned bounding boxes (xmin, zmin, xmax, zmax) of the polygons ``verts[pstart[k]:
    pstart[k + 1]]`` (computed per call from the arrays as they are: callers may move obstacles in place)."""
    k = pstart.shape[0] - 1
    out = np.zeros((max(k, 0), 4), np.float64)
    if k > 0 and verts.shape[0]:
        s = pstart[:-1]
        out[:, 0] = np.minimum.reduceat(verts[:, 0], s)
        out[:, 1] = np.minimum.reduceat(verts[:, 1], s)
        out[:, 2] = np.maximum.reduceat(verts[:, 0], s)
        out[:, 3] = np.maximum.reduceat(verts[:, 1], s)
    return out


@njit(cache=True, inline="always")
def box_dist2(px, pz, pbox, k):
    """Squared distance from p to polygon k's bounding box (0 inside): a lower bound of the squared distance
    to any of its edges."""
    dx = max(pbox[k, 0] - px, 0.0, px - pbox[k, 2])
    dz = max(pbox[k, 1] - pz, 0.0, pz - pbox[k, 3])
    return dx * dx + dz * dz


@njit(cache=True, inline="always")
def _clear_bound(px, pz, circles, pbox):
    """A lower bound of the distance from p to every obstacle: exact for circles, the distance to the
    bounding box for polygons (0 inside it)."""
    best = _FAR
    for c in range(circles.shape[0]):
        dx, dz = px - circles[c, 0], pz - circles[c, 1]
        d = math.sqrt(dx * dx + dz * dz) - circles[c, 2]
        if d < best:
            best = d
    for k in range(pbox.shape[0]):
        d = math.sqrt(box_dist2(px, pz, pbox, k))
        if d < best:
            best = d
    return best


@njit(cache=True, parallel=True)
def _project_kernel(pos, vel, prev, has_prev, circles, verts, pstart, pbound, radius, pbox):
    """Hard constraint: continuous collision along prev -> pos, then projection.

    Sphere tracing along the step's segment (the SDF is an exact distance, so
    steps of ``d - radius`` never skip an obstacle) stops an agent at its first
    contact: no tunnelling through thin obstacles. An agent starting the step in
    contact slides: the part of its move into the obstacle is dropped. Agents
    still overlapping (e.g. spawned inside) are projected out along the normal.
    """
    for i in prange(pos.shape[0]):
        px, pz = pos[i, 0], pos[i, 2]
        if has_prev:
            sx, sz = prev[i, 0], prev[i, 1]
            ux, uz = px - sx, pz - sz
            ll = math.sqrt(ux * ux + uz * uz)
            if _clear_bound(sx, sz, circles, pbox) - ll - radius > OBSTACLES_CONTACT + OBSTACLES_CCD_EPS:
                # clear of every obstacle along the whole move (the SDF is 1-Lipschitz, the bound is at most
                # the SDF): the sphere trace ends at pos, and the projection and contact tests change nothing
                continue
            d0, n0x, n0z = _sdf_point(sx, sz, circles, verts, pstart, pbound, _FAR)
            if d0 - ll - radius > OBSTACLES_CONTACT + OBSTACLES_CCD_EPS:  # the same with the exact distance
                continue
            if ll > 0.0 and d0 - radius > OBSTACLES_CCD_EPS:
                t = 0.0
                for it in range(OBSTACLES_CCD_ITERATIONS):
                    qx, qz = sx + t * ux, sz + t * uz
                    d, _, _ = _sdf_point(qx, qz, circles, verts, pstart, pbound, _FAR)
                    gap = d - radius
                    if gap <= OBSTACLES_CCD_EPS:  # contact: stop here
                        px, pz = qx, qz
                        break
                    t += gap / ll
                    if t >= 1.0:
                        break
            elif ll > 0.0 and d0 - radius <= OBSTACLES_CONTACT:
                # started in contact: slide, i.e. drop the part of the move into the obstacle
                un = ux * n0x + uz * n0z
                if un < 0.0:
                    px, pz = sx + ux - un * n0x, sz + uz - un * n0z
        for it in range(4):  # a few passes resolve corners between two obstacles
            d, nx, nz = _sdf_point(px, pz, circles, verts, pstart, pbound, radius)
            pen = radius - d
            if pen <= 0.0:
                break
            px += nx * pen
            pz += nz * pen
            vn = vel[i, 0] * nx + vel[i, 2] * nz
            if vn < 0.0:
                vel[i, 0] -= vn * nx
                vel[i, 2] -= vn * nz
        # at contact, drop the velocity component into the obstacle
        d, nx, nz = _sdf_point(px, pz, circles, verts, pstart, pbound, radius + OBSTACLES_CONTACT)
        if d - radius <= OBSTACLES_CONTACT:
            vn = vel[i, 0] * nx + vel[i, 2] * nz
            if vn < 0.0:
                vel[i, 0] -= vn * nx
                vel[i, 2] -= vn * nz
        pos[i, 0] = px
        pos[i, 2] = pz


def sdf_numpy(obs: ObstacleSet, x, z):
    """Plain numpy reference of :meth:`ObstacleSet.sdf` (no early-out)."""
    x, z = np.asarray(x, np.float64), np.asarray(z, np.float64)
    best = np.full(x.shape, _FAR)
    bnx, bnz = np.zeros(x.shape), np.ones(x.shape)
    for cx, cz, r in obs.circles:
        dx, dz = x - cx, z - cz
        rr = np.hypot(dx, dz)
        d = rr - r
        ok = rr > OBSTACLES_EPS
        upd = d < best
        best = np.where(upd, d, best)
        bnx = np.where(upd, np.where(ok, dx / np.where(ok, rr, 1), 0.0), bnx)
        bnz = np.where(upd, np.where(ok, dz / np.where(ok, rr, 1), 1.0), bnz)
    for k in range(obs.pbound.shape[0]):
        p = obs.verts[obs.pstart[k]:obs.pstart[k + 1]]
        a, b = p, np.roll(p, -1, 0)
        u = b - a
        ll = (u ** 2).sum(1)
        t = np.clip(((x[:, None] - a[:, 0]) * u[:, 0] + (z[:, None] - a[:, 1]) * u[:, 1]) / ll, 0, 1)
        qx, qz = a[:, 0] + t * u[:, 0], a[:, 1] + t * u[:, 1]
        d2 = (x[:, None] - qx) ** 2 + (z[:, None] - qz) ** 2
        e = np.argmin(d2, 1)
        r = np.arange(x.size)
        dist = np.sqrt(d2[r, e])
        cross = (a[:, 1] > z[:, None]) != (b[:, 1] > z[:, None])
        xc = a[:, 0] + (z[:, None] - a[:, 1]) / np.where(cross, b[:, 1] - a[:, 1], 1) * u[:, 0]
        inside = (np.sum(cross & (x[:, None] < xc), 1) % 2) == 1
        d = np.where(inside, -dist, dist)
        sg = np.where(inside, -1.0, 1.0)
        ok = dist > OBSTACLES_EPS
        nx = np.where(ok, (x - qx[r, e]) / np.where(ok, dist, 1) * sg, 0.0)
        nz = np.where(ok, (z - qz[r, e]) / np.where(ok, dist, 1) * sg, 1.0)
        upd = d < best
        best, bnx, bnz = np.where(upd, d, best), np.where(upd, nx, bnx), np.where(upd, nz, bnz)
    return best, bnx, bnz


def steer_numpy(obs: ObstacleSet, pos, vel, radius, margin, lookahead, strength, w_slide, acc) -> None:
    """Plain numpy reference of ``_steer_kernel`` (adds to ``acc`` in place)."""
    for probe in range(2):
        qx = pos[:, 0] + (vel[:, 0] * lookahead if probe == 1 else 0.0)
        qz = pos[:, 2] + (vel[:, 2] * lookahead if probe == 1 else 0.0)
        d, nx, nz = sdf_numpy(obs, qx, qz)
        gap = d - radius
        f = np.where(gap < margin, strength * np.minimum((margin - gap) / margin, 2.0), 0.0)
        tx, tz = -nz, nx
        flip = tx * vel[:, 0] + tz * vel[:, 2] < 0.0
        tx, tz = np.where(flip, -tx, tx), np.where(flip, -tz, tz)
        acc[:, 0] += f * (nx + w_slide * tx)
        acc[:, 2] += f * (nz + w_slide * tz)


def project_numpy(obs: ObstacleSet, pos, vel, prev, radius) -> None:
    """Plain numpy reference of ``_project_kernel`` (in place; ``prev`` (n, 2) or None)."""
    px, pz = pos[:, 0].copy(), pos[:, 2].copy()
    if prev is not None:
        sx, sz = prev[:, 0], prev[:, 1]
        ux, uz = px - sx, pz - sz
        ll = np.hypot(ux, uz)
        d0, n0x, n0z = sdf_numpy(obs, sx, sz)
        trace = (ll > 0) & (d0 - radius > OBSTACLES_CCD_EPS)
        t = np.zeros_like(px)
        active = trace.copy()
        for _ in range(OBSTACLES_CCD_ITERATIONS):
            qx, qz = sx + t * ux, sz + t * uz
            d, _, _ = sdf_numpy(obs, qx, qz)
            gap = d - radius
            hit = active & (gap <= OBSTACLES_CCD_EPS)
            px, pz = np.where(hit, qx, px), np.where(hit, qz, pz)
            active &= ~hit
            t = np.where(active, t + gap / np.where(ll > 0, ll, 1.0), t)
            active &= t < 1.0
        un = ux * n0x + uz * n0z
        slide = ~trace & (ll > 0) & (d0 - radius <= OBSTACLES_CONTACT) & (un < 0)
        px = np.where(slide, sx + ux - un * n0x, px)
        pz = np.where(slide, sz + uz - un * n0z, pz)
    for _ in range(4):
        d, nx, nz = sdf_numpy(obs, px, pz)
        pen = radius - d
        on = pen > 0
        px, pz = np.where(on, px + nx * pen, px), np.where(on, pz + nz * pen, pz)
        vn = vel[:, 0] * nx + vel[:, 2] * nz
        cut = on & (vn < 0)
        vel[:, 0] = np.where(cut, vel[:, 0] - vn * nx, vel[:, 0])
        vel[:, 2] = np.where(cut, vel[:, 2] - vn * nz, vel[:, 2])
    d, nx, nz = sdf_numpy(obs, px, pz)
    vn = vel[:, 0] * nx + vel[:, 2] * nz
    cut = (d - radius <= OBSTACLES_CONTACT) & (vn < 0)
    vel[:, 0] = np.where(cut, vel[:, 0] - vn * nx, vel[:, 0])
    vel[:, 2] = np.where(cut, vel[:, 2] - vn * nz, vel[:, 2])
    pos[:, 0], pos[:, 2] = px, pz


# ----------------------------------------------------------------- effect
def install(world, cfg: dict) -> None:
    """Effect ``obstacles``: ``world.resources["obstacles"]`` = ObstacleSet;
    steps ``obstacles.record`` (before goals and boids: positions at the start
    of the step), ``obstacles.steer`` (before boids, if boids is installed) and
    ``obstacles.project`` (after boids, before terrain_follow and animation)."""
    obs = ObstacleSet.from_config(cfg)
    world.resources["obstacles"] = obs
    world.resources["obstacles.agent_radius"] = float(cfg.get("agent_radius", 0.4))  # read by avoidance.resolve
    r, m = float(cfg.get("agent_radius", 0.4)), float(cfg.get("margin", 2.0))
    la, s, ws = float(cfg.get("lookahead", 1.0)), float(cfg.get("strength", 8.0)), float(cfg.get("w_slide", 0.5))

    def steer(w, dt):
        if "boids" not in w.effects or obs.count == 0 or w.state.n == 0:
            return
        from sim.boids import external_accel

        acc = external_accel(w)
        _steer_kernel(w.state.position, w.state.velocity, obs.circles, obs.verts, obs.pstart, obs.pbound,
                      r, m, la, s, ws, acc)

    prev = {"xz": None}

    def record(w, dt):
        if obs.count == 0:
            return
        st = w.state
        if prev["xz"] is None or prev["xz"].shape != (st.n, 2):
            prev["xz"] = np.empty((st.n, 2), np.float64)
        prev["xz"][:, 0] = st.position[:, 0]
        prev["xz"][:, 1] = st.position[:, 2]

    def project(w, dt):
        if obs.count == 0 or w.state.n == 0:
            return
        p = prev["xz"]
        ok = p is not None and p.shape == (w.state.n, 2)
        _project_kernel(w.state.position, w.state.velocity, p if ok else np.zeros((1, 2)), ok,
                        obs.circles, obs.verts, obs.pstart, obs.pbound, r, polygon_boxes(obs.verts, obs.pstart))

    world.schedule.add_step("obstacles.record", record, before=("goals", "obstacles.steer", "boids"))
    world.schedule.add_step("obstacles.steer", steer, after=("goals",), before=("boids",))
    world.schedule.add_step("obstacles.project", project, after=("boids", "goals"),
                            before=("terrain_follow", "animation"))
