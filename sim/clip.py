"""Skeletal animation clips: per-joint translation / rotation / scale keys.

Interpolation modes follow glTF 2.0: LINEAR (slerp for rotations), STEP and
CUBICSPLINE (Hermite with in/out tangents).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Channel:
    """Keys of one joint property.

    joint : int
    path : "translation" | "rotation" | "scale"
    times : (K,) float64, strictly increasing
    values : (K, C) float64, C = 3 or 4; for CUBICSPLINE (K, 3, C) as
        (in-tangent, value, out-tangent).
    interpolation : "LINEAR" | "STEP" | "CUBICSPLINE"
    """

    joint: int
    path: str
    times: np.ndarray
    values: np.ndarray
    interpolation: str = "LINEAR"


@dataclass
class Clip:
    """A named animation of a skeleton.

    duration : float, seconds (> 0); sampling wraps modulo duration when ``loop``.
    """

    name: str
    duration: float
    channels: list = field(default_factory=list)
    loop: bool = True

    def sample(self, skeleton, t: float):
        """Local TRS of every joint at time t (seconds): (J,3), (J,4), (J,3) float64.

        Joints without a channel keep their rest values.
        """
        raise NotImplementedError
