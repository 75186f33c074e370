"""A long dance-like clip for any generated character: clips of any length without assets (issue 27's 35 s dance).

:func:`dance_clip` keys every joint's rotation at 30 Hz (LINEAR) for ``duration`` seconds, in sections of 2-6 s,
each a different move on a common beat (100-130 beats per minute): for the generated humanoid
(``sim.procedural.humanoid``'s joint names) arms swung out and overhead over two or four beats (up to 2.6 rad at
the shoulders, the elbows bending up to 1.8 rad; a brisk dance, at most about 5 rad/s), hips twisting and
swaying with the chest twisting back, knees lifted in turn, head nodding; for any other skeleton every joint turns on random axes by up to 0.4 rad. Consecutive sections
cross-fade over 0.3 s, so the motion never repeats and never jumps (within a section it is periodic on the
beat, as dances are). Deterministic for a seed.
"""
from __future__ import annotations

import numpy as np

from sim.clip import Channel, Clip

#: key rate (per second)
KEY_RATE = 30.0
#: cross-fade between sections (seconds)
FADE = 0.3


def _humanoid_moves(rng, names: dict, times: np.ndarray, beat: float) -> dict:
    """joint index -> (n, 3) Euler angles (X, Y, Z) of one section of the humanoid's dance."""
    w = 2.0 * np.pi / beat
    out = {}
    ph = rng.uniform(0.0, 2.0 * np.pi)
    up = rng.uniform(0.3, 2.6)  # how high the arms go (rad, sideways)
    fwd = rng.uniform(-0.9, 0.9)
    elbow = rng.uniform(0.0, 1.8)
    half = rng.choice([0.25, 0.5])  # arms over four beats or two (at most ~5 rad/s, a brisk dance)
    for side, sgn, off in (("l", 1.0, 0.0), ("r", -1.0, np.pi * rng.integers(0, 2))):
        a = np.zeros((times.size, 3))
        a[:, 2] = sgn * up * (0.7 + 0.3 * np.sin(half * w * times + ph + off))
        a[:, 0] = -fwd * np.sin(half * w * times + ph + off + 0.7)
        out[names[f"{side}_upper_arm"]] = a
        f = np.zeros((times.size, 3))
        f[:, 0] = -elbow * (0.5 + 0.5 * np.sin(half * w * times + ph + off + 1.3))
        out[names[f"{side}_forearm"]] = f
        lift = rng.uniform(0.0, 0.9)
        leg = 0.0 if side == "l" else np.pi
        t = np.zeros((times.size, 3))
        t[:, 0] = -lift * np.maximum(0.0, np.sin(0.5 * w * times + leg + ph))
        out[names[f"{side}_thigh"]] = t
        s = np.zeros((times.size, 3))
        s[:, 0] = 1.6 * lift * np.maximum(0.0, np.sin(0.5 * w * times + leg + ph))
        out[names[f"{side}_shin"]] = s
    twist, sway = rng.uniform(0.0, 0.5), rng.uniform(0.0, 0.15)
    hips = np.zeros((times.size, 3))
    hips[:, 1] = twist * np.sin(0.5 * w * times + ph)
    hips[:, 2] = sway * np.sin(w * times + ph)
    out[names["hips"]] = hips
    for j, k in (("spine", -0.4), ("chest", -0.6)):
        a = np.zeros((times.size, 3))
        a[:, 1] = k * twist * np.sin(0.5 * w * times + ph)
        a[:, 0] = rng.uniform(-0.15, 0.25)
        out[names[j]] = a
    head = np.zeros((times.size, 3))
    head[:, 0] = rng.uniform(0.05, 0.3) * np.sin(w * times + ph)
    out[names["head"]] = head
    return out


def _generic_moves(rng, J: int, times: np.ndarray, beat: float) -> dict:
    w = 2.0 * np.pi / beat
    out = {}
    for j in range(J):
        axis = rng.normal(size=3)
        axis /= max(np.linalg.norm(axis), 1e-9)
        amp = rng.uniform(0.0, 0.4)
        out[j] = amp * np.sin(rng.choice([0.5, 1.0]) * w * times + rng.uniform(0, 2 * np.pi))[:, None] * axis
    return out


def dance_clip(character, duration: float, seed: int = 0, name: str = "dance") -> Clip:
    """A looping ``duration``-second dance of ``character`` (a ``sim.character.SkinnedCharacter``; module
    docstring). Raises ValueError for a non-positive or non-finite duration."""
    from sim.procedural import _rot_channel

    d = float(duration)
    if not (d > 0.0) or not np.isfinite(d):
        raise ValueError(f"dance_clip: expected a positive duration, got {duration!r}")
    sk = character.skeleton
    names = {n: i for i, n in enumerate(sk.names)}
    humanoid = all(k in names for k in ("hips", "spine", "chest", "head", "l_upper_arm", "r_upper_arm",
                                        "l_forearm", "r_forearm", "l_thigh", "r_thigh", "l_shin", "r_shin"))
    rng = np.random.default_rng([int(seed), 0x44414E])
    times = np.arange(0.0, d, 1.0 / KEY_RATE)
    beat = 60.0 / rng.uniform(100.0, 130.0)
    J = sk.n_joints
    angles = np.zeros((J, times.size, 3))
    weight = np.zeros(times.size)
    t0 = 0.0
    while t0 < d:
        n = rng.uniform(2.0, 6.0)
        # the section's window with linear fades at both ends (a fade overlaps the neighbour's)
        win = np.clip(np.minimum((times - t0 + FADE) / FADE, (t0 + n + FADE - times) / FADE), 0.0, 1.0)
        moves = _humanoid_moves(rng, names, times, beat) if humanoid else _generic_moves(rng, J, times, beat)
        for j, a in moves.items():
            angles[j] += win[:, None] * a
        weight += win
        t0 += n
    angles /= np.maximum(weight, 1e-9)[None, :, None]
    rest_q = np.asarray(sk.rest_rotation, np.float64)
    chans = []
    from sim import math3d

    for j in range(J):
        if not np.any(angles[j]):
            continue
        c = _rot_channel(j, times, (angles[j, :, 0], angles[j, :, 1], angles[j, :, 2]))
        c.values = math3d.quat_multiply(np.broadcast_to(rest_q[j], c.values.shape), c.values)  # on the rest pose
        chans.append(c)
    return Clip(name, d, chans, loop=True)


__all__ = ["dance_clip"]
