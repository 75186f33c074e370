"""View-dependent terrain: a Rivara/Bänsch bisection hierarchy over the heightfield.

The terrain's domain square is split along a diagonal into two root triangles
whose refinement edge is that diagonal; newest-vertex bisection (see
:mod:`lod.temporal.bisection`, Fig. 2) of a ``(2^k + 1)^2`` grid then produces, at depth
``2k``, exactly the full-resolution grid triangles. The complete hierarchy is
stored implicitly as two heap-ordered binary trees (node ``i`` has children
``2i`` and ``2i + 1``; node 1 is a virtual square, 2 and 3 the roots), with the
grid vertex id ``z * N + x`` as vertex identity, so every keyframe section of
:mod:`lod.temporal.terrain_keyframes` is a sub-hierarchy of the same infinite hierarchy
(Definition 2 holds by construction).

Error and selection
-------------------
For every node the exact object-space error ``err(T)`` is the largest vertical
distance between the triangle's plane and the grid samples it covers (the
full-resolution surface is piecewise linear on a refinement of ``T``, so this
is the max deviation from the full-resolution mesh). A triangle is bisected
iff its refinement-edge midpoint ``m`` is *active*. Vertex errors ``e(m)`` and
bounding-sphere radii ``r(m)`` are saturated over the vertex dependency DAG (a
midpoint depends on the apexes of the triangles sharing its edge), so the
screen-space test below is monotone: an active vertex's parents are active,
which is the conforming closure of Definition 1 computed without iteration
(tested against :class:`lod.temporal.bisection.BisectionForest`). A vertex is active iff
its sphere meets the view frustum and

    e(m) * K / max(z_near, depth(centre) - r(m)) > tau,
    K = (H / 2) / tan(fov_y / 2) * sqrt(1 + tan^2(fov_y / 2) (1 + aspect^2))

where the last factor bounds the on-screen length of a vertical world segment
anywhere in the frustum relative to its length at the image centre. Hence for
every point ``s`` of a drawn triangle, ``|h_full(s) - h_lod(s)|`` projected to
pixels at ``s`` is at most ``tau`` (to first order in error / depth).

Notes
-----
Friedrich, Polthier & Schmies, §2.1 (bisection hierarchy), §3 (view-dependent
extraction as a boolean refinement flag per triangle); the saturated vertex
errors and spheres follow Lindstrom & Pascucci, "Visualization of large
terrains made easy", IEEE Vis 2001, §3-4.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from lod.view import Camera
from sim.mesh import Mesh
from sim.terrain import Terrain

#: default screen-space error bound (pixels)
TERRAIN_LOD_TAU = 1.0
#: largest grid side (2^k + 1) the hierarchy resamples a terrain to
TERRAIN_LOD_MAX_SIDE = 1025


# ---------------------------------------------------------------------------- hierarchy kernels
@njit(cache=True)
def _build_tree(n_side, k):
    """Heap-ordered complete bisection hierarchy of a (2^k+1)^2 grid.

    Returns tri (M, 3) int32 (refinement edge = columns 0, 1) and mid (M,)
    int32 (midpoint vertex of the refinement edge, -1 at the finest level),
    M = 2^(2k + 2); rows 0 and 1 are unused.
    """
    n_levels = 2 * k + 1
    m_nodes = 1 << (n_levels + 1)
    tri = np.full((m_nodes, 3), -1, np.int32)
    mid = np.full(m_nodes, -1, np.int32)
    s = n_side - 1
    a = 0
    b = s
    c = s * n_side + s
    d = s * n_side
    # (x, z) CCW seen from +Y: root 0 = (A, C, B), root 1 = (C, A, D); diagonal A-C first
    tri[2, 0] = a
    tri[2, 1] = c
    tri[2, 2] = b
    tri[3, 0] = c
    tri[3, 1] = a
    tri[3, 2] = d
    first_leaf = 1 << n_levels
    for i in range(2, first_leaf):
        v0 = tri[i, 0]
        v1 = tri[i, 1]
        v2 = tri[i, 2]
        mx = ((v0 % n_side) + (v1 % n_side)) // 2
        mz = ((v0 // n_side) + (v1 // n_side)) // 2
        m = mz * n_side + mx
        mid[i] = m
        tri[2 * i, 0] = v2
        tri[2 * i, 1] = v0
        tri[2 * i, 2] = m
        tri[2 * i + 1, 0] = v1
        tri[2 * i + 1, 1] = v2
        tri[2 * i + 1, 2] = m
    return tri, mid


@njit(cache=True)
def _node_errors(tri, heights, first_leaf):
    """(M,) float64 max |height - plane| over the grid samples inside each
    internal node (0 for the finest level and unused rows)."""
    nz, nx = heights.shape
    m_nodes = tri.shape[0]
    err = np.zeros(m_nodes)
    for i in range(2, first_leaf):
        x0 = tri[i, 0] % nx
        z0 = tri[i, 0] // nx
        x1 = tri[i, 1] % nx
        z1 = tri[i, 1] // nx
        x2 = tri[i, 2] % nx
        z2 = tri[i, 2] // nx
        h0 = heights[z0, x0]
        h1 = heights[z1, x1]
        h2 = heights[z2, x2]
        det = (x1 - x0) * (z2 - z0) - (x2 - x0) * (z1 - z0)
        if det == 0:
            continue
        lo_x = min(x0, min(x1, x2))
        hi_x = max(x0, max(x1, x2))
        lo_z = min(z0, min(z1, z2))
        hi_z = max(z0, max(z1, z2))
        best = 0.0
        for z in range(lo_z, hi_z + 1):
            for x in range(lo_x, hi_x + 1):
                # barycentric coordinates (exact integers / det)
                l1 = ((x - x0) * (z2 - z0) - (x2 - x0) * (z - z0)) / det
                l2 = ((x1 - x0) * (z - z0) - (x - x0) * (z1 - z0)) / det
                l0 = 1.0 - l1 - l2
                if l0 < -1e-9 or l1 < -1e-9 or l2 < -1e-9:
                    continue
                dv = abs(heights[z, x] - (l0 * h0 + l1 * h1 + l2 * h2))
                if dv > best:
                    best = dv
        err[i] = best
    return err


def node_errors_reference(tri: np.ndarray, heights: np.ndarray, first_leaf: int) -> np.ndarray:
    """Plain numpy reference of :func:`_node_errors` (small grids only)."""
    nz, nx = heights.shape
    gx, gz = np.meshgrid(np.arange(nx), np.arange(nz))
    gx, gz, gh = gx.ravel().astype(np.float64), gz.ravel().astype(np.float64), heights.ravel()
    err = np.zeros(tri.shape[0])
    for i in range(2, first_leaf):
        v = tri[i].astype(np.int64)
        xs, zs, hs = (v % nx).astype(np.float64), (v // nx).astype(np.float64), heights.ravel()[v]
        A = np.stack([xs, zs, np.ones(3)], 1)
        lam = np.linalg.solve(A.T, np.stack([gx, gz, np.ones_like(gx)]))  # (3, P)
        inside = (lam >= -1e-9).all(0)
        err[i] = np.abs(gh[inside] - hs @ lam[:, inside]).max(initial=0.0)
    return err


@njit(cache=True)
def _saturate(tri, mid, err, pos, n_levels):
    """Saturated vertex errors e (V,) and sphere radii r (V,) over the DAG
    midpoint -> apexes of the triangles sharing its refinement edge
    (finest level first). Vertices that are never midpoints keep e = -1."""
    nv = pos.shape[0]
    e = np.full(nv, -1.0)
    r = np.zeros(nv)
    for lev in range(n_levels - 2, -1, -1):
        lo = 1 << (lev + 1)
        hi = 1 << (lev + 2)
        for i in range(lo, hi):  # own triangles
            m = mid[i]
            if m < 0:
                continue
            if err[i] > e[m]:
                e[m] = err[i]
            for j in range(3):
                v = tri[i, j]
                dd = math.sqrt((pos[v, 0] - pos[m, 0]) ** 2 + (pos[v, 1] - pos[m, 1]) ** 2
                               + (pos[v, 2] - pos[m, 2]) ** 2)
                if dd > r[m]:
                    r[m] = dd
        for i in range(lo, hi):  # propagate to the dependency parents (apexes)
            m = mid[i]
            p = tri[i, 2]
            if m < 0 or lev == 0:
                continue
            if e[m] > e[p]:
                e[p] = e[m]
            dd = math.sqrt((pos[p, 0] - pos[m, 0]) ** 2 + (pos[p, 1] - pos[m, 1]) ** 2
                           + (pos[p, 2] - pos[m, 2]) ** 2) + r[m]
            if dd > r[p]:
                r[p] = dd
    return e, r


@njit(cache=True)
def _collect_leaves(mid, active, first_leaf):
    """Leaf heap ids of the hierarchy refined where ``active[mid[node]]``."""
    out = np.empty(first_leaf, np.int64)
    n = 0
    stack = np.empty(128, np.int64)
    sp = 0
    stack[0] = 3
    stack[1] = 2
    sp = 2
    while sp > 0:
        sp -= 1
        i = stack[sp]
        if i < first_leaf and active[mid[i]]:
            stack[sp] = 2 * i + 1
            stack[sp + 1] = 2 * i
            sp += 2
        else:
            out[n] = i
            n += 1
    return out[:n]


@njit(cache=True)
def _active_kernel(pos, err, rad, cam, fwd, planes, scale, tau, near, cull):
    """(V,) bool screen-space activation of the module docstring (see
    :meth:`TerrainHierarchy.active_vertices_reference`)."""
    nv = pos.shape[0]
    out = np.zeros(nv, np.bool_)
    for v in range(nv):
        if err[v] <= 0.0:
            continue
        rx = pos[v, 0] - cam[0]
        ry = pos[v, 1] - cam[1]
        rz = pos[v, 2] - cam[2]
        d = rx * fwd[0] + ry * fwd[1] + rz * fwd[2] - rad[v]
        if d < near:
            d = near
        if not err[v] * scale > tau * d:
            continue
        ok = True
        if cull:
            for k in range(planes.shape[0]):
                if rx * planes[k, 0] + ry * planes[k, 1] + rz * planes[k, 2] + planes[k, 3] < -rad[v]:
                    ok = False
                    break
        out[v] = ok
    return out


@njit(cache=True)
def _interp_heights(y_true, tri, mid, active, n_levels):
    """(V,) float64 surface heights of a section (see
    :meth:`TerrainHierarchy.interpolated_heights_reference`)."""
    y = y_true.copy()
    for lev in range(n_levels - 1):
        for i in range(1 << (lev + 1), 1 << (lev + 2)):
            m = mid[i]
            if not active[m]:
                y[m] = 0.5 * (y[tri[i, 0]] + y[tri[i, 1]])
    return y


def collect_leaves_reference(mid: np.ndarray, active: np.ndarray, first_leaf: int) -> np.ndarray:
    """Plain numpy reference of :func:`_collect_leaves` (level-synchronous, heap-id order)."""
    front = np.array([2, 3], np.int64)
    leaves = []
    while front.size:
        split = (front < first_leaf) & active[np.maximum(mid[np.minimum(front, mid.size - 1)], 0)]
        split &= front < first_leaf
        leaves.append(front[~split])
        front = np.stack([2 * front[split], 2 * front[split] + 1], 1).ravel()
    return np.sort(np.concatenate(leaves))


# ---------------------------------------------------------------------------- public API
@dataclass
class TerrainSelection:
    """One view-dependent section of a :class:`TerrainHierarchy`.

    Attributes
    ----------
    active : (V,) bool, grid vertices inserted (closed under dependency)
    leaves : (L,) int64 heap ids of the drawn triangles
    triangles : (L, 3) int64 grid vertex ids of the drawn triangles
    """

    active: np.ndarray
    leaves: np.ndarray
    triangles: np.ndarray


class TerrainHierarchy:
    """The bisection hierarchy of a terrain heightfield.

    Parameters
    ----------
    terrain : sim.terrain.Terrain
    max_side : int, largest grid side; a terrain whose grid is not ``2^k + 1``
        square (or is larger than ``max_side``) is resampled bilinearly onto the
        smallest ``2^k + 1`` grid covering its resolution (capped).

    Attributes
    ----------
    n_side : int, N = 2^k + 1
    positions : (N*N, 3) float64 world positions of the grid (id = z * N + x)
    normals, colors : (N*N, 3) float32, (N*N, 4) float32 (as ``Terrain.mesh``)
    tri, mid : heap arrays of the complete hierarchy (see :func:`_build_tree`)
    node_err : (M,) float64 exact vertical error per node, metres
    vert_err, vert_radius : (N*N,) float64 saturated error / sphere radius
    """

    def __init__(self, terrain: Terrain, max_side: int = TERRAIN_LOD_MAX_SIDE):
        side = max(terrain.nx, terrain.nz, 3)
        k = max(1, int(math.ceil(math.log2(side - 1))))
        while (1 << k) + 1 > max_side and k > 1:
            k -= 1
        n = (1 << k) + 1
        if terrain.nx == n and terrain.nz == n:
            h = terrain.heights.copy()
        else:
            xs = terrain.origin[0] + np.linspace(0.0, terrain.size[0], n)
            zs = terrain.origin[2] + np.linspace(0.0, terrain.size[1], n)
            h = terrain.height(xs[None, :], zs[:, None]) - terrain.origin[1]
        self.terrain = Terrain(h, terrain.size, terrain.origin)
        self.k, self.n_side = k, n
        self.n_levels = 2 * k + 1
        self.first_leaf = 1 << self.n_levels
        full = self.terrain.mesh(max_resolution=n)
        self.positions = full.positions.astype(np.float64)
        self.normals = full.normals
        self.colors = full.colors
        self.full_indices = full.indices
        self.tri, self.mid = _build_tree(n, k)
        self.node_err = _node_errors(self.tri, h, self.first_leaf)
        self.vert_err, self.vert_radius = _saturate(self.tri, self.mid, self.node_err, self.positions,
                                                    self.n_levels)
        self.n_selections = 0

    # ------------------------------------------------------------------ geometry helpers
    @property
    def n_vertices(self) -> int:
        return self.n_side * self.n_side

    @property
    def n_full_triangles(self) -> int:
        return 2 * (self.n_side - 1) ** 2

    def error_scale(self, camera, size) -> float:
        """K of the module docstring: pixels per metre of vertical error at depth 1."""
        w, h = float(size[0]), float(size[1])
        ty = math.tan(math.radians(camera.fov_y) * 0.5)
        return (0.5 * h / ty) * math.sqrt(1.0 + ty * ty * (1.0 + (w / h) ** 2))

    @staticmethod
    def cull_planes(camera, size, margin_deg: float = 0.0) -> np.ndarray:
        """(6, 4) camera-relative frustum planes, the side planes opened by
        ``margin_deg`` degrees each (so geometry about to enter the view while a
        keyframe is shown is already refined)."""
        aspect = float(size[0]) / float(size[1])
        if margin_deg <= 0:
            return camera.frustum_planes(aspect)
        ty = math.tan(math.radians(camera.fov_y) * 0.5)
        hy = min(math.atan(ty) + math.radians(margin_deg), math.radians(85.0))
        hx = min(math.atan(ty * aspect) + math.radians(margin_deg), math.radians(85.0))
        wide = Camera(camera.position, camera.rotation, math.degrees(2 * hy), camera.near, camera.far)
        return wide.frustum_planes(math.tan(hx) / math.tan(hy))

    def active_vertices(self, camera, size, tau: float = TERRAIN_LOD_TAU, cull: bool = True,
                        cull_margin: float = 0.0) -> np.ndarray:
        """(V,) bool: vertices whose saturated screen-space error exceeds ``tau``
        pixels (and whose sphere meets the frustum, opened by ``cull_margin``
        degrees, when ``cull``); numba kernel."""
        if not tau > 0 or not math.isfinite(tau):
            raise ValueError(f"terrain LOD tau: expected pixels > 0, got {tau}")
        planes = self.cull_planes(camera, size, cull_margin)
        return _active_kernel(self.positions, self.vert_err, self.vert_radius, camera.position,
                              np.ascontiguousarray(camera.forward), planes, self.error_scale(camera, size),
                              float(tau), float(camera.near), bool(cull))

    def active_vertices_reference(self, camera, size, tau: float = TERRAIN_LOD_TAU, cull: bool = True,
                                  cull_margin: float = 0.0) -> np.ndarray:
        """Plain numpy reference of :meth:`active_vertices`."""
        if not tau > 0 or not math.isfinite(tau):
            raise ValueError(f"terrain LOD tau: expected pixels > 0, got {tau}")
        rel = self.positions - camera.position
        depth = rel @ camera.forward - self.vert_radius
        depth = np.maximum(depth, camera.near)
        act = (self.vert_err > 0) & (self.vert_err * self.error_scale(camera, size) > tau * depth)
        if cull:
            planes = self.cull_planes(camera, size, cull_margin)
            dist = rel @ planes[:, :3].T + planes[:, 3]
            act &= (dist >= -self.vert_radius[:, None]).all(1)
        return act

    def select(self, camera, size, tau: float = TERRAIN_LOD_TAU, cull: bool = True,
               cull_margin: float = 0.0) -> TerrainSelection:
        """View-dependent section for ``camera`` at ``size`` (width, height) pixels."""
        self.n_selections += 1
        act = self.active_vertices(camera, size, tau, cull, cull_margin)
        return self.section(act)

    def section(self, active: np.ndarray) -> TerrainSelection:
        """The conforming section of a dependency-closed active vertex set."""
        act = np.ascontiguousarray(active, bool)
        leaves = _collect_leaves(self.mid, act, self.first_leaf)
        return TerrainSelection(act, leaves, self.tri[leaves].astype(np.int64))

    def interpolated_heights(self, active: np.ndarray) -> np.ndarray:
        """(V,) float64 world y of every grid vertex on the surface of the
        section ``active`` (inactive vertices: linear interpolation along the
        refinement edge they would bisect, coarse to fine); numba kernel."""
        return _interp_heights(self.positions[:, 1].copy(), self.tri, self.mid,
                               np.ascontiguousarray(active, np.bool_), self.n_levels)

    def interpolated_heights_reference(self, active: np.ndarray) -> np.ndarray:
        """Plain numpy reference of :meth:`interpolated_heights`."""
        y = self.positions[:, 1].copy()
        for lev in range(self.n_levels - 1):
            ids = np.arange(1 << (lev + 1), 1 << (lev + 2))
            m = self.mid[ids]
            off = ~active[m]
            if off.any():
                t = self.tri[ids[off]]
                y[m[off]] = 0.5 * (y[t[:, 0]] + y[t[:, 1]])
        return y

    def mesh(self, selection: TerrainSelection, heights: np.ndarray | None = None) -> Mesh:
        """A compact ``sim.mesh.Mesh`` of a section (float32 world positions,
        terrain normals and colours), ready for ``lod.full.reps.build_static_rep``.

        heights : optional (V,) float64 world y per grid vertex (interpolated
            keyframe heights); default the true terrain heights.
        """
        tris = selection.triangles
        used, inv = np.unique(tris.reshape(-1), return_inverse=True)
        pos = self.positions[used].copy()
        if heights is not None:
            pos[:, 1] = heights[used]
        return Mesh(positions=pos.astype(np.float32), indices=inv.reshape(-1, 3).astype(np.uint32),
                    normals=self.normals[used].copy(), colors=self.colors[used].copy())

    def full_mesh(self) -> Mesh:
        """The full-resolution grid mesh (the reference the LOD approximates)."""
        return Mesh(positions=self.positions.astype(np.float32), indices=self.full_indices,
                    normals=self.normals, colors=self.colors)

    def surface_height(self, leaves: np.ndarray, heights: np.ndarray, x, z) -> np.ndarray:
        """World y of the piecewise-linear surface of the section with leaf
        heap ids ``leaves`` and per-grid-vertex world heights ``heights`` (V,)
        at world points x, z (arrays); a slow reference for tests."""
        x = np.asarray(x, np.float64).ravel()
        z = np.asarray(z, np.float64).ravel()
        n = self.n_side
        gx = np.clip((x - self.terrain.origin[0]) / self.terrain.dx, 0, n - 1)
        gz = np.clip((z - self.terrain.origin[2]) / self.terrain.dz, 0, n - 1)
        # point location by descending the complete hierarchy is simple and exact here
        out = np.empty(x.size)
        leafset = np.zeros(self.tri.shape[0], bool)
        leafset[np.asarray(leaves, np.int64)] = True
        for q in range(x.size):
            i = 2 if _inside(self, 2, gx[q], gz[q]) else 3
            while not leafset[i]:
                i = 2 * i if _inside(self, 2 * i, gx[q], gz[q]) else 2 * i + 1
            v = self.tri[i]
            xs, zs = (v % n).astype(np.float64), (v // n).astype(np.float64)
            A = np.stack([xs, zs, np.ones(3)], 1)
            lam = np.linalg.solve(A.T, np.array([gx[q], gz[q], 1.0]))
            out[q] = lam @ heights[v]
        return out


def _inside(h: TerrainHierarchy, i: int, gx: float, gz: float) -> bool:
    v = h.tri[i]
    n = h.n_side
    xs, zs = v % n, v // n
    A = np.stack([xs, zs, np.ones(3)], 1).astype(np.float64)
    lam = np.linalg.solve(A.T, np.array([gx, gz, 1.0]))
    return bool((lam >= -1e-9).all())


def terrain_hierarchy_from_scene(terrain_table: dict, base_dir=None, max_side: int = TERRAIN_LOD_MAX_SIDE):
    """Build a :class:`TerrainHierarchy` from a scene's validated ``[terrain]`` table."""
    return TerrainHierarchy(Terrain.from_config(terrain_table, base_dir), max_side)
