"""Keyframe animations of triangle meshes (Wand & Straßer 2002, §3).

A keyframe animation is a sequence of triangle meshes of arbitrary topology.
Between consecutive keyframes k and k+1, every vertex is matched with a vertex
of the other keyframe and all vertex attributes move linearly. Triangles can
appear or vanish at a keyframe: a vertex of one keyframe blends to three
positions of the next (Fig. 1), so a new triangle grows out of a point.

The canonical form used by every later layer is the *segment*: for one pair of
keyframes, a vertex list where each vertex is a (source vertex in k,
destination vertex in k+1) pair, and one index buffer over those vertices.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Keyframe:
    """One keyframe mesh.

    positions : (V_k, 3) float32; normals : (V_k, 3) float32;
    colors : (V_k, 4) float32; indices : (T_k, 3) uint32.
    """

    positions: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    indices: np.ndarray


@dataclass
class Segment:
    """Vertex correspondences between keyframe k and k+1.

    src : (S,) int32, vertex of keyframe k for each segment vertex
    dst : (S,) int32, vertex of keyframe k+1 for each segment vertex
    indices : (T_s, 3) uint32 into the segment vertices (union of both
        keyframes' triangles; a triangle that exists only at one end collapses
        to a point at the other end).
    """

    src: np.ndarray
    dst: np.ndarray
    indices: np.ndarray


@dataclass
class KeyframeAnimation:
    """Keyframe meshes at times ``times`` with a segment per consecutive pair.

    times : (K,) float64 strictly increasing, seconds.
    keyframes : list of K Keyframe
    segments : list of K-1 Segment (K segments when ``loop``: the last pairs
        keyframe K-1 with keyframe 0, ending at ``duration``).
    duration : float; loop period when ``loop``.
    """

    name: str
    times: np.ndarray
    keyframes: list
    segments: list
    duration: float
    loop: bool = True

    def locate(self, t: float) -> tuple[int, float]:
        """Segment index and local parameter u in [0, 1] at time t."""
        raise NotImplementedError

    def interpolate(self, t: float):
        """(positions (S,3), normals (S,3), colors (S,4), indices) of the segment active at t."""
        raise NotImplementedError
