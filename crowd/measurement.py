"""``[[measurement]]`` tables of a scene: named measurement areas (polygons) and lines on the floor.

A measurement is where ``crowd report`` measures the pedestrian quantities of a run with PedPy
(:mod:`crowd.report.pedestrian`): density, speed and the fundamental diagram inside a polygon, the
N-t curve and flow across a line. Coordinates are floor coordinates ``[x, z]`` of the sandbox (Y up),
which are PedPy's ``(x, y)`` (:mod:`crowd.trajectories`).

Validation (one-line errors, before anything is built): ``name`` is a unique non-empty string; at least one of
``polygon`` / ``line``; a polygon has >= 3 finite points, non-zero area and is simple (no two edges cross or
touch except neighbours at their shared corner; a repeated closing point is accepted and dropped); a line has
exactly two distinct finite points.

Pure Python (no shapely): the scene loader must not need the report's optional dependencies.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from sim.params import Param, ParamError, validate

MEASUREMENT_SCHEMA = {
    "name": Param("str", doc="unique name, shown in the report"),
    "polygon": Param("list", None, doc="measurement area [[x, z], ...], >= 3 points, simple, non-zero area"),
    "line": Param("list", None, doc="measurement line [[x1, z1], [x2, z2]], two distinct points"),
}


@dataclass(frozen=True)
class MeasurementSpec:
    """One ``[[measurement]]`` table.

    polygon : tuple of (x, z) float tuples (open ring, counter-clockwise or not) or None
    line : ((x1, z1), (x2, z2)) or None
    """

    name: str
    polygon: tuple | None = None
    line: tuple | None = None
    index: int = 0


def _points(key: str, value) -> list:
    if not isinstance(value, list):
        raise ParamError(key, f"expected a list of [x, z] points, got {value!r}")
    return [tuple(Param("vec2").check(f"{key}[{i}]", p)) for i, p in enumerate(value)]


def polygon_area(pts) -> float:
    """Signed area (shoelace) of the ring ``pts`` [(x, z), ...], positive counter-clockwise in (x, z)."""
    n = len(pts)
    x0, z0 = pts[0]  # relative to the first point: exact far from the origin
    s = 0.0
    for i in range(n):
        ax, az = pts[i][0] - x0, pts[i][1] - z0
        bx, bz = pts[(i + 1) % n][0] - x0, pts[(i + 1) % n][1] - z0
        s += ax * bz - bx * az
    return 0.5 * s


def _orient(a, b, c) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _on_segment(a, b, c) -> bool:
    """c (collinear with a, b) lies within the bounding box of segment ab."""
    return min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(a[1], b[1])


def segments_intersect(a, b, c, d) -> bool:
    """Closed segments ab and cd share a point (touching and collinear overlap count)."""
    o1, o2, o3, o4 = _orient(a, b, c), _orient(a, b, d), _orient(c, d, a), _orient(c, d, b)
    if ((o1 > 0 > o2) or (o1 < 0 < o2)) and ((o3 > 0 > o4) or (o3 < 0 < o4)):
        return True
    return ((o1 == 0 and _on_segment(a, b, c)) or (o2 == 0 and _on_segment(a, b, d))
            or (o3 == 0 and _on_segment(c, d, a)) or (o4 == 0 and _on_segment(c, d, b)))


def collinear(pts) -> bool:
    """All points of ``pts`` on one line (or all equal)."""
    a = pts[0]
    b = next((q for q in pts if q != a), None)
    return b is None or all(_orient(a, b, c) == 0 for c in pts)


def simple_polygon_problem(pts) -> str | None:
    """None when the ring ``pts`` is a simple polygon, else what is wrong (a phrase).

    O(n^2) edge pairs: measurement polygons have a handful of corners."""
    n = len(pts)
    x0, z0 = pts[0]
    p = [(x - x0, z - z0) for x, z in pts]
    for i in range(n):
        if p[i] == p[(i + 1) % n]:
            return f"points {i} and {(i + 1) % n} coincide"
    for i in range(n):
        a, b = p[i], p[(i + 1) % n]
        for j in range(i + 1, n):
            c, d = p[j], p[(j + 1) % n]
            if j == i + 1 or (i == 0 and j == n - 1):  # neighbours share one corner: only overlap is wrong
                shared = b if j == i + 1 else a
                other_e = d if j == i + 1 else c
                other_s = a if j == i + 1 else b
                if _orient(other_s, shared, other_e) == 0 and (
                        _on_segment(other_s, shared, other_e) or _on_segment(shared, other_e, other_s)):
                    return f"edges {i} and {j} fold back on each other"
                continue
            if segments_intersect(a, b, c, d):
                return f"edges {i} and {j} cross or touch"
    return None


def parse_polygon(key: str, value, fail) -> tuple:
    """A validated floor polygon ``[[x, z], ...]`` (>= 3 finite points, simple, non-zero area; a repeated closing
    point is dropped) as a tuple of (x, z), else ``fail(key, message)``."""
    try:
        pts = _points(key, value)
    except ParamError as e:
        fail(e.key, e.message)
    if len(pts) >= 4 and pts[0] == pts[-1]:
        pts = pts[:-1]  # a closed ring written out
    if len(pts) < 3:
        fail(key, f"expected at least 3 [x, z] points, got {len(pts)}")
    if collinear(pts):
        fail(key, "expected a polygon of non-zero area, got collinear points")
    problem = simple_polygon_problem(pts)
    if problem is not None:
        fail(key, f"expected a simple polygon (edges meet only at shared corners): {problem}")
    area = polygon_area(pts)
    if not (abs(area) > 0.0) or not math.isfinite(area):
        fail(key, "expected a polygon of non-zero area, got collinear points")
    return tuple(pts)


def parse_line(key: str, value, fail, what: str = "expected two distinct points") -> tuple:
    """A validated floor segment ``[[x1, z1], [x2, z2]]`` (two distinct finite points), else ``fail(key, ...)``;
    ``what`` words the complaint about coincident points."""
    try:
        pts = _points(key, value)
    except ParamError as e:
        fail(e.key, e.message)
    if len(pts) != 2:
        fail(key, f"expected two [x, z] points, got {len(pts)}")
    if pts[0] == pts[1]:
        fail(key, f"{what}, got {list(pts[0])} twice")
    return tuple(pts)


def parse_measurements(doc_value, fail) -> tuple:
    """Validate the ``measurement`` array of tables of a scene document.

    Parameters
    ----------
    doc_value : the parsed TOML value of ``measurement`` (None when absent)
    fail : callable(key, message) raising the scene's one-line error

    Returns
    -------
    tuple of MeasurementSpec
    """
    if doc_value is None:
        return ()
    if not isinstance(doc_value, list) or not all(isinstance(t, dict) for t in doc_value):
        fail("measurement", f"expected an array of tables [[measurement]], got {doc_value!r}")
    out, names = [], {}
    for i, t in enumerate(doc_value):
        where = f"measurement[{i}]"
        m = validate(MEASUREMENT_SCHEMA, t, where)
        name = m["name"].strip()
        if not name:
            fail(f"{where}.name", "expected a non-empty string")
        if name in names:
            fail(f"{where}.name", f"duplicate measurement name {name!r} (also measurement[{names[name]}])")
        names[name] = i
        if m["polygon"] is None and m["line"] is None:
            fail(where, "expected `polygon` (a measurement area [[x, z], ...]) and/or `line` ([[x1, z1], [x2, z2]])")
        polygon = parse_polygon(f"{where}.polygon", m["polygon"], fail) if m["polygon"] is not None else None
        line = parse_line(f"{where}.line", m["line"], fail) if m["line"] is not None else None
        out.append(MeasurementSpec(name=name, polygon=polygon, line=line, index=i))
    return tuple(out)
