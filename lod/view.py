"""View math: the camera, its projection, frustum planes and pixel projection.

Conventions (shared with ``render``): right-handed world, Y up; the camera
looks down its local -Z with +Y up (OpenGL). All matrices are 4x4 float64 for
column vectors (``p' = M @ p``). The view matrix is *camera-relative*: it holds
the rotation only and assumes the camera sits at the origin, because every
position that reaches the GPU has already had the camera position subtracted
in float64 (see ``lod.drawlist.DrawList.origin``). Frustum planes are given in
the same camera-relative world frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: below this length a direction is treated as degenerate (position == target,
#: forward parallel to up) and a fallback is used instead of dividing by it.
VIEW_EPS = 1e-12


def _normalize(v: np.ndarray) -> tuple[np.ndarray, float]:
    n = float(np.linalg.norm(v))
    if n < VIEW_EPS or not np.isfinite(n):
        return v, 0.0
    return v / n, n


def rotation_from_forward(forward, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """World-from-camera rotation (3, 3) float64 whose -Z column is ``forward``.

    Robust for degenerate input: a zero forward means "look down -Z"; a
    forward parallel to ``up`` (looking straight up or down) uses world -Z or
    +X as the secondary axis, so the result is always a proper rotation.
    """
    f, n = _normalize(np.asarray(forward, np.float64).reshape(3))
    if n == 0.0:
        f = np.array([0.0, 0.0, -1.0])
    u, nu = _normalize(np.asarray(up, np.float64).reshape(3))
    if nu == 0.0:
        u = np.array([0.0, 1.0, 0.0])
    x = np.cross(f, u)
    x, nx = _normalize(x)
    if nx < 1e-9:
        # forward is (anti)parallel to up: pick a secondary axis not parallel to f
        for alt in ((0.0, 0.0, -1.0), (1.0, 0.0, 0.0)):
            x, nx = _normalize(np.cross(f, np.array(alt)))
            if nx > 1e-6:
                break
    y = np.cross(x, f)
    y, _ = _normalize(y)
    return np.stack([x, y, -f], axis=1)


@dataclass
class Camera:
    """A perspective camera.

    Attributes
    ----------
    position : (3,) float64, world metres
    rotation : (3, 3) float64, world-from-camera (columns: camera +X, +Y, +Z
        in world); the camera looks down its -Z.
    fov_y : float, vertical field of view in degrees, in (0, 180)
    near, far : float, clip distances in metres, 0 < near < far
    """

    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    fov_y: float = 50.0
    near: float = 0.1
    far: float = 1000.0

    def __post_init__(self):
        self.position = np.asarray(self.position, np.float64).reshape(3).copy()
        self.rotation = np.asarray(self.rotation, np.float64).reshape(3, 3).copy()
        if not (np.isfinite(self.position).all() and np.isfinite(self.rotation).all()):
            raise ValueError("Camera.position/rotation: expected finite values, got NaN or Inf")
        if not 0.0 < float(self.fov_y) < 180.0:
            raise ValueError(f"Camera.fov_y: expected degrees in (0, 180), got {self.fov_y}")
        if not 0.0 < float(self.near) < float(self.far):
            raise ValueError(f"Camera.near/far: expected 0 < near < far, got {self.near}, {self.far}")

    # ------------------------------------------------------------------ construction
    @classmethod
    def look_at(cls, position, target, up=(0.0, 1.0, 0.0), fov_y=50.0, near=0.1, far=1000.0) -> "Camera":
        """Camera at ``position`` looking at ``target``.

        Never produces NaN: position == target looks down -Z, and looking
        straight up or down keeps a valid (if arbitrary) roll.
        """
        p = np.asarray(position, np.float64).reshape(3)
        t = np.asarray(target, np.float64).reshape(3)
        return cls(p, rotation_from_forward(t - p, up), float(fov_y), float(near), float(far))

    @classmethod
    def from_yaw_pitch(cls, position, yaw: float, pitch: float, fov_y=50.0, near=0.1, far=1000.0) -> "Camera":
        """Camera from yaw (radians about +Y; 0 looks down -Z, positive turns
        towards -X) and pitch (radians about the camera X; positive looks up)."""
        cam = cls(np.asarray(position, np.float64), np.eye(3), float(fov_y), float(near), float(far))
        cam.set_yaw_pitch(yaw, pitch)
        return cam

    # ------------------------------------------------------------------ orientation
    @property
    def forward(self) -> np.ndarray:
        """(3,) float64 unit viewing direction in world (the camera's -Z)."""
        return -self.rotation[:, 2]

    @property
    def yaw(self) -> float:
        """Radians about +Y; 0 looks down world -Z."""
        f = self.forward
        return float(math.atan2(-f[0], -f[2]))

    @property
    def pitch(self) -> float:
        """Radians above the horizontal plane, in [-pi/2, pi/2]."""
        return float(math.asin(float(np.clip(self.forward[1], -1.0, 1.0))))

    def set_yaw_pitch(self, yaw: float, pitch: float) -> None:
        """Set the orientation to ``Ry(yaw) @ Rx(pitch)`` (no roll)."""
        cy, sy = math.cos(yaw), math.sin(yaw)
        cp, sp = math.cos(pitch), math.sin(pitch)
        ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
        rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
        self.rotation = ry @ rx

    # ------------------------------------------------------------------ matrices
    def view_matrix(self) -> np.ndarray:
        """(4, 4) float64 camera-relative view matrix (rotation only: the
        camera sits at the origin of camera-relative world coordinates)."""
        v = np.eye(4)
        v[:3, :3] = self.rotation.T
        return v

    def world_view_matrix(self) -> np.ndarray:
        """(4, 4) float64 absolute view matrix (includes -position); for CPU use only."""
        v = self.view_matrix()
        v[:3, 3] = -self.rotation.T @ self.position
        return v

    def projection(self, aspect: float) -> np.ndarray:
        """(4, 4) float64 OpenGL perspective projection (clip z in [-w, w])."""
        aspect = float(aspect)
        if not aspect > 0.0 or not math.isfinite(aspect):
            raise ValueError(f"Camera.projection: expected aspect > 0, got {aspect}")
        f = 1.0 / math.tan(math.radians(self.fov_y) * 0.5)
        n, fa = float(self.near), float(self.far)
        p = np.zeros((4, 4))
        p[0, 0] = f / aspect
        p[1, 1] = f
        p[2, 2] = (fa + n) / (n - fa)
        p[2, 3] = 2.0 * fa * n / (n - fa)
        p[3, 2] = -1.0
        return p

    def frustum_planes(self, aspect: float) -> np.ndarray:
        """(6, 4) float64 planes (nx, ny, nz, d) in camera-relative world
        coordinates, unit inward normals: a point p is inside when
        ``n . p + d >= 0`` for all six. Order: left, right, bottom, top, near, far.

        Notes
        -----
        Gribb & Hartmann's extraction from the rows of ``proj @ view``.
        """
        m = self.projection(aspect) @ self.view_matrix()
        planes = np.stack([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
        planes /= np.linalg.norm(planes[:, :3], axis=1, keepdims=True)
        return planes

    def project(self, points_world, size, return_depth: bool = False):
        """Project world points to pixel coordinates.

        Parameters
        ----------
        points_world : (N, 3) float64 world positions
        size : (width, height) pixels
        return_depth : also return the view-space depth (distance along the
            viewing direction; <= 0 means behind the camera, where the pixel
            coordinates are meaningless but finite).

        Returns
        -------
        pixels : (N, 2) float64; x right, y down, origin at the top-left corner
            of the top-left pixel (pixel (i, j) covers [i, i+1) x [j, j+1)),
            matching ``Renderer.read_pixels`` (top row first).
        depth : (N,) float64, only when ``return_depth``.
        """
        w, h = float(size[0]), float(size[1])
        p = np.asarray(points_world, np.float64).reshape(-1, 3) - self.position
        cam = p @ self.rotation  # camera-space coordinates (R^T p per row)
        clip = cam @ self.projection(w / h)[:3, :3].T
        clip[:, 2] += self.projection(w / h)[2, 3]
        depth = -cam[:, 2]
        ww = np.where(np.abs(depth) < VIEW_EPS, VIEW_EPS, depth)
        ndc_x = clip[:, 0] / ww
        ndc_y = clip[:, 1] / ww
        px = np.stack([(ndc_x + 1.0) * 0.5 * w, (1.0 - ndc_y) * 0.5 * h], axis=1)
        if return_depth:
            return px, depth
        return px
