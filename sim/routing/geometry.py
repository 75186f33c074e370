"""Walkable geometry: the area agents may be in, its walls, the checks of shapes against it, and its raster.

The walkable area of a scene (effect ``routing``) is either the union of polygons with holes (``walkable``) or a
rectangle (``bounds``), minus every obstacle of the ``obstacles`` effect (circles, boxes, polygons, and so the
footprints of ``obstacle = true`` props). Polygons here are shapely geometries (GEOS); the raster that the fields
are marched on is computed by the numba kernels :func:`_inside_kernel` (even-odd scanline fill, exact on the
polygon's edges) and :func:`_wall_distance_kernel` (the distance of every node within ``reach`` of an edge to the
nearest edge), with :func:`raster_numpy` as their shapely reference.

Circles become polygons *circumscribing* them (:data:`CIRCLE_SEGMENTS` sides at ``r / cos(pi / n)``), so a node
outside the polygon is outside the circle: the routing never sends an agent through a circle's rim.

The outline of the walkable area is also a wall: :func:`wall_polygons` turns the frame (the area's bounding box
grown by a wall thickness) minus the area into simple polygons (no holes: the ``obstacles`` effect takes simple
polygons), which the scene loader adds to the ``obstacles`` effect, so the hard constraint, cfsm and orca see them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

#: sides of the polygon that circumscribes an obstacle circle
CIRCLE_SEGMENTS = 64


def circle_polygon(cx: float, cz: float, r: float, n: int = CIRCLE_SEGMENTS) -> np.ndarray:
    """(n, 2) float64 vertices of the regular n-gon circumscribing the circle (counter-clockwise)."""
    a = (np.arange(n) + 0.5) * (2.0 * math.pi / n)
    rr = r / math.cos(math.pi / n)
    return np.stack([cx + rr * np.cos(a), cz + rr * np.sin(a)], 1)


def polygon_problem(points, holes=()) -> str | None:
    """Why ``points`` (outer ring) with ``holes`` is not a valid polygon (one phrase), or None.

    Checks what GEOS checks (self-intersection, holes outside the shell or crossing it, nested holes, a split
    interior) and zero area; the phrase names the place, e.g. ``"intersects itself near (2, 3)"``."""
    import shapely
    from shapely.validation import explain_validity

    ring = np.asarray(points, np.float64)
    if ring.shape[0] < 3:
        return "has fewer than 3 points"
    if shapely.MultiPoint(ring).convex_hull.area <= 1e-12:  # all on one line (GEOS would call it self-crossing)
        return "has zero area"
    poly = shapely.Polygon(ring, [np.asarray(h, np.float64) for h in holes])
    why = explain_validity(poly)
    if why != "Valid Geometry":
        reason, _, where = why.partition("[")
        xy = where.rstrip("]").split()
        at = f" near ({float(xy[0]):g}, {float(xy[1]):g})" if len(xy) >= 2 else ""
        reason = reason.strip().lower()
        if "self-intersection" in reason:
            return f"intersects itself{at}"
        if "hole lies outside" in reason:
            return f"has a hole outside its outer ring{at}"
        if "nested" in reason:
            return f"has a hole inside another hole{at}"
        if "disconnected" in reason:
            return f"has holes that split its interior{at}"
        if "too few" in reason:
            return "has a ring with fewer than 3 distinct points"
        return f"is not a valid polygon ({reason}{at})"
    if poly.area <= 1e-12:
        return "has zero area"
    return None


def obstacle_geometry(obstacles: dict | None):
    """The union of the ``obstacles`` effect's shapes (``circles``, ``boxes``, ``polygons``) as one shapely
    geometry (empty without obstacles). Boxes turned by their yaw as :class:`sim.obstacles.ObstacleSet` does."""
    import shapely

    if not obstacles:
        return shapely.Polygon()
    from sim.obstacles import ObstacleSet

    obs = ObstacleSet(obstacles.get("circles", ()), obstacles.get("boxes", ()), obstacles.get("polygons", ()))
    parts = [shapely.Polygon(circle_polygon(x, z, r)) for x, z, r in obs.circles]
    for k in range(obs.pstart.shape[0] - 1):
        p = shapely.Polygon(obs.verts[obs.pstart[k]:obs.pstart[k + 1]])
        parts.append(p if p.is_valid else shapely.make_valid(p))
    return shapely.union_all(parts) if parts else shapely.Polygon()


@dataclass
class Walkable:
    """The walkable area (module docstring).

    outer : shapely geometry, the ``walkable`` polygons' union (or the ``bounds`` box) before obstacles
    obstacles : shapely geometry, the union of the obstacles
    area : shapely (Multi)Polygon, ``outer`` minus ``obstacles``
    """

    outer: object
    obstacles: object
    area: object

    @classmethod
    def from_config(cls, routing: dict, obstacles: dict | None = None) -> "Walkable":
        """From the ``routing`` effect's validated table (``walkable`` polygons or ``bounds``) and the
        ``obstacles`` effect's (None: no obstacles)."""
        import shapely

        if routing.get("walkable"):
            outer = shapely.union_all([shapely.Polygon(np.asarray(t["points"], np.float64),
                                                       [np.asarray(h, np.float64) for h in t.get("holes", [])])
                                       for t in routing["walkable"]])
        else:
            x0, z0, x1, z1 = routing["bounds"]
            outer = shapely.box(x0, z0, x1, z1)
        obs = obstacle_geometry(obstacles)
        area = outer.difference(obs) if not obs.is_empty else outer
        for g in (outer, area):
            shapely.prepare(g)  # point queries (agents, goals) in O(log edges)
        return cls(outer=outer, obstacles=obs, area=area)

    @property
    def bounds(self) -> tuple:
        """(x0, z0, x1, z1) of the area."""
        return tuple(float(v) for v in self.area.bounds)

    def rings(self) -> list:
        """Every ring (exterior and holes) of the area's polygons as (m, 2) float64 arrays (not closed)."""
        out = []
        for poly in getattr(self.area, "geoms", [self.area]):
            if poly.is_empty or poly.geom_type != "Polygon":
                continue
            for ring in [poly.exterior, *poly.interiors]:
                out.append(np.asarray(ring.coords, np.float64)[:-1])
        return out

    def where(self, xz) -> np.ndarray:
        """(m,) int8 per point: 0 inside the area (or on its boundary), 1 outside the walkable polygons (or
        bounds), 2 inside an obstacle."""
        import shapely

        xz = np.asarray(xz, np.float64).reshape(-1, 2)
        out = np.zeros(xz.shape[0], np.int8)
        inside = shapely.intersects_xy(self.area, xz[:, 0], xz[:, 1])
        if not inside.all():
            rest = ~inside
            in_outer = shapely.intersects_xy(self.outer, xz[rest, 0], xz[rest, 1])
            out[rest] = np.where(in_outer, 2, 1)
        return out


def describe_where(code: int) -> str:
    """The phrase of a :meth:`Walkable.where` code."""
    return {1: "lies outside the walkable area", 2: "lies inside an obstacle"}.get(int(code), "")


def shape_problem(walkable: Walkable, shape) -> str | None:
    """Why a goal/stage shape cannot be used in this walkable area (one phrase), or None.

    shape : ``("point", (x, z))`` | ``("line", ((x1, z1), (x2, z2)))`` | ``("polygon", [(x, z), ...])``.
    A point must lie in the area; a line must have a length and a part of positive length in the area; a polygon
    must be valid (:func:`polygon_problem`), of non-zero area, and overlap the area. The zero-width line is named
    as such (an exit or a waiting line nobody can cross)."""
    import shapely

    kind, geom = shape
    if kind == "point":
        code = walkable.where([geom])[0]
        return describe_where(code) if code else None
    if kind == "line":
        (x1, z1), (x2, z2) = geom
        if math.hypot(x2 - x1, z2 - z1) <= 1e-9:
            return "has zero width (its two ends coincide)"
        line = shapely.LineString([(x1, z1), (x2, z2)])
        if walkable.area.intersection(line).length <= 1e-9:
            mid = walkable.where([((x1 + x2) / 2, (z1 + z2) / 2)])[0]
            return "lies inside an obstacle" if mid == 2 else "lies outside the walkable area"
        return None
    if kind == "polygon":
        why = polygon_problem(geom)
        if why:
            return why
        poly = shapely.Polygon(np.asarray(geom, np.float64))
        if walkable.area.intersection(poly).area <= 1e-12:
            c = poly.representative_point()
            code = walkable.where([(c.x, c.y)])[0]
            return "lies inside an obstacle" if code == 2 else "lies outside the walkable area"
        return None
    return f"unknown shape kind {kind!r}; accepted: 'point', 'line', 'polygon'"


# -------------------------------------------------------------------------------------------------------- walls
def _split_holes(poly, out: list) -> None:
    """Cut ``poly`` by vertical lines through its holes until no piece has a hole; append the pieces."""
    import shapely

    if poly.is_empty or poly.area <= 1e-12:
        return
    if poly.geom_type == "MultiPolygon" or poly.geom_type == "GeometryCollection":
        for g in poly.geoms:
            _split_holes(g, out)
        return
    if poly.geom_type != "Polygon":
        return
    if not poly.interiors:
        out.append(poly)
        return
    hole = poly.interiors[0]
    hx = float(np.mean(np.asarray(hole.coords)[:-1, 0]))
    x0, z0, x1, z1 = poly.bounds
    left = shapely.box(x0 - 1.0, z0 - 1.0, hx, z1 + 1.0)
    right = shapely.box(hx, z0 - 1.0, x1 + 1.0, z1 + 1.0)
    for half in (left, right):
        _split_holes(poly.intersection(half), out)


def wall_polygons(walkable: Walkable, thickness: float) -> list:
    """The walls around and inside the walkable polygons (module docstring): simple polygons as lists of
    [x, z], the frame (``outer``'s bounding box grown by ``thickness``) minus ``outer``. Obstacles are not
    repeated (they are obstacles already)."""
    import shapely

    x0, z0, x1, z1 = walkable.outer.bounds
    frame = shapely.box(x0 - thickness, z0 - thickness, x1 + thickness, z1 + thickness)
    pieces: list = []
    _split_holes(shapely.make_valid(frame.difference(walkable.outer)), pieces)
    out = []
    for p in pieces:
        p = p.simplify(0.0)  # drop collinear vertices left by the cuts
        ring = np.asarray(p.exterior.coords, np.float64)[:-1]
        if ring.shape[0] >= 3 and p.area > 1e-9:
            out.append(ring.tolist())
    return out


# ------------------------------------------------------------------------------------------------------- raster
@njit(cache=True, parallel=True)
def _inside_kernel(ex0, ez0, ex1, ez1, x0, z0, h, nx, nz, inside):
    """Even-odd scanline fill: node (i, j) at (x0 + i h, z0 + j h) is inside when a ray towards +x crosses an odd
    number of the edges (ex0, ez0) -> (ex1, ez1) (half-open in z, so a vertex on the row counts once)."""
    ne = ex0.shape[0]
    for j in prange(nz):
        z = z0 + j * h
        xs = np.empty(ne, np.float64)
        m = 0
        for e in range(ne):
            a, b = ez0[e], ez1[e]
            if (a > z) != (b > z):
                xs[m] = ex0[e] + (z - a) / (b - a) * (ex1[e] - ex0[e])
                m += 1
        xs_s = np.sort(xs[:m])
        for q in range(0, m - 1, 2):
            lo = int(math.ceil((xs_s[q] - x0) / h))
            hi = int(math.floor((xs_s[q + 1] - x0) / h))
            # a node exactly on a crossing is inside (the boundary belongs to the area)
            for i in range(max(lo, 0), min(hi, nx - 1) + 1):
                inside[j, i] = True


@njit(cache=True)
def _wall_distance_kernel(ex0, ez0, ex1, ez1, x0, z0, h, nx, nz, reach, dist):
    """dist[j, i] = min(dist, distance of the node to each edge) for the nodes within ``reach`` of it."""
    for e in range(ex0.shape[0]):
        ax, az, bx, bz = ex0[e], ez0[e], ex1[e], ez1[e]
        i0 = max(int(math.floor((min(ax, bx) - reach - x0) / h)), 0)
        i1 = min(int(math.ceil((max(ax, bx) + reach - x0) / h)), nx - 1)
        j0 = max(int(math.floor((min(az, bz) - reach - z0) / h)), 0)
        j1 = min(int(math.ceil((max(az, bz) + reach - z0) / h)), nz - 1)
        ux, uz = bx - ax, bz - az
        ll = ux * ux + uz * uz
        for j in range(j0, j1 + 1):
            pz = z0 + j * h
            for i in range(i0, i1 + 1):
                px = x0 + i * h
                t = ((px - ax) * ux + (pz - az) * uz) / ll if ll > 0.0 else 0.0
                t = min(max(t, 0.0), 1.0)
                dx, dz = px - (ax + t * ux), pz - (az + t * uz)
                d = math.sqrt(dx * dx + dz * dz)
                if d < dist[j, i]:
                    dist[j, i] = d


def edges_of(rings: list) -> tuple:
    """(ex0, ez0, ex1, ez1) float64 arrays of every edge of the rings."""
    if not rings:
        z = np.zeros(0)
        return z, z, z, z
    a = np.concatenate(rings, 0)
    b = np.concatenate([np.roll(r, -1, 0) for r in rings], 0)
    return (np.ascontiguousarray(a[:, 0]), np.ascontiguousarray(a[:, 1]), np.ascontiguousarray(b[:, 0]),
            np.ascontiguousarray(b[:, 1]))


def raster(walkable: Walkable, x0: float, z0: float, h: float, nx: int, nz: int, reach: float) -> tuple:
    """(inside (nz, nx) bool, wall (nz, nx) float64): nodes in the area, and every node's distance to the area's
    boundary where it is below ``reach`` (inf elsewhere)."""
    ex0, ez0, ex1, ez1 = edges_of(walkable.rings())
    inside = np.zeros((nz, nx), np.bool_)
    wall = np.full((nz, nx), np.inf)
    if ex0.size:
        _inside_kernel(ex0, ez0, ex1, ez1, float(x0), float(z0), float(h), nx, nz, inside)
        _wall_distance_kernel(ex0, ez0, ex1, ez1, float(x0), float(z0), float(h), nx, nz, float(reach), wall)
    return inside, wall


def raster_numpy(walkable: Walkable, x0: float, z0: float, h: float, nx: int, nz: int, reach: float) -> tuple:
    """Shapely reference of :func:`raster` (``intersects_xy`` and ``distance`` to the boundary)."""
    import shapely

    X, Z = np.meshgrid(x0 + np.arange(nx) * h, z0 + np.arange(nz) * h)
    inside = shapely.intersects_xy(walkable.area, X.ravel(), Z.ravel()).reshape(nz, nx)
    d = shapely.distance(walkable.area.boundary, shapely.points(X.ravel(), Z.ravel())).reshape(nz, nx)
    wall = np.where(d < reach, d, np.inf)
    return inside, wall
