"""Planted feet for replayed people (issue 47, item 3): the stance foot held where it landed.

Advancing the walk clip by the recorded speed (``sim.replay.track``) makes a straight walk at constant speed step
without sliding; what a recording does beyond that (turning on the stance foot, speeding up within a step, the
sway of a tracked head, shuffling in a jam) moves the body under a foot that bears its weight. Games plant the
foot instead and let the body give way: here the drawn body stands off its recorded position by a small *offset*
(floor plane) chosen so that the stance foot stays put, and the offset returns to the recording while no foot is
planted.

Per person, each frame (after ``animation`` has advanced the clip, before ``terrain_follow``):

- the clip's contact points (the lower of each foot's foot and toe joints, ``sim.replay.feet.contact_points``) and
  whether each foot is down (within ``STANCE_HEIGHT`` of its lowest over the clip, the measure's own rule, with
  :data:`DOWN_MARGIN` more so the plant covers every frame the measure counts) come from a table sampled at
  :data:`SAMPLES` times over the clip, linear in between;
- a planted foot that is still down keeps its world point (the *anchor*): offset = anchor - recorded position -
  the foot's point turned by the heading and scaled; at most :data:`MAX_OFFSET` from the recording (beyond it the
  foot slides by the excess: the recording is not left further than that);
- otherwise the first foot that is down is planted where it is now; with no foot down the offset shrinks towards
  nothing at :data:`RETURN_SPEED`.

The drawn position is the recorded one plus the offset (:meth:`Planting.drawn`, which the engine draws: the
world's state keeps the recorded positions, so ``trajectories.txt``, the report's measures and every effect see
the recording itself); the clip's phase is the one change to the state. Characters
without ``l_foot``/``l_toe``/``r_foot``/``r_toe`` joints (``sim.replay.feet.feet_joints``) are left as
recorded. Measured by ``scripts/bench_foot_drift.py``.
"""
from __future__ import annotations

import copy
import math

import numpy as np
from numba import njit, prange

from sim.angles import sincos_fast
from sim.replay.feet import STANCE_HEIGHT, contact_points, feet_joints

#: samples of a clip's contact points and down flags
SAMPLES = 256
#: extra height (metres, model space) under which a foot counts as down for planting
DOWN_MARGIN = 0.005
#: how far (metres) the drawn body may stand off its recorded position
MAX_OFFSET = 0.2
#: how fast (m/s) the offset returns to the recording while no foot is down
RETURN_SPEED = 0.5
#: feet a table holds per clip
MAX_FEET = 2
#: fastest the clip may run (clip seconds per second) while a planted foot sets its phase
PHASE_RATE_MAX = 3.0


class FeetTable:
    """Per (character, clip): contact points ``contact`` (C, M, SAMPLES, MAX_FEET, 2) model-space x, z; ``down``
    (C, M, SAMPLES, MAX_FEET) bool; ``feet`` (C, M) int feet of the pair (0: not planted); ``duration`` (C, M)."""

    def __init__(self, characters):
        clips = [list((getattr(c, "clips", None) or {}).values()) for c in characters]
        C, M = max(len(characters), 1), max([len(c) for c in clips] + [1])
        self.contact = np.zeros((C, M, SAMPLES, MAX_FEET, 2), np.float64)
        self.down = np.zeros((C, M, SAMPLES, MAX_FEET), np.bool_)
        self.feet = np.zeros((C, M), np.int64)
        self.duration = np.zeros((C, M), np.float64)
        for h, (ch, cl) in enumerate(zip(characters, clips)):
            skeleton = getattr(ch, "skeleton", None)
            feet = feet_joints(skeleton)[:MAX_FEET] if skeleton is not None else []
            for m, clip in enumerate(cl):
                d = float(getattr(clip, "duration", 0.0) or 0.0)
                if not feet or not (np.isfinite(d) and d > 0):
                    continue
                pts = contact_points(skeleton, clip, np.arange(SAMPLES) * (d / SAMPLES), feet)  # (K, F, 3)
                if not np.isfinite(pts).all():
                    continue
                lowest = pts[:, :, 1].min(axis=0)
                self.contact[h, m, :, :len(feet)] = pts[:, :, [0, 2]]
                self.down[h, m, :, :len(feet)] = pts[:, :, 1] <= lowest + STANCE_HEIGHT + DOWN_MARGIN
                self.feet[h, m] = len(feet)
                self.duration[h, m] = d

    @property
    def any(self) -> bool:
        return bool((self.feet > 0).any())


class Planting:
    """The per-agent plant state: ``lock`` (n,) int8 planted foot (-1: none), ``anchor`` (n, 2) its world x, z,
    ``offset`` (n, 2) the drawn position less the recorded one."""

    def __init__(self, table: FeetTable, n: int):
        self.table = table
        self.lock = np.full(n, -1, np.int8)
        self.anchor = np.zeros((n, 2), np.float64)
        self.offset = np.zeros((n, 2), np.float64)
        self._drawn = None  # the drawn positions' buffer (drawn)

    def remap_agents(self, src, state=None) -> None:
        from sim.population import remap_rows

        self.lock = remap_rows(self.lock, src, -1)
        self.anchor = remap_rows(self.anchor, src, 0.0)
        self.offset = remap_rows(self.offset, src, 0.0)

    def drawn(self, state):
        """A shallow copy of ``state`` whose positions are the drawn ones (recorded plus offset, into a buffer
        kept from frame to frame; the other arrays shared)."""
        n = state.position.shape[0]
        if self._drawn is None or self._drawn.shape[0] != n:
            self._drawn = np.empty((n, 3), np.float64)
        _drawn_kernel(state.position, self.offset, self._drawn)
        out = copy.copy(state)
        out.position = self._drawn
        return out

    def step(self, state, track: np.ndarray, planted: np.ndarray, dt: float) -> None:
        """Plant the feet of the agents of tracks ``track`` (n,) int (-1: none) where ``planted`` (tracks,) bool
        says so, at their recorded positions (``state.position``), setting their offsets and, while a foot is
        planted, their clips' phase (module docstring)."""
        t = self.table
        _plant_kernel(np.asarray(track, np.int32), np.asarray(planted, np.bool_), state.character, state.clip,
                      state.anim_time, state.anim_rate, state.heading, state.scale, t.contact, t.down, t.feet,
                      t.duration, float(MAX_OFFSET), float(max(dt, 0.0)), float(RETURN_SPEED), float(PHASE_RATE_MAX),
                      state.position, self.lock, self.anchor, self.offset)


@njit(cache=True, parallel=True)
def _drawn_kernel(position, offset, out):  # pragma: no cover - compiled
    """``out`` = ``position`` plus the floor-plane ``offset`` (:meth:`Planting.drawn`)."""
    for i in prange(position.shape[0]):
        out[i, 0] = position[i, 0] + offset[i, 0]
        out[i, 1] = position[i, 1]
        out[i, 2] = position[i, 2] + offset[i, 1]


@njit(cache=True, inline="always")
def _foot(contact, h, m, k0, k1, a, f, c, s):
    """World x, z of foot ``f`` relative to the body: the sampled contact point (linear between samples ``k0``
    and ``k1``) turned by the heading (``c``, ``s``: cos and sin times the scale; ``lod.full.pack.model_rows``)."""
    px = contact[h, m, k0, f, 0] * (1.0 - a) + contact[h, m, k1, f, 0] * a
    pz = contact[h, m, k0, f, 1] * (1.0 - a) + contact[h, m, k1, f, 1] * a
    return c * px + s * pz, -s * px + c * pz


@njit(cache=True, inline="always")
def _contact_z(contact, h, m, u, f, K):
    """Model-space z of foot ``f``'s contact point at sample position ``u`` (any real: wraps over the clip)."""
    fl = math.floor(u)
    a = u - fl
    k0 = int(fl) % K
    if k0 < 0:
        k0 += K
    k1 = (k0 + 1) % K
    return contact[h, m, k0, f, 1] * (1.0 - a) + contact[h, m, k1, f, 1] * a, k0, k1


@njit(cache=True, inline="always")
def _stance_phase(contact, h, m, u0, du_max, f, K, pz):
    """The sample position in ``u0 .. u0 + du_max`` at which foot ``f``'s contact z (falling through a stance as
    the body walks over it) reaches ``pz``: a few secant steps on the sampled curve; ``u0`` when it lies ahead."""
    u = u0
    for _ in range(4):
        z, k0, k1 = _contact_z(contact, h, m, u, f, K)
        slope = contact[h, m, k1, f, 1] - contact[h, m, k0, f, 1]
        if z <= pz or slope >= 0.0:
            break
        u_next = min(u + (pz - z) / slope, u0 + du_max)
        if u_next <= u:
            break
        u = u_next
        if u >= u0 + du_max:
            break
    return u


@njit(cache=True, parallel=True)
def _plant_kernel(track, planted, character, clip, anim_time, anim_rate, heading, scale, contact, down, feet,
                  duration, max_off, dt, back_speed, rate_max, position, lock, anchor,
                  offset):  # pragma: no cover - compiled
    """:meth:`Planting.step` (module docstring)."""
    C, M = feet.shape
    K = contact.shape[2]
    T = planted.shape[0]
    for i in prange(position.shape[0]):
        k = track[i]
        if k < 0 or k >= T or not planted[k]:
            continue
        h, m = character[i], clip[i]
        nf = feet[h, m] if 0 <= h < C and 0 <= m < M else 0
        if nf == 0 or not math.isfinite(anim_time[i]):
            lock[i] = -1
            offset[i, 0] = 0.0
            offset[i, 1] = 0.0
            continue
        dur = duration[h, m]
        sc = float(scale[i])
        s, c = sincos_fast(heading[i])
        c *= sc
        s *= sc
        rx, rz = position[i, 0], position[i, 2]
        ox, oz = offset[i, 0], offset[i, 1]
        f = lock[i]
        u = anim_time[i] / dur * K
        rate = float(anim_rate[i])
        if f >= 0 and f < nf and rate >= 0.0 and sc > 0.0:
            # a planted foot sets the stance's phase: where along its stance the anchor lies under the body
            # (the clip's own advance this frame undone, then moved on to that point, never back)
            u0 = u - rate * dt * K / dur
            dx, dz = anchor[i, 0] - rx, anchor[i, 1] - rz
            pz = (s * dx + c * dz) / (sc * sc)
            u = _stance_phase(contact, h, m, u0, rate_max * dt * K / dur, f, K, pz)
            t = (u / K) * dur
            t = t - math.floor(t / dur) * dur
            anim_time[i] = t if t < dur else 0.0
            u = anim_time[i] / dur * K
        fl = math.floor(u)
        a = u - fl
        k0 = int(fl) % K
        k1 = (k0 + 1) % K
        kn = k1 if a >= 0.5 else k0  # the nearest sample tells down or not
        if f >= 0 and f < nf and down[h, m, kn, f]:  # still down: hold its anchor
            wx, wz = _foot(contact, h, m, k0, k1, a, f, c, s)
            ox = anchor[i, 0] - rx - wx
            oz = anchor[i, 1] - rz - wz
            d = math.sqrt(ox * ox + oz * oz)
            if d > max_off:  # the recording pulls further: the foot gives way by the excess
                ox *= max_off / d
                oz *= max_off / d
                anchor[i, 0] = rx + ox + wx
                anchor[i, 1] = rz + oz + wz
        else:
            f = -1
            for g in range(nf):
                if down[h, m, kn, g]:
                    f = g
                    break
            if f >= 0:  # a foot lands: plant it where it is
                wx, wz = _foot(contact, h, m, k0, k1, a, f, c, s)
                anchor[i, 0] = rx + ox + wx
                anchor[i, 1] = rz + oz + wz
            else:  # in the air: back towards the recording
                d = math.sqrt(ox * ox + oz * oz)
                shrink = max(d - back_speed * dt, 0.0) / d if d > 0 else 0.0
                ox *= shrink
                oz *= shrink
        lock[i] = f
        offset[i, 0] = ox
        offset[i, 1] = oz


__all__ = ["FeetTable", "MAX_OFFSET", "Planting", "RETURN_SPEED"]
