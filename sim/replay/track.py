"""A ``[[placement]] kind = "trajectories"``: its recording, the character its people are drawn as, and how a
recorded person becomes an agent at a frame (issue 46).

Axes: a recording's floor plane (PedPy's x, y) is the sandbox's (x, z), as ``crowd run`` writes
``trajectories.txt`` (``crowd.trajectories``), so a run's own file replays in place; heights are left to the
scene (0, or the terrain's with ``terrain_follow``).

Clock: the recording's time ``tau`` (seconds after its first frame) is the world's time at the end of the frame
less one frame, so the first frame drawn (the state after the first step; ``trajectories.txt``'s frame 0) shows the
recording's first frame, and frame ``k`` the recording at ``k dt`` (its frame ``k`` when the rates agree).

Kinematics: the velocity is the central difference of the interpolated positions ``SMOOTHING_S`` seconds either
side (clamped to the person's recorded span), which smooths PeTrack's frame-to-frame jitter; the heading follows
it only above ``HEADING_MIN_SPEED`` (a person standing keeps the heading they had: no spin on the spot; one who
enters standing faces the way they will go); the walk clip plays at the velocity's component along the heading
over the clip's natural speed (``sim.animation.ClipTable.speed``; backwards when the person steps back; a clip
without a natural speed plays at its authored rate): the stance foot travels back along the heading, so sideways
motion must not advance it. Measured on the bottleneck experiment (``scripts/bench_foot_drift.py``,
``sim.replay.feet``): the stance foot's drift per step, median 5.7 cm (95th percentile 25 cm) against 7.2 cm
(29 cm) at the ground speed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from sim.replay.recording import Recording
from sim.state import CrowdState

#: seconds either side of a frame over which the velocity is measured
SMOOTHING_S = 0.4
#: ground speed (m/s) below which a person keeps their heading
HEADING_MIN_SPEED = 0.2


@dataclass
class Track:
    """One trajectories placement: ``recording``, its people drawn as the characters of ``choices``, a (k, 5)
    array of rows (character, clip, weight, character scale, clip duration): each person who enters draws a row by
    weight (``rng``); ``scale`` (times the character's) and ``scale_jitter`` as the other placements' keys;
    ``phase`` "random" starts each entering person's clip at a random time, "zero" at 0."""

    recording: Recording
    choices: np.ndarray
    scale: float = 1.0
    scale_jitter: float = 0.0
    phase: str = "random"
    rng: np.random.Generator | None = None

    def __post_init__(self):
        c = np.asarray(self.choices, np.float64).reshape(-1, 5)
        if not c.shape[0] or not (c[:, 2] > 0).all():
            raise ValueError("Track.choices: expected at least one row, every weight > 0")
        self.choices = c
        self._p = c[:, 2] / c[:, 2].sum()

    @property
    def played(self) -> list:
        """``[(character, clip), ...]`` the people of this track can play."""
        return [(int(a), int(b)) for a, b in self.choices[:, :2]]

    def frame_at(self, tau: float) -> float:
        """The recorded frame at ``tau`` seconds after the recording's first frame."""
        rec = self.recording
        return rec.first_frame + float(tau) * rec.frame_rate

    def kinematics(self, persons: np.ndarray, frame: float, cursors: np.ndarray | None = None) -> tuple:
        """``(xy (k, 2), velocity (k, 2))`` of ``persons`` at ``frame``, floor plane, metres and m/s
        (:meth:`kinematic_rows`)."""
        out = self.kinematic_rows(persons, frame, cursors)
        return out[:, :2], out[:, 2:]

    def kinematic_rows(self, persons: np.ndarray, frame: float, cursors: np.ndarray | None = None) -> np.ndarray:
        """(k, 4) float64 rows (x, y, vx, vy) of ``persons`` at ``frame``: position and velocity, floor plane.

        ``cursors`` (k, 3) int64: each person's rows at ``frame`` - w, ``frame`` and ``frame`` + w from an
        earlier call (moved forward in place: a frame later than the last costs a step or two, not a search;
        -1: none yet). None: searched from each person's first row."""
        rec = self.recording
        p = np.ascontiguousarray(persons, np.int64)
        cur = np.full((p.shape[0], 3), -1, np.int64) if cursors is None else cursors
        out = np.empty((p.shape[0], 4), np.float64)
        if p.shape[0]:
            _kinematics_kernel(p, np.asarray(rec.start), np.asarray(rec.frames), np.asarray(rec.xy), cur,
                               float(frame), SMOOTHING_S * rec.frame_rate, float(rec.frame_rate), out)
        return out

    def overall_heading(self, persons: np.ndarray) -> np.ndarray:
        """(k,) yaw from each person's first to last recorded position (0 when they never moved)."""
        rec = self.recording
        p = np.asarray(persons, np.int64)
        d = rec.xy[rec.start[p + 1] - 1] - rec.xy[rec.start[p]]
        moved = np.hypot(d[:, 0], d[:, 1]) > 1e-6
        return np.where(moved, np.arctan2(d[:, 0], d[:, 1]), 0.0)

    def agents(self, persons: np.ndarray, frame: float) -> CrowdState:
        """New agents standing for ``persons`` at ``frame`` (their positions, velocities, headings, clip and
        scale); the replay step sets their animation rate."""
        p = np.asarray(persons, np.int64)
        n = p.shape[0]
        st = CrowdState.empty(n)
        xy, v = self.kinematics(p, frame)
        st.position[:, 0] = xy[:, 0]
        st.position[:, 2] = xy[:, 1]
        st.velocity[:, 0] = v[:, 0]
        st.velocity[:, 2] = v[:, 1]
        moving = np.hypot(v[:, 0], v[:, 1]) > HEADING_MIN_SPEED
        st.heading[:] = np.where(moving, np.arctan2(v[:, 0], v[:, 1]), self.overall_heading(p))
        rng = self.rng if self.rng is not None else np.random.default_rng(0)
        row = self.choices[rng.choice(self.choices.shape[0], size=n, p=self._p) if self.choices.shape[0] > 1
                           else np.zeros(n, np.int64)]
        j = float(self.scale_jitter)
        base = self.scale * row[:, 3]
        st.scale[:] = (base * (1.0 + j * rng.uniform(-1.0, 1.0, n))) if j > 0 else base
        st.character[:] = row[:, 0].astype(np.int32)
        st.clip[:] = row[:, 1].astype(np.int16)
        if self.phase == "random" and n:
            span = np.where(row[:, 4] > 0, row[:, 4], 1.0)
            st.anim_time[:] = rng.uniform(0.0, 1.0, n) * span
        return st


@njit(cache=True, inline="always")
def _seek(frames, xy, lo, hi, c, q):
    """``(row, x, y)``: the person's position at frame ``q`` (within its rows ``lo .. hi``), linear between the
    last row at or before ``q`` and the next, found from row ``c`` onwards (from ``lo`` when ``c`` is none or lies
    after ``q``). The arithmetic of :meth:`Recording.at`."""
    if c < lo or c > hi or frames[c] > q:
        c = lo
    while c < hi and frames[c + 1] <= q:
        c += 1
    c1 = c + 1 if c < hi else hi
    df = frames[c1] - frames[c]
    a = (q - frames[c]) / df if df > 0 else 0.0
    return c, xy[c, 0] * (1.0 - a) + xy[c1, 0] * a, xy[c, 1] * (1.0 - a) + xy[c1, 1] * a


@njit(cache=True, parallel=True)
def _kinematics_kernel(persons, start, frames, xy, cur, frame, w, rate, out):  # pragma: no cover - compiled
    """Per person: position at ``frame`` and the velocity over ``frame`` -+ ``w`` (clamped to the person's rows),
    ``out`` rows (x, y, vx, vy); ``cur`` the three rows found, kept for the next frame (:meth:`Track.kinematics`)."""
    for a in prange(persons.shape[0]):
        p = persons[a]
        lo = start[p]
        hi = start[p + 1] - 1
        f_lo, f_hi = frames[lo], frames[hi]
        q = min(max(frame, f_lo), f_hi)
        qa = min(max(frame - w, f_lo), f_hi)
        qb = min(max(frame + w, f_lo), f_hi)
        c, x, y = _seek(frames, xy, lo, hi, cur[a, 1], q)
        ca, xa, ya = _seek(frames, xy, lo, hi, cur[a, 0], qa)
        cb, xb, yb = _seek(frames, xy, lo, hi, cur[a, 2], qb)
        cur[a, 0], cur[a, 1], cur[a, 2] = ca, c, cb
        span = (qb - qa) / rate
        out[a, 0], out[a, 1] = x, y
        out[a, 2] = (xb - xa) / span if span > 0 else 0.0
        out[a, 3] = (yb - ya) / span if span > 0 else 0.0


__all__ = ["HEADING_MIN_SPEED", "SMOOTHING_S", "Track"]
