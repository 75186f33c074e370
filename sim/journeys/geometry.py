"""Floor shapes of the journeys: points, polygons, lines (door segments) as flat arrays.

A :class:`Shapes` table holds every shape a scene's stages and sources use; shape ``k`` is
``kind[k]`` (:data:`POINT`, :data:`POLYGON`, :data:`LINE`) with the vertices ``verts[start[k]:start[k + 1]]``
((x, z) floor coordinates). The per-agent queries are numba kernels over ``(shape id, position)`` beside
plain numpy/Python references the tests compare with:

- :func:`nearest` : the nearest point of the shape (a polygon's boundary, a segment) and whether the
  position lies inside (polygons: crossing number; a point on the boundary counts as inside);
- :func:`crossed` : the move ``p0 -> p1`` crosses the segment ``a b`` (PedPy's definition: a move ending
  on the line does not cross, one starting on it does).

Coordinates are differenced before they are multiplied, so shapes far from the origin keep their precision.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

POINT, POLYGON, LINE = 0, 1, 2
KIND_NAMES = {"point": POINT, "polygon": POLYGON, "line": LINE}


class Shapes:
    """Shapes back to back: ``kind`` (S,) int64, ``start`` (S + 1,) int64, ``verts`` (V, 2) float64."""

    def __init__(self):
        self._kinds: list = []
        self._verts: list = []
        self._keys: dict = {}

    def add(self, kind: str, points) -> int:
        """The id of shape (``kind``, ``points``); an equal shape added before keeps its id."""
        pts = np.asarray(points, np.float64).reshape(-1, 2)
        key = (kind, pts.tobytes())
        k = self._keys.get(key)
        if k is None:
            k = self._keys[key] = len(self._kinds)
            self._kinds.append(KIND_NAMES[kind])
            self._verts.append(pts)
        return k

    def arrays(self) -> tuple:
        kind = np.asarray(self._kinds, np.int64)
        start = np.zeros(len(self._verts) + 1, np.int64)
        start[1:] = np.cumsum([v.shape[0] for v in self._verts]) if self._verts else []
        verts = np.concatenate(self._verts, 0) if self._verts else np.zeros((0, 2))
        return kind, start, np.ascontiguousarray(verts, np.float64)

    def shape(self, k: int) -> tuple:
        """(kind name, (m, 2) points) of shape ``k``."""
        names = {v: n for n, v in KIND_NAMES.items()}
        return names[self._kinds[k]], self._verts[k]

    def __len__(self) -> int:
        return len(self._kinds)


# ------------------------------------------------------------------------------------------------ kernels
@njit(cache=True, inline="always")
def _seg_nearest(px, pz, ax, az, bx, bz):
    """Nearest point of segment ab to p: (qx, qz, squared distance); a degenerate segment is its point."""
    ex, ez = bx - ax, bz - az
    wx, wz = px - ax, pz - az
    ll = ex * ex + ez * ez
    t = 0.0
    if ll > 0.0:
        t = (wx * ex + wz * ez) / ll
        t = min(1.0, max(0.0, t))
    qx, qz = ax + t * ex, az + t * ez
    dx, dz = px - qx, pz - qz
    return qx, qz, dx * dx + dz * dz


@njit(cache=True)
def nearest_one(kind, start, verts, k, px, pz):
    """(qx, qz, inside) of shape ``k`` at (px, pz) (module docstring)."""
    a, b = start[k], start[k + 1]
    if kind[k] == POINT:
        return verts[a, 0], verts[a, 1], False
    if kind[k] == LINE:
        qx, qz, _ = _seg_nearest(px, pz, verts[a, 0], verts[a, 1], verts[a + 1, 0], verts[a + 1, 1])
        return qx, qz, False
    best, bx, bz = 1e300, 0.0, 0.0
    inside = False
    m = b - a
    for i in range(m):
        x0, z0 = verts[a + i, 0], verts[a + i, 1]
        x1, z1 = verts[a + (i + 1) % m, 0], verts[a + (i + 1) % m, 1]
        qx, qz, d2 = _seg_nearest(px, pz, x0, z0, x1, z1)
        if d2 < best:
            best, bx, bz = d2, qx, qz
        if (z0 > pz) != (z1 > pz):  # crossing number, relative coordinates
            xi = (x0 - px) + (pz - z0) * (x1 - x0) / (z1 - z0)
            if xi > 0.0:
                inside = not inside
    return bx, bz, inside or best == 0.0


@njit(cache=True)
def nearest(kind, start, verts, shape, px, pz, qx, qz, inside):
    """:func:`nearest_one` for every agent: shape (n,) int64 (-1: none, q = p, not inside)."""
    for i in range(px.shape[0]):
        k = shape[i]
        if k < 0:
            qx[i], qz[i], inside[i] = px[i], pz[i], False
            continue
        qx[i], qz[i], inside[i] = nearest_one(kind, start, verts, k, px[i], pz[i])


@njit(cache=True, inline="always")
def _side(ax, az, bx, bz, px, pz):
    return (bx - ax) * (pz - az) - (bz - az) * (px - ax)


@njit(cache=True)
def crossed_one(p0x, p0z, p1x, p1z, ax, az, bx, bz):
    """The move p0 -> p1 crosses segment ab: p0 on the line or strictly on one side, p1 strictly on the
    other, and the crossing point within the segment (PedPy's ``compute_crossing_frames``)."""
    s0 = _side(ax, az, bx, bz, p0x, p0z)
    s1 = _side(ax, az, bx, bz, p1x, p1z)
    if s1 == 0.0 or (s0 > 0.0 and s1 > 0.0) or (s0 < 0.0 and s1 < 0.0):
        return False
    t0 = _side(p0x, p0z, p1x, p1z, ax, az)
    t1 = _side(p0x, p0z, p1x, p1z, bx, bz)
    return not ((t0 > 0.0 and t1 > 0.0) or (t0 < 0.0 and t1 < 0.0))


@njit(cache=True)
def reached_exit(idx, stage, polygon, line, kind, start, verts, prev, pos, hit):
    """Agents ``idx`` at exit stages: ``hit[j]`` when agent ``idx[j]`` is inside its stage's exit polygon
    (``polygon[s]`` a shape id, -1 for a door) or its move ``prev -> pos`` crossed the door ``line[s]``
    ((x1, z1, x2, z2)); ``prev`` (n, 2) floor, ``pos`` (n, 3)."""
    for j in range(idx.shape[0]):
        i = idx[j]
        s = stage[i]
        if polygon[s] >= 0:
            hit[j] = nearest_one(kind, start, verts, polygon[s], pos[i, 0], pos[i, 2])[2]
        else:
            hit[j] = crossed_one(prev[i, 0], prev[i, 1], pos[i, 0], pos[i, 2], line[s, 0], line[s, 1], line[s, 2],
                                 line[s, 3])


# ------------------------------------------------------------------------------------------- references
def nearest_reference(points: np.ndarray, kind: str, p) -> tuple:
    """Plain Python reference of :func:`nearest_one` for one shape ``points`` (m, 2) and point p."""
    px, pz = float(p[0]), float(p[1])
    if kind == "point":
        return float(points[0, 0]), float(points[0, 1]), False

    def seg(a, b):
        ex, ez = b[0] - a[0], b[1] - a[1]
        ll = ex * ex + ez * ez
        t = 0.0 if ll == 0 else min(1.0, max(0.0, ((px - a[0]) * ex + (pz - a[1]) * ez) / ll))
        q = (a[0] + t * ex, a[1] + t * ez)
        return q, math.hypot(px - q[0], pz - q[1])

    if kind == "line":
        q, _ = seg(points[0], points[1])
        return q[0], q[1], False
    m = len(points)
    cands = [seg(points[i], points[(i + 1) % m]) for i in range(m)]
    q, d = min(cands, key=lambda c: c[1])
    inside = False
    for i in range(m):
        (x0, z0), (x1, z1) = points[i], points[(i + 1) % m]
        if (z0 > pz) != (z1 > pz) and px < x0 + (pz - z0) * (x1 - x0) / (z1 - z0):
            inside = not inside
    return q[0], q[1], inside or d == 0.0


def sample_polygon(points: np.ndarray, rng: np.random.Generator, k: int) -> np.ndarray:
    """(k, 2) points uniform in polygon ``points`` (rejection in its bounding box; a polygon covering under
    1e-6 of its box returns what it found)."""
    points = np.asarray(points, np.float64)
    lo, hi = points.min(0), points.max(0)
    kind = np.array([POLYGON])
    start = np.array([0, points.shape[0]])
    out, have = [], 0
    for _ in range(1000):
        if have >= k:
            break
        c = lo + (hi - lo) * rng.random((max(4 * k, 16), 2))
        m = c.shape[0]
        qx, qz, inside = np.empty(m), np.empty(m), np.empty(m, np.bool_)
        nearest(kind, start, points, np.zeros(m, np.int64), np.ascontiguousarray(c[:, 0]),
                np.ascontiguousarray(c[:, 1]), qx, qz, inside)
        out.append(c[inside][:k - have])
        have += out[-1].shape[0]
    return np.concatenate(out, 0) if out else np.zeros((0, 2))


def grid_in_polygon(points: np.ndarray, spacing: float) -> np.ndarray:
    """(m, 2) points of a square lattice of ``spacing`` inside polygon ``points``, at least spacing / 2 from
    its boundary, in rows of increasing z then x (waiting-area slots)."""
    points = np.asarray(points, np.float64)
    lo, hi = points.min(0), points.max(0)
    xs = np.arange(lo[0] + spacing / 2, hi[0], spacing)
    zs = np.arange(lo[1] + spacing / 2, hi[1], spacing)
    kind, start = np.array([POLYGON]), np.array([0, points.shape[0]])
    out = []
    for z in zs:
        for x in xs:
            qx, qz, inside = nearest_one(kind, start, points, 0, x, z)
            if inside and math.hypot(x - qx, z - qz) >= spacing / 2 - 1e-9:
                out.append((x, z))
    return np.asarray(out, np.float64).reshape(-1, 2)


def polyline_slots(points: np.ndarray, spacing: float, count: int | None = None) -> np.ndarray:
    """(m, 2) points every ``spacing`` metres along the polyline ``points`` from its first point (queue slots:
    slot 0 is the head); ``count`` caps m."""
    points = np.asarray(points, np.float64)
    seg = np.diff(points, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    total = float(length.sum())
    m = int(math.floor(total / spacing + 1e-9)) + 1
    if count is not None:
        m = min(m, int(count))
    s = np.arange(m) * spacing
    cum = np.concatenate([[0.0], np.cumsum(length)])
    j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(length) - 1)
    t = np.where(length[j] > 0, (s - cum[j]) / np.where(length[j] > 0, length[j], 1.0), 0.0)
    return points[j] + seg[j] * t[:, None]
