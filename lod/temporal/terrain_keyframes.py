"""View-dependent keyframes: terrain selection every n-th frame, interpolated in between.

The view-dependent section of a :class:`lod.temporal.terrain.TerrainHierarchy` is
computed only at keyframe frames ``f_i = i * n``. A frame between two keyframes
draws their *union hierarchy* (a triangle of the union carries the ternary flag
1 = node of section i, 2 = node of section i+1, 3 = both) with every vertex
height interpolated linearly between the two sections' surfaces; vertices a
section lacks take that section's piecewise-linear height (the "additional
vertex array" of §3). The only per-frame work is that interpolation. Theorem 1
makes the result conforming and continuous in time: at a keyframe the drawn
surface is exactly the section, so nothing pops at the switch.

Camera extrapolation (§4.1), for interactive use where the camera at the next
keyframe is unknown, is chosen by ``mode``:

- ``"delayed"`` (1): draw ``S_inter(t_d)`` with the camera ``M(t_d)``, one
  keyframe interval late (``t_d = t - n dt``); error ``err_inter(t_d)`` plus the
  delay ``t - t_d``.
- ``"current"`` (2): the same geometry with the current camera ``M(t)``;
  error ``err_inter(t_d) + err_view(t, t_d)``.
- ``"extrapolated"`` (3): at each keyframe the next section is selected for a
  camera extrapolated to ``t_{i+1}`` (constant linear and yaw/pitch velocity
  from the last two frames); drawn at ``t`` with ``M(t)``; error
  ``err_inter(t) + err_extra(t_{i+1})`` (``err_extra`` known once ``t_{i+1}``
  is reached; it is reported from then on).

Every error term is a screen-space pixel deviation between two sections,
:func:`pixel_deviation`: the largest vertical distance between the two
surfaces at the grid vertices in view (their common refinement, where the
largest difference of two piecewise-linear surfaces lies), projected to pixels
at its depth. Measuring them needs a full selection each frame, so it is off
unless ``measure_errors`` (the drawing never depends on it).

Notes
-----
Friedrich, Polthier & Schmies, §3 (view-dependent keyframes, flags i / i+1,
one hierarchy plus an interpolated vertex array) and §4.1 (approaches 1-3 and
the errors err_inter, err_view, err_extra).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from lod.temporal.terrain import TERRAIN_LOD_TAU, TerrainHierarchy, TerrainSelection
from lod.view import Camera
from sim.mesh import Mesh
from sim.params import Param

#: default keyframe spacing n (frames per view-dependent selection)
TEMPORAL_N = 8
#: camera extrapolation modes of §4.1, in the paper's order
TEMPORAL_MODES = ("delayed", "current", "extrapolated")
#: degrees the culling frustum of keyframe selections is opened by on every side
TEMPORAL_CULL_MARGIN = 15.0

#: keys a scene table (proposed: ``[terrain]``) may add to drive the bisection
#: terrain; see :func:`terrain_lod_from_params`
TERRAIN_LOD_PARAMS: dict[str, Param] = {
    "lod": Param("str", "none", choices=("none", "bisection"),
                 doc="terrain level of detail: full-resolution mesh or view-dependent bisection hierarchy"),
    "lod_tau": Param("float", TERRAIN_LOD_TAU, min=1e-3, max=1e3,
                     doc="screen-space error bound of the bisection terrain, pixels"),
    "lod_keyframe_every": Param("int", TEMPORAL_N, min=1, max=1000,
                                doc="frames per view-dependent selection (1 = every frame)"),
    "lod_extrapolation": Param("str", "extrapolated", choices=TEMPORAL_MODES,
                               doc="camera handling between keyframes (Friedrich et al. §4.1)"),
    "lod_measure_errors": Param("bool", False,
                                doc="report err_inter / err_view / err_extra (one extra selection per frame)"),
}


def pixel_deviation(hier: TerrainHierarchy, heights_a: np.ndarray, heights_b: np.ndarray, camera: Camera,
                    size, reduce: str = "max") -> float:
    """Screen-space deviation (pixels) between two surfaces of ``hier``.

    Parameters
    ----------
    heights_a, heights_b : (V,) float64 world heights of both surfaces at every grid vertex
    camera : the camera the deviation is seen with; size : (width, height) pixels
    reduce : "max" or "mean" over the grid vertices in view

    Returns
    -------
    float >= 0: ``|y_a - y_b| * (H / 2) / tan(fov_y / 2) / depth`` reduced over
    the vertices in front of the near plane and inside the frustum (0 if none).
    """
    rel = hier.positions - camera.position
    depth = rel @ camera.forward
    planes = camera.frustum_planes(float(size[0]) / float(size[1]))
    vis = (depth > camera.near) & ((rel @ planes[:, :3].T + planes[:, 3]) >= 0).all(1)
    if not vis.any():
        return 0.0
    k = 0.5 * float(size[1]) / math.tan(math.radians(camera.fov_y) * 0.5)
    dev = np.abs(heights_a[vis] - heights_b[vis]) * k / depth[vis]
    return float(dev.max() if reduce == "max" else dev.mean())


def extrapolate_camera(prev: Camera, cur: Camera, steps: float) -> Camera:
    """Camera ``steps`` frame periods after ``cur``, extrapolating the position
    and the yaw / pitch linearly from ``prev`` -> ``cur`` (one frame apart)."""
    pos = cur.position + (cur.position - prev.position) * steps
    dyaw = math.remainder(cur.yaw - prev.yaw, 2 * math.pi)
    pitch = float(np.clip(cur.pitch + (cur.pitch - prev.pitch) * steps, -1.55, 1.55))
    return Camera.from_yaw_pitch(pos, cur.yaw + dyaw * steps, pitch, cur.fov_y, cur.near, cur.far)


@dataclass
class Keyframe:
    """A view-dependent section at a keyframe.

    Attributes
    ----------
    frame : int, frame index the section is for
    camera : Camera the section was selected with (extrapolated in mode 3)
    selection : TerrainSelection
    heights : (V,) float64 world heights of the section's surface at every grid vertex
    """

    frame: int
    camera: Camera
    selection: TerrainSelection
    heights: np.ndarray


@dataclass
class TemporalFrame:
    """What one displayed frame draws and what it costs.

    Attributes
    ----------
    frame : int; s : float in [0, 1], interpolation parameter between the keyframes
    camera : Camera to render with (the delayed one in mode "delayed")
    triangles : (L, 3) int64 grid vertex ids of the union hierarchy's leaves
    flags : (L,) uint8, 1 = triangle of section i, 2 = of section i+1, 3 = both
    grid_heights : (V,) float64 drawn surface height at every grid vertex
    selected : bool, a view-dependent selection ran during this frame
    err_inter, err_view, err_extra : float pixels (0 when not measured / not part of the mode)
    delay : float seconds between the camera time drawn and the current time
    """

    frame: int
    s: float
    camera: Camera
    triangles: np.ndarray
    flags: np.ndarray
    grid_heights: np.ndarray
    selected: bool
    err_inter: float = 0.0
    err_view: float = 0.0
    err_extra: float = 0.0
    delay: float = 0.0
    _hier: TerrainHierarchy | None = field(default=None, repr=False)
    _compact: tuple | None = field(default=None, repr=False)  # (used grid ids, compact indices), per interval

    @property
    def error(self) -> float:
        """The mode's total error term (pixels): err_1 / err_2 / err_3 of §4.1
        without the delay, which is reported separately in seconds."""
        return self.err_inter + self.err_view + self.err_extra

    def mesh(self) -> Mesh:
        """The frame as a ``sim.mesh.Mesh`` for ``lod.full.reps.build_static_rep``
        (positions float32 world, terrain normals and colours, uint32 indices;
        the index array is shared by all frames of a keyframe interval)."""
        h = self._hier
        used, idx = self._compact
        pos = h.positions[used].copy()
        pos[:, 1] = self.grid_heights[used]
        return Mesh(positions=pos.astype(np.float32), indices=idx, normals=h.normals[used], colors=h.colors[used])


class TemporalTerrainLOD:
    """Keyframed view-dependent terrain (§3) with camera extrapolation (§4).

    Parameters
    ----------
    hierarchy : TerrainHierarchy
    size : (width, height) pixels of the view
    n : int >= 1, frames per keyframe (n = 1 is per-frame selection)
    tau : float > 0, screen-space error bound of each selection (pixels)
    mode : one of :data:`TEMPORAL_MODES`
    dt : float > 0, frame period in seconds (for ``delay``)
    measure_errors : compute err_inter / err_view / err_extra (one extra
        reference selection per frame; off for real use)
    cull : frustum-cull the selections
    cull_margin : degrees the keyframe selections' culling frustum is opened by
        on every side (n > 1 only), so that terrain entering the view between
        two keyframes is interpolated from refined geometry, not from culled
        coarse triangles

    Call :meth:`frame` once per displayed frame with the current camera.
    """

    def __init__(self, hierarchy: TerrainHierarchy, size, n: int = TEMPORAL_N, tau: float = TERRAIN_LOD_TAU,
                 mode: str = "extrapolated", dt: float = 1.0 / 30.0, measure_errors: bool = False,
                 cull: bool = True, cull_margin: float = TEMPORAL_CULL_MARGIN):
        if int(n) != n or n < 1:
            raise ValueError(f"temporal LOD n: expected an integer >= 1, got {n!r}")
        if mode not in TEMPORAL_MODES:
            raise ValueError(f"temporal LOD mode: expected one of {', '.join(TEMPORAL_MODES)}, got {mode!r}")
        if not dt > 0:
            raise ValueError(f"temporal LOD dt: expected seconds > 0, got {dt!r}")
        self.h = hierarchy
        self.size = (int(size[0]), int(size[1]))
        self.n, self.tau, self.mode, self.dt = int(n), float(tau), mode, float(dt)
        self.measure_errors, self.cull = bool(measure_errors), bool(cull)
        self.cull_margin = float(cull_margin) if self.n > 1 else 0.0
        self.f = 0
        self.history: deque = deque(maxlen=self.n + 2)  # recent actual cameras (for delay / extrapolation)
        self.keys: dict[int, Keyframe] = {}
        self.n_selections = 0  # selections used for drawing
        self.n_reference_selections = 0  # selections used only to measure errors
        self._union_cache: tuple | None = None
        self._extra_err = 0.0
        self._truth: dict[int, np.ndarray] = {}

    # ------------------------------------------------------------------ selections
    def _select(self, camera: Camera, frame: int) -> Keyframe:
        self.n_selections += 1
        sel = self.h.select(camera, self.size, self.tau, self.cull, self.cull_margin)
        return Keyframe(frame, camera, sel, self.h.interpolated_heights(sel.active))

    def _view_heights(self, camera: Camera) -> np.ndarray:
        """S_view: heights of the exact per-frame section for ``camera`` (measurement only)."""
        self.n_reference_selections += 1
        act = self.h.active_vertices(camera, self.size, self.tau, self.cull)
        return self.h.interpolated_heights(act)

    def _union(self, a: Keyframe, b: Keyframe):
        key = (a.frame, b.frame)
        if self._union_cache is None or self._union_cache[0] != key:
            sec = self.h.section(a.selection.active | b.selection.active)
            parent = sec.leaves // 2
            pm = self.h.mid[parent]
            in_a = (parent == 1) | a.selection.active[np.maximum(pm, 0)]
            in_b = (parent == 1) | b.selection.active[np.maximum(pm, 0)]
            flags = (in_a.astype(np.uint8) | (in_b.astype(np.uint8) << 1))
            used, inv = np.unique(sec.triangles.reshape(-1), return_inverse=True)
            self._union_cache = (key, sec, flags, (used, inv.reshape(-1, 3).astype(np.uint32)))
        return self._union_cache[1], self._union_cache[2], self._union_cache[3]

    # ------------------------------------------------------------------ frames
    def frame(self, camera: Camera) -> TemporalFrame:
        """Advance one displayed frame with the current (actual) ``camera``."""
        f = self.f
        self.f += 1
        self.history.append(camera)
        n = self.n
        i, r = divmod(f, n)
        selected = False
        if r == 0:
            selected = True
            if self.mode == "extrapolated":
                if i not in self.keys:  # first keyframe: nothing was extrapolated yet
                    self.keys[i] = self._select(camera, f)
                elif self.measure_errors:  # t_{i} reached: the extrapolated section's error
                    self._extra_err = pixel_deviation(self.h, self._view_heights(camera), self.keys[i].heights,
                                                      camera, self.size)
                prev = self.history[-2] if len(self.history) >= 2 else camera
                self.keys[i + 1] = self._select(extrapolate_camera(prev, camera, n), f + n)
            else:
                self.keys[i] = self._select(camera, f)
            for k in [k for k in self.keys if k < i - 1]:
                del self.keys[k]
        s = r / n
        if self.mode == "extrapolated":
            a, b = self.keys[i], self.keys[i + 1]
            draw_cam, delay = camera, 0.0
        else:  # interval (i-1, i) shown one interval late
            a = self.keys.get(i - 1, self.keys[i])
            b = self.keys[i]
            if i == 0:
                s = 1.0
            lag = min(n, f) if i > 0 else 0
            delayed = self.history[-1 - lag] if lag < len(self.history) else self.history[0]
            delay = lag * self.dt
            draw_cam = delayed if self.mode == "delayed" else camera
        sec, flags, compact = self._union(a, b)
        heights = (1.0 - s) * a.heights + s * b.heights
        out = TemporalFrame(f, s, draw_cam, sec.triangles, flags, heights, selected, delay=delay, _hier=self.h,
                            _compact=compact)
        if self.measure_errors:
            if self.mode == "extrapolated":
                out.err_inter = pixel_deviation(self.h, self._view_heights(camera), heights, camera, self.size)
                out.err_extra = self._extra_err
            else:
                t_d_cam = self.history[-1 - (min(n, f) if i > 0 else 0)] if i > 0 else camera
                view_td = self._view_heights(t_d_cam)
                out.err_inter = pixel_deviation(self.h, view_td, heights, t_d_cam, self.size)
                if self.mode == "current":
                    out.err_view = pixel_deviation(self.h, self._view_heights(camera), view_td, camera, self.size)
        return out


def terrain_lod_from_params(terrain, size, params: dict, dt: float) -> "TemporalTerrainLOD | None":
    """Build the keyframed bisection terrain from a validated table holding the
    :data:`TERRAIN_LOD_PARAMS` keys (None when ``lod`` is ``"none"``).

    terrain : sim.terrain.Terrain; size : (width, height) pixels; dt : frame period, seconds
    """
    c = {k: p.default for k, p in TERRAIN_LOD_PARAMS.items()}
    c.update({k: v for k, v in params.items() if k in TERRAIN_LOD_PARAMS})
    if c["lod"] == "none":
        return None
    return TemporalTerrainLOD(TerrainHierarchy(terrain), size, n=int(c["lod_keyframe_every"]),
                              tau=float(c["lod_tau"]), mode=str(c["lod_extrapolation"]), dt=float(dt),
                              measure_errors=bool(c["lod_measure_errors"]))
