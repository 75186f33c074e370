"""Skeletal animation clips: per-joint translation / rotation / scale keys,
and morph target weights.

Interpolation modes follow glTF 2.0 (§3.11, Appendix C): LINEAR (slerp for
rotations), STEP and CUBICSPLINE (Hermite with in/out tangents). A channel of
path ``"weights"`` animates the weights of a run of morph targets
(:class:`sim.mesh.MorphTargets`, glTF §3.7.2.2), sampled by
:meth:`Clip.morph_weights`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim import math3d

PATHS = ("translation", "rotation", "scale", "weights")
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")


@dataclass
class Channel:
    """Keys of one joint property, or of morph target weights.

    joint : int, the joint index; for path "weights" the first morph target
        whose weight the C columns set (targets ``joint .. joint + C - 1``)
    path : "translation" | "rotation" | "scale" | "weights"
    times : (K,) float64, strictly increasing
    values : (K, C) float64, C = 3 or 4 (weights: C targets); for CUBICSPLINE
        (K, 3, C) as (in-tangent, value, out-tangent).
    interpolation : "LINEAR" | "STEP" | "CUBICSPLINE"
    """

    joint: int
    path: str
    times: np.ndarray
    values: np.ndarray
    interpolation: str = "LINEAR"

    def sample(self, t) -> np.ndarray:
        """Values at times ``t`` (N,) -> (N, C) float64 (glTF 2.0 Appendix C).

        Times before the first key give the first value, after the last key the
        last value. LINEAR rotations use shortest-arc slerp; CUBICSPLINE uses
        the Hermite spline with tangents scaled by the key interval, and
        rotations are renormalised afterwards.
        """
        t = np.atleast_1d(np.asarray(t, np.float64))
        times = np.asarray(self.times, np.float64)
        vals = np.asarray(self.values, np.float64)
        if self.interpolation not in INTERPOLATIONS:
            raise ValueError(f"channel interpolation {self.interpolation!r}: expected one of {', '.join(INTERPOLATIONS)}")
        cubic = self.interpolation == "CUBICSPLINE"
        if cubic:
            vals = vals.reshape(times.shape[0], 3, -1)
            points = vals[:, 1]
        else:
            points = vals.reshape(times.shape[0], -1)
        K = times.shape[0]
        rot = self.path == "rotation"
        if K == 0:
            raise ValueError(f"channel of joint {self.joint} ({self.path}) has no keys")
        if K == 1:
            out = np.broadcast_to(points[0], (t.shape[0], points.shape[1])).copy()
            return math3d.quat_normalize(out) if rot else out
        if self.interpolation == "STEP":
            k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, K - 1)
            out = points[k].copy()
            return math3d.quat_normalize(out) if rot else out
        k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, K - 2)
        td = times[k + 1] - times[k]
        u = np.clip((t - times[k]) / np.where(td > 0, td, 1.0), 0.0, 1.0)
        if cubic:
            u2, u3 = u * u, u * u * u
            h00 = 2 * u3 - 3 * u2 + 1
            h10 = u3 - 2 * u2 + u
            h01 = -2 * u3 + 3 * u2
            h11 = u3 - u2
            out = (h00[:, None] * points[k] + (h10 * td)[:, None] * vals[k, 2]
                   + h01[:, None] * points[k + 1] + (h11 * td)[:, None] * vals[k + 1, 0])
            return math3d.quat_normalize(out) if rot else out
        if rot:
            return math3d.quat_slerp(points[k], points[k + 1], u)
        return points[k] * (1.0 - u)[:, None] + points[k + 1] * u[:, None]


@dataclass
class Clip:
    """A named animation of a skeleton.

    duration : float, seconds (> 0); sampling wraps modulo duration when ``loop``.
        A zero duration is tolerated (every time samples t = 0).
    speed : float, natural ground speed in m/s at playback rate 1 (0 when the
        clip does not travel, e.g. idle or imported clips): the simulation
        advances the phase by distance / speed so feet do not skate.
    """

    name: str
    duration: float
    channels: list = field(default_factory=list)
    loop: bool = True
    speed: float = 0.0

    def local_time(self, t) -> np.ndarray:
        """Clip-local times (float64, same shape as ``t``): wrapped modulo the
        duration when ``loop``, clamped to [0, duration] otherwise."""
        t = np.asarray(t, np.float64)
        d = float(self.duration)
        if not (d > 0.0) or not np.isfinite(d):
            return np.zeros_like(t)
        t = np.where(np.isfinite(t), t, 0.0)
        if self.loop:
            return np.mod(t, d)
        return np.clip(t, 0.0, d)

    def sample_times(self, skeleton, times):
        """Local TRS of every joint at many times.

        Parameters
        ----------
        skeleton : sim.skeleton.Skeleton
        times : (N,) float, seconds (wrapped/clamped by :meth:`local_time`)

        Returns
        -------
        translation (N, J, 3), rotation (N, J, 4), scale (N, J, 3), float64.
            Joints without a channel keep their rest values.
        """
        tl = np.atleast_1d(self.local_time(times)).reshape(-1)
        n = tl.shape[0]
        tr, rot, sc = skeleton.rest_pose()
        T = np.broadcast_to(np.asarray(tr, np.float64), (n,) + tr.shape).copy()
        R = np.broadcast_to(np.asarray(rot, np.float64), (n,) + rot.shape).copy()
        S = np.broadcast_to(np.asarray(sc, np.float64), (n,) + sc.shape).copy()
        target = {"translation": T, "rotation": R, "scale": S}
        for ch in self.channels:
            if ch.path not in target:
                continue  # e.g. morph "weights": not a joint property
            if not 0 <= ch.joint < skeleton.n_joints:
                raise ValueError(f"clip {self.name!r}: channel joint {ch.joint} outside 0..{skeleton.n_joints - 1}")
            target[ch.path][:, ch.joint, :] = ch.sample(tl)
        return T, R, S

    def sample(self, skeleton, t: float):
        """Local TRS of every joint at time t (seconds): (J,3), (J,4), (J,3) float64.

        Joints without a channel keep their rest values.
        """
        T, R, S = self.sample_times(skeleton, np.array([t], np.float64))
        return T[0], R[0], S[0]

    def has_morph_weights(self) -> bool:
        """True when a channel animates morph target weights."""
        return any(ch.path == "weights" for ch in self.channels)

    def morph_weights(self, morph, times) -> np.ndarray:
        """Morph target weights at many times (glTF 2.0 §3.11, Appendix C).

        Parameters
        ----------
        morph : sim.mesh.MorphTargets (or anything with ``default_weights``)
        times : (N,) float, seconds (wrapped/clamped by :meth:`local_time`)

        Returns
        -------
        (N, M) float64: the channels' values, the default weight for targets
        no channel of this clip drives.
        """
        tl = np.atleast_1d(self.local_time(times)).reshape(-1)
        d = np.asarray(morph.default_weights, np.float64).reshape(-1)
        out = np.broadcast_to(d, (tl.shape[0], d.shape[0])).copy()
        for ch in self.channels:
            if ch.path != "weights":
                continue
            v = ch.sample(tl)
            a = int(ch.joint)
            if a < 0 or a + v.shape[1] > d.shape[0]:
                raise ValueError(f"clip {self.name!r}: weights channel drives targets {a}..{a + v.shape[1] - 1}, "
                                 f"the mesh has {d.shape[0]} morph targets")
            out[:, a:a + v.shape[1]] = v
        return out

    def skinning_matrices(self, skeleton, times) -> np.ndarray:
        """Skinning matrices at many times, (N, J, 4, 4) float64."""
        return skeleton.skinning_matrices(*self.sample_times(skeleton, times))


#: Name and duration (seconds) of the clip a character without animation is given (:func:`rest_clip`); the same
#: name and duration as the still keyframe animation of an unanimated morph-target model (``sim.gltf.load``).
REST_CLIP_NAME = "rest"
REST_CLIP_SECONDS = 1.0


def rest_clip(skeleton, name: str = REST_CLIP_NAME, duration: float = REST_CLIP_SECONDS) -> Clip:
    """A constant looping clip that holds ``skeleton``'s rest pose: one key, at t = 0, on joint 0's rotation.

    A character without animation (a statue, a prop) is a legitimate character: it is drawn in its rest pose.
    Giving it this clip, rather than teaching every consumer to accept zero clips, keeps one rule everywhere:
    every character has at least one clip and clip index 0 exists (``CrowdState.clip``, placements, the baked
    joint tables of mode ``none``, the pose samples of the point and cluster hierarchies, mode ``auto``). One
    real key (not an empty channel list) means code that reads key times also sees a well-formed clip.
    """
    if skeleton.n_joints < 1:
        raise ValueError("rest_clip: the skeleton has no joints")
    q = np.asarray(skeleton.rest_rotation, np.float64)[:1].copy()
    return Clip(name=name, duration=float(duration),
                channels=[Channel(joint=0, path="rotation", times=np.zeros(1), values=q, interpolation="STEP")],
                loop=True)
