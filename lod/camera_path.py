"""Keyed camera paths: smooth interpolation of camera position and target over time.

A path is a list of keys ``(time, position, target)``. Between keys, position
and target each follow a Catmull-Rom spline whose knots are the key *times*
(the non-uniform Catmull-Rom of Barry & Goldman's pyramidal formulation,
parametrised by time). With equally spaced key times it is the uniform
Catmull-Rom spline; with uneven spacing it stays C1 *in time*, so the camera's
velocity never jumps at a key. The curve passes through every key exactly.

Ends: the path is clamped — before the first key the camera holds the first
pose, after the last key the last pose. Phantom end points are the reflections
``P[-1] = 2 P[0] - P[1]`` (at time ``2 t[0] - t[1]``) and likewise at the end,
so a two-key path moves linearly and a one-key path is a fixed camera.

Files (JSON) hold a list of ``{"time": s, "position": [x, y, z], "target": [x, y, z]}``
(or an object ``{"keys": [...]}``); :func:`save_path` writes the plain list.

References
----------
P. J. Barry and R. N. Goldman, "A recursive evaluation algorithm for a class of
Catmull-Rom splines", SIGGRAPH 1988, §3 (the pyramidal evaluation used in
:func:`catmull_rom`).
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from sim.atomic_io import atomic_open


class CameraPathError(ValueError):
    """A malformed camera path (keys or file); the message says what is wrong."""


def catmull_rom(times: np.ndarray, points: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Evaluate the time-knotted Catmull-Rom spline through ``points`` at ``t``.

    Parameters
    ----------
    times : (K,) float64, strictly increasing key times (K >= 1)
    points : (K, D) float64, key values
    t : (M,) float64, query times (clamped to [times[0], times[-1]])

    Returns
    -------
    (M, D) float64

    Notes
    -----
    Barry & Goldman 1988, §3: three levels of linear interpolation between the
    four points around the segment, with the key times as knots.
    """
    times = np.asarray(times, np.float64)
    pts = np.asarray(points, np.float64)
    t = np.atleast_1d(np.asarray(t, np.float64))
    k = times.shape[0]
    if k == 1:
        return np.broadcast_to(pts[0], (t.shape[0], pts.shape[1])).copy()
    t = np.clip(t, times[0], times[-1])
    # padded knots and points: reflected phantoms at both ends
    kt = np.concatenate([[2 * times[0] - times[1]], times, [2 * times[-1] - times[-2]]])
    kp = np.concatenate([[2 * pts[0] - pts[1]], pts, [2 * pts[-1] - pts[-2]]])
    seg = np.clip(np.searchsorted(times, t, side="right") - 1, 0, k - 2)  # segment [seg, seg+1] in key indices
    i = seg + 1  # index of P1 in the padded arrays
    t0, t1, t2, t3 = kt[i - 1], kt[i], kt[i + 1], kt[i + 2]
    p0, p1, p2, p3 = kp[i - 1], kp[i], kp[i + 1], kp[i + 2]
    tc = t[:, None]

    def lerp(pa, pb, ta, tb):
        w = ((tc - ta[:, None]) / (tb - ta)[:, None])
        return pa + (pb - pa) * w

    a1 = lerp(p0, p1, t0, t1)
    a2 = lerp(p1, p2, t1, t2)
    a3 = lerp(p2, p3, t2, t3)
    b1 = lerp(a1, a2, t0, t2)
    b2 = lerp(a2, a3, t1, t3)
    return lerp(b1, b2, t1, t2)


class CameraPath:
    """A smooth camera path through keyed poses.

    Parameters
    ----------
    keys : sequence of (time, position, target) or of dicts with those names.
        At least one key; times finite, >= 0 and strictly increasing;
        positions/targets three finite numbers, a key's position != its target.

    Attributes
    ----------
    times : (K,) float64
    positions : (K, 3) float64
    targets : (K, 3) float64
    """

    def __init__(self, keys):
        keys = list(keys)
        if not keys:
            raise CameraPathError("a camera path needs at least one key")
        times, pos, tgt = [], [], []
        for i, key in enumerate(keys):
            if isinstance(key, dict):
                missing = [n for n in ("time", "position", "target") if n not in key]
                if missing:
                    raise CameraPathError(f"key {i}: missing {', '.join(missing)}")
                extra = sorted(set(key) - {"time", "position", "target"})
                if extra:
                    raise CameraPathError(f"key {i}: unknown field {extra[0]!r}; accepted: time, position, target")
                t, p, g = key["time"], key["position"], key["target"]
            else:
                try:
                    t, p, g = key
                except (TypeError, ValueError):
                    raise CameraPathError(f"key {i}: expected (time, position, target), got {key!r}") from None
            if isinstance(t, bool) or not isinstance(t, (int, float, np.floating, np.integer)) or not math.isfinite(t):
                raise CameraPathError(f"key {i}: time must be a finite number, got {t!r}")
            for name, v in (("position", p), ("target", g)):
                a = np.asarray(v, dtype=object)
                if a.shape != (3,) or not all(isinstance(x, (int, float, np.floating, np.integer))
                                              and not isinstance(x, bool) and math.isfinite(x) for x in a):
                    raise CameraPathError(f"key {i}: {name} must be three finite numbers, got {v!r}")
            if times and float(t) <= times[-1]:
                raise CameraPathError(f"key {i}: times must be strictly increasing, got {t} after {times[-1]}")
            if np.array_equal(np.asarray(p, float), np.asarray(g, float)):
                raise CameraPathError(f"key {i}: position and target must differ")
            times.append(float(t))
            pos.append(np.asarray(p, np.float64))
            tgt.append(np.asarray(g, np.float64))
        self.times = np.asarray(times, np.float64)
        self.positions = np.stack(pos)
        self.targets = np.stack(tgt)

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])

    def keys(self) -> list:
        """The keys as a list of dicts (JSON-ready)."""
        return [{"time": float(t), "position": p.tolist(), "target": g.tolist()}
                for t, p, g in zip(self.times, self.positions, self.targets)]

    def pose_at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Interpolated (position, target) at time(s) ``t``.

        Returns (3,) arrays for a scalar ``t``, (M, 3) for an array. When the
        spline brings position and target together (possible between keys),
        the target is placed one metre along the nearest key's view direction
        so the view stays defined.
        """
        scalar = np.ndim(t) == 0
        tt = np.atleast_1d(np.asarray(t, np.float64))
        p = catmull_rom(self.times, self.positions, tt)
        g = catmull_rom(self.times, self.targets, tt)
        d = np.linalg.norm(g - p, axis=1)
        bad = ~(d > 1e-9)
        if bad.any():
            near = np.abs(tt[bad, None] - self.times[None, :]).argmin(axis=1)
            v = self.targets[near] - self.positions[near]
            g[bad] = p[bad] + v / np.linalg.norm(v, axis=1, keepdims=True)
        return (p[0], g[0]) if scalar else (p, g)

    def camera_at(self, t: float, fov_y: float = 50.0, near: float = 0.1, far: float = 1000.0):
        """The :class:`lod.view.Camera` at time ``t`` (seconds), looking from position to target."""
        from lod.view import Camera

        p, g = self.pose_at(float(t))
        return Camera.look_at(p, g, fov_y=fov_y, near=near, far=far)

    # -- files -----------------------------------------------------------------------------------------------------
    @classmethod
    def from_json(cls, data) -> "CameraPath":
        if isinstance(data, dict):
            if "keys" not in data:
                raise CameraPathError("expected a list of keys or an object with `keys`")
            data = data["keys"]
        if not isinstance(data, list):
            raise CameraPathError(f"expected a list of keys {{time, position, target}}, got {type(data).__name__}")
        return cls(data)


def load_path(path: str | os.PathLike) -> CameraPath:
    """Read a camera path from a JSON file; CameraPathError names the problem."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CameraPathError(f"file not found: {path}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CameraPathError(f"not valid JSON: {e}") from None
    return CameraPath.from_json(data)


def save_path(path: str | os.PathLike, camera_path: CameraPath) -> None:
    """Write ``camera_path`` as JSON, atomically (temp file in the same folder + rename)."""
    with atomic_open(path, "w") as f:
        json.dump(camera_path.keys(), f, indent=1)
        f.write("\n")
