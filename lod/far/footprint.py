"""A character's far footprint: what one pre-filtered splat must carry to stand for the whole agent
(issue 45's far tier), measured from the character at build.

Wand & Straßer 2002 stop refining where a node's samples project within a pixel (§3.2) and give every
representative sample the filtered attributes of the surface it stands for (§3.5). An agent whose whole
body projects within a pixel or two is the limit case: one sample for the whole agent, whose attributes
are the mean of what the agent shows from that side. What a pixel of the full-detail frame receives from
such an agent (box-filtered) is its *covered area* (the silhouette's area over the pixel's) times the
*mean lit colour* of its visible surface. Both depend on the side it is seen from and, for the colour,
on where the light is; neither is a sum over the surface (the far side and the parts behind the arms do
not count), so they are measured by drawing the character:

* Views. Directions ``d`` from the character to the viewer in its own frame (heading removed: +Z is
  forward, +Y up), on a grid of :data:`VIEW_AZIMUTHS` azimuths (periodic) by :data:`VIEW_ELEVATIONS`
  elevations from -90 to +90 degrees; the renderer interpolates between them.
* Poses. :data:`POSES` poses spread evenly over the clip (its baked rows, or its keyframes); each view's
  figures are the mean over them, so a crowd of agents at every phase of the clip gets its mean.
* Drawing. An orthographic z-buffer of the posed triangles (:func:`gbuffer`, numba, one pixel centre
  test per pixel like a rasteriser's) at :data:`RESOLUTION` pixels across the posed mesh's bounding
  sphere, keeping per pixel the nearest triangle's interpolated base colour and normal (the surface
  the renderer lights, ``render/shaders/world/light.glsl``).
* Figures per view: ``area`` (m^2 at scale 1, covered pixels times their area; the mean over the poses),
  ``ambient`` (mean base colour over the covered pixels of all poses: what the ambient term multiplies),
  ``head`` (mean of base x |n . d|, the renderer's headlight term) and ``direct`` (mean of base x |n . l| for each light direction l of a
  grid of :data:`LIGHT_AZIMUTHS` x :data:`LIGHT_ELEVATIONS` directions in the character's frame: the
  scene's light, fixed in the world, turns in the agent's frame with its heading). The renderer's lit
  colour is ``base (ambient + 0.35 |n . head| + 0.55 light |n . l|)``, so the mean lit colour of the
  view is ``a ambient + 0.35 head + 0.55 light direct(l)`` without another draw. And ``ground``: the share of
  each of :data:`RINGS` floor rings about the rest pose's floor point that the body leaves in view (points on
  the ring tested against the z-buffer): the renderer weighs a blob shadow's opacity with it. And the varied
  part's share, its lighting sums (mask x |n . d|, mask x |n . l|) and its mean base colour, from which the
  renderer turns an agent's variation word into a change of the mean colour.

Departures: normals of skinned poses are the rest normals through each vertex's blended matrix
(morph-target normal deltas are left out); the shadow map's visibility is taken as 1 (a far agent in
a building's shadow keeps its sunlit colour); an agent's colour variation (``lod.variation``, which changes the
base colour of the vertices its mask marks) changes the varied part's *mean* base colour, lit with that part's
own lighting sums (``varied``, ``varied_base``): exact where the varied part has one colour (a palette word, or
a uniformly coloured garment), an approximation of the mean of varied colours where it has several.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

#: version of the measurement (part of a cache key)
FOOTPRINT_FORMAT = 3  # 2: the floor rings' visibility (ground shadows); 3: the varied part
#: view grid: azimuths over a full turn (the first faces the character's front, +Z) and elevations from
#: -90 to +90 degrees (both poles included)
VIEW_AZIMUTHS = 16
VIEW_ELEVATIONS = 9
#: light grid in the character's frame (same layout as the views')
LIGHT_AZIMUTHS = 16
LIGHT_ELEVATIONS = 9
#: poses measured per clip (spread evenly over it; their mean is the table)
POSES = 6
#: pixels across the bounding sphere of a pose in the orthographic drawing (a humanoid covers ~15 % of
#: them: ~600 pixels per view, the area within ~1 %)
RESOLUTION = 64
#: rings of the floor around the agent whose visibility past the agent's own body is measured (the share of a
#: ground shadow under it that the viewer sees), out to RING_EXTENT x the rest pose's height, and the points
#: tested on each ring
RINGS = 8
RING_EXTENT = 0.5
RING_POINTS = 48


def grid_directions(azimuths: int, elevations: int) -> np.ndarray:
    """(elevations, azimuths, 3) unit directions: azimuth ``2 pi k / azimuths`` about +Y from +Z towards
    +X, elevation ``-90 + 180 j / (elevations - 1)`` degrees."""
    az = 2.0 * np.pi * np.arange(azimuths) / azimuths
    el = np.radians(np.linspace(-90.0, 90.0, elevations))
    ce, se = np.cos(el)[:, None], np.sin(el)[:, None]
    d = np.stack([ce * np.sin(az)[None, :], np.broadcast_to(se, (elevations, azimuths)),
                  ce * np.cos(az)[None, :]], axis=-1)
    return d


def _basis(d: np.ndarray) -> np.ndarray:
    """(3, 3) rows right, up, d of an orthographic view looking along -d."""
    up = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.99 else np.array([0.0, 0.0, 1.0])
    right = np.cross(up, d)
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(d, right), d])


@njit(cache=True)
def _raster_one(P, idx, basis, centre, half, res, zbuf, tri, b1, b2):  # pragma: no cover - compiled
    """Nearest triangle (and barycentrics of its vertices 1, 2) at every pixel centre of one view."""
    pix = 2.0 * half / res
    for i in range(res * res):
        zbuf[i] = -np.inf
        tri[i] = -1
    for t in range(idx.shape[0]):
        xs = np.empty(3)
        ys = np.empty(3)
        zs = np.empty(3)
        for k in range(3):
            v = idx[t, k]
            q0 = P[v, 0] - centre[0]
            q1 = P[v, 1] - centre[1]
            q2 = P[v, 2] - centre[2]
            xs[k] = ((basis[0, 0] * q0 + basis[0, 1] * q1 + basis[0, 2] * q2) + half) / pix
            ys[k] = ((basis[1, 0] * q0 + basis[1, 1] * q1 + basis[1, 2] * q2) + half) / pix
            zs[k] = basis[2, 0] * q0 + basis[2, 1] * q1 + basis[2, 2] * q2
        den = (ys[1] - ys[2]) * (xs[0] - xs[2]) + (xs[2] - xs[1]) * (ys[0] - ys[2])
        if not abs(den) > 1e-12:
            continue  # degenerate in this view: covers no pixel centre
        x0 = max(int(np.floor(min(xs[0], min(xs[1], xs[2])) - 0.5)), 0)
        x1 = min(int(np.ceil(max(xs[0], max(xs[1], xs[2])) - 0.5)), res - 1)
        y0 = max(int(np.floor(min(ys[0], min(ys[1], ys[2])) - 0.5)), 0)
        y1 = min(int(np.ceil(max(ys[0], max(ys[1], ys[2])) - 0.5)), res - 1)
        for py in range(y0, y1 + 1):
            cy = py + 0.5
            for px in range(x0, x1 + 1):
                cx = px + 0.5
                l0 = ((ys[1] - ys[2]) * (cx - xs[2]) + (xs[2] - xs[1]) * (cy - ys[2])) / den
                l1 = ((ys[2] - ys[0]) * (cx - xs[2]) + (xs[0] - xs[2]) * (cy - ys[2])) / den
                l2 = 1.0 - l0 - l1
                if l0 < 0.0 or l1 < 0.0 or l2 < 0.0:
                    continue
                z = l0 * zs[0] + l1 * zs[1] + l2 * zs[2]
                j = py * res + px
                if z > zbuf[j]:
                    zbuf[j] = z
                    tri[j] = t
                    b1[j] = l1
                    b2[j] = l2


@njit(cache=True, parallel=True)
def _views_kernel(P, Nrm, C, idx, bases, centre, half, res, lights, area, ambient, head, direct, floor, rings,
                  ground, varied, varied_base):  # pragma: no cover - compiled
    """Figures of every view (see the module docstring), added into the output rows of the view; ``ground``
    (views, rings): the share of each floor ring (radius ``rings[k]`` about ``floor``) no triangle hides;
    ``varied`` (views, 2 + lights): the varied part's sums of mask, mask x |n . d| and mask x |n . l|;
    ``varied_base`` (views, 3): its sum of mask x base colour."""
    V = bases.shape[0]
    L = lights.shape[0]
    pix_area = (2.0 * half / res) ** 2
    for v in prange(V):
        zbuf = np.empty(res * res)
        tri = np.empty(res * res, np.int64)
        b1 = np.empty(res * res)
        b2 = np.empty(res * res)
        _raster_one(P, idx, bases[v], centre, half, res, zbuf, tri, b1, b2)
        n = 0
        s_amb = np.zeros(3)
        s_head = np.zeros(3)
        s_dir = np.zeros((L, 3))
        s_var = np.zeros(2 + L)
        s_vbase = np.zeros(3)
        for j in range(res * res):
            t = tri[j]
            if t < 0:
                continue
            n += 1
            a, b, c = idx[t, 0], idx[t, 1], idx[t, 2]
            w1, w2 = b1[j], b2[j]
            w0 = 1.0 - w1 - w2
            nx = w0 * Nrm[a, 0] + w1 * Nrm[b, 0] + w2 * Nrm[c, 0]
            ny = w0 * Nrm[a, 1] + w1 * Nrm[b, 1] + w2 * Nrm[c, 1]
            nz = w0 * Nrm[a, 2] + w1 * Nrm[b, 2] + w2 * Nrm[c, 2]
            ln = nx * nx + ny * ny + nz * nz
            if ln > 1e-20:
                inv = 1.0 / np.sqrt(ln)
                nx, ny, nz = nx * inv, ny * inv, nz * inv
            else:  # the shader's fallback for a zero normal
                nx, ny, nz = 0.0, 1.0, 0.0
            hd = abs(nx * bases[v, 2, 0] + ny * bases[v, 2, 1] + nz * bases[v, 2, 2])
            m = min(max(w0 * C[a, 3] + w1 * C[b, 3] + w2 * C[c, 3], 0.0), 1.0)  # the variation mask
            s_var[0] += m
            s_var[1] += m * hd
            for li in range(L):
                s_var[2 + li] += m * abs(nx * lights[li, 0] + ny * lights[li, 1] + nz * lights[li, 2])
            for k in range(3):
                base = w0 * C[a, k] + w1 * C[b, k] + w2 * C[c, k]
                s_amb[k] += base
                s_head[k] += base * hd
                s_vbase[k] += m * base
                for li in range(L):
                    s_dir[li, k] += base * abs(nx * lights[li, 0] + ny * lights[li, 1] + nz * lights[li, 2])
        pix = 2.0 * half / res
        for k in range(rings.shape[0]):
            seen = 0
            for q in range(RING_POINTS):
                ang = 2.0 * np.pi * (q + 0.5) / RING_POINTS
                q0 = floor[0] + rings[k] * np.sin(ang) - centre[0]
                q1 = floor[1] - centre[1]
                q2 = floor[2] + rings[k] * np.cos(ang) - centre[2]
                px = int(np.floor(((bases[v, 0, 0] * q0 + bases[v, 0, 1] * q1 + bases[v, 0, 2] * q2) + half) / pix))
                py = int(np.floor(((bases[v, 1, 0] * q0 + bases[v, 1, 1] * q1 + bases[v, 1, 2] * q2) + half) / pix))
                if px < 0 or py < 0 or px >= res or py >= res:
                    seen += 1
                    continue
                j = py * res + px
                z = bases[v, 2, 0] * q0 + bases[v, 2, 1] * q1 + bases[v, 2, 2] * q2
                if tri[j] < 0 or zbuf[j] <= z:
                    seen += 1
            ground[v, k] += seen / RING_POINTS
        area[v] += n * pix_area  # sums over covered area: the table divides by the total at the end
        for k in range(3):
            ambient[v, k] += s_amb[k] * pix_area
            head[v, k] += s_head[k] * pix_area
            varied_base[v, k] += s_vbase[k] * pix_area
            for li in range(L):
                direct[v, li, k] += s_dir[li, k] * pix_area
        for q in range(2 + L):
            varied[v, q] += s_var[q] * pix_area


def gbuffer(P, idx, d, centre, half: float, res: int = RESOLUTION) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One orthographic view of posed triangles looking along ``-d``: (tri (res, res) int64, the nearest
    triangle at each pixel centre or -1; b1, b2 (res, res): its barycentrics of vertices 1 and 2). Row 0
    is the bottom of the view (``up`` of :func:`_basis`)."""
    P = np.ascontiguousarray(P, np.float64)
    idx = np.ascontiguousarray(idx, np.int64).reshape(-1, 3)
    zbuf = np.empty(res * res)
    tri = np.empty(res * res, np.int64)
    b1, b2 = np.empty(res * res), np.empty(res * res)
    _raster_one(P, idx, _basis(np.asarray(d, np.float64) / np.linalg.norm(d)), np.asarray(centre, np.float64),
                float(half), int(res), zbuf, tri, b1, b2)
    return tri.reshape(res, res), b1.reshape(res, res), b2.reshape(res, res)


@dataclass
class FarTable:
    """The far footprint of one clip of a character (see the module docstring).

    area : (VE, VA) float64, covered area (m^2 at scale 1) seen from each view direction
    ambient, head : (VE, VA, 3) float64, mean base colour and mean base x |n . d| over the covered pixels
    direct : (VE, VA, LE, LA, 3) float64, mean base x |n . l| for each light direction of the light grid
    radius : float, the bounding-sphere radius (m at scale 1) of the clip's poses about ``centre``
    centre : (3,) float64, model-space centre of that sphere
    ground : (VE, VA, RINGS) float64, the share of each floor ring about ``floor`` (radii ``ring_radii``) that
        the agent's body leaves visible from each view (the part of a ground shadow under it the viewer sees)
    floor : (3,) float64, the rest pose's floor point (centre x, lowest y, centre z)
    extent : (3,) float64, the rest pose's extent (x, y, z)
    varied : (VE, VA, 2 + LE x LA) float64, the varied part (vertex alpha, ``lod.variation``'s mask) per unit of
        covered area: its share, its mean mask x |n . d|, its mean mask x |n . l| for each light direction
    varied_base : (VE, VA, 3) float64, the varied part's mean base colour
    """

    area: np.ndarray
    ambient: np.ndarray
    head: np.ndarray
    direct: np.ndarray
    radius: float
    centre: np.ndarray
    ground: np.ndarray = None
    floor: np.ndarray = None
    extent: np.ndarray = None
    varied: np.ndarray = None
    varied_base: np.ndarray = None

    def ring_radii(self) -> np.ndarray:
        """(RINGS,) radii (m at scale 1) of the floor rings of :attr:`ground`."""
        h = float(self.extent[1]) if self.extent is not None else 0.0
        return (np.arange(RINGS) + 0.5) / RINGS * RING_EXTENT * h

    def lit(self, light_dir, light_color=(1.0, 1.0, 1.0), ambient: float = 0.3) -> np.ndarray:
        """(VE, VA, 3) mean lit colour of each view under one light fixed in the character's frame (the
        renderer's shading, ``render/shaders/world/light.glsl``, with the light's direction interpolated
        in the light grid): the reference of the renderer's own lookup in tests."""
        l = np.asarray(light_dir, np.float64)
        l = l / np.linalg.norm(l)
        el = np.degrees(np.arcsin(np.clip(l[1], -1.0, 1.0)))
        az = np.arctan2(l[0], l[2]) % (2.0 * np.pi)
        fe = (el + 90.0) / 180.0 * (self.direct.shape[2] - 1)
        fa = az / (2.0 * np.pi) * self.direct.shape[3]
        e0 = min(int(np.floor(fe)), self.direct.shape[2] - 2)
        a0 = int(np.floor(fa)) % self.direct.shape[3]
        te, ta = fe - e0, fa - np.floor(fa)
        a1 = (a0 + 1) % self.direct.shape[3]
        d = ((1 - te) * ((1 - ta) * self.direct[:, :, e0, a0] + ta * self.direct[:, :, e0, a1])
             + te * ((1 - ta) * self.direct[:, :, e0 + 1, a0] + ta * self.direct[:, :, e0 + 1, a1]))
        return self.ambient * float(ambient) + 0.35 * self.head + 0.55 * np.asarray(light_color, np.float64) * d


def measure(poses, *, res: int = RESOLUTION, rest=None) -> FarTable:
    """The far table of a list of poses.

    poses : sequence of (positions (V, 3), normals (V, 3), base colours (V, 3 or 4; alpha: the variation mask,
        0 without), indices (T, 3)) in model space
    rest : (V, 3) rest-pose positions (the floor point and extent a ground shadow is placed by, as the
        renderer's blob shadows are: ``render/world/shadows.py``), or None: the first pose's
    A pose without a finite, non-degenerate extent contributes nothing; with no usable pose the table is
    all zero (the agent covers nothing) and the radius 0.
    """
    views = grid_directions(VIEW_AZIMUTHS, VIEW_ELEVATIONS).reshape(-1, 3)
    lights = np.ascontiguousarray(grid_directions(LIGHT_AZIMUTHS, LIGHT_ELEVATIONS).reshape(-1, 3))
    bases = np.ascontiguousarray(np.stack([_basis(d) for d in views]))
    V, L = views.shape[0], lights.shape[0]
    area, amb, head, direct = np.zeros(V), np.zeros((V, 3)), np.zeros((V, 3)), np.zeros((V, L, 3))
    ground = np.zeros((V, RINGS))
    varied, vbase = np.zeros((V, 2 + L)), np.zeros((V, 3))
    floor, extent = _floor(rest if rest is not None else (poses[0][0] if len(poses) else None))
    rings = (np.arange(RINGS) + 0.5) / RINGS * RING_EXTENT * extent[1]
    used = 0
    los, his = [], []
    for P, N, C, idx in poses:
        P = np.ascontiguousarray(P, np.float64)
        N = np.ascontiguousarray(N, np.float64)
        C = np.asarray(C, np.float64)
        C = np.ascontiguousarray(C[:, :4] if C.shape[1] >= 4 else np.concatenate([C[:, :3], np.zeros((C.shape[0], 1))], 1))
        idx = np.ascontiguousarray(idx, np.int64).reshape(-1, 3)
        if idx.shape[0] == 0 or not (np.isfinite(P).all() and np.isfinite(N).all() and np.isfinite(C).all()):
            continue
        if idx.min() < 0 or idx.max() >= P.shape[0]:
            raise ValueError(f"far footprint: triangle indices reach {int(idx.max())}, the pose has {P.shape[0]} "
                             f"vertices")
        used_v = np.unique(idx)
        lo, hi = P[used_v].min(axis=0), P[used_v].max(axis=0)
        centre = 0.5 * (lo + hi)
        half = float(np.sqrt(((P[used_v] - centre) ** 2).sum(axis=1).max()))
        if not half > 0.0:
            continue
        half *= 1.0 + 1.0 / res  # no vertex exactly on the view's border
        _views_kernel(P, N, C, idx, bases, centre, half, int(res), lights, area, amb, head, direct, floor, rings,
                      ground, varied, vbase)
        used += 1
        los.append(lo)
        his.append(hi)
    shape = (VIEW_ELEVATIONS, VIEW_AZIMUTHS)
    if not used:
        return FarTable(np.zeros(shape), np.zeros(shape + (3,)), np.zeros(shape + (3,)),
                        np.zeros(shape + (LIGHT_ELEVATIONS, LIGHT_AZIMUTHS, 3)), 0.0, np.zeros(3),
                        np.ones(shape + (RINGS,)), floor, extent, np.zeros(shape + (2 + L,)), np.zeros(shape + (3,)))
    lo, hi = np.min(los, axis=0), np.max(his, axis=0)
    centre = 0.5 * (lo + hi)
    radius = float(0.5 * np.linalg.norm(hi - lo))
    w = np.where(area > 0.0, 1.0 / np.maximum(area, 1e-300), 0.0)  # colours: means over all poses' covered area
    return FarTable((area / used).reshape(shape), (amb * w[:, None]).reshape(shape + (3,)),
                    (head * w[:, None]).reshape(shape + (3,)),
                    (direct * w[:, None, None]).reshape(shape + (LIGHT_ELEVATIONS, LIGHT_AZIMUTHS, 3)), radius, centre,
                    (ground / used).reshape(shape + (RINGS,)), floor, extent, (varied * w[:, None]).reshape(shape + (2 + L,)),
                    (vbase / np.maximum(varied[:, :1], 1e-300) * (varied[:, :1] > 0)).reshape(shape + (3,)))


def _floor(rest) -> tuple[np.ndarray, np.ndarray]:
    """(floor point (centre x, lowest y, centre z), extent (x, y, z)) of rest-pose positions (zeros without)."""
    p = None if rest is None else np.asarray(rest, np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)] if p is not None else None
    if p is None or p.shape[0] == 0:
        return np.zeros(3), np.zeros(3)
    lo, hi = p.min(axis=0), p.max(axis=0)
    return np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2]), hi - lo
