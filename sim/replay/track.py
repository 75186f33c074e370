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

from sim.replay.frames import Stream
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
    ``phase`` "random" starts each entering person's clip at a random time, "zero" at 0; ``feet`` "planted" or
    "recorded" (the placement's key)."""

    recording: Recording
    choices: np.ndarray
    scale: float = 1.0
    scale_jitter: float = 0.0
    phase: str = "random"
    rng: np.random.Generator | None = None
    #: "planted": the replay plants its people's stance feet (``sim.replay.planting``); "recorded": it does not
    feet: str = "planted"

    def __post_init__(self):
        c = np.asarray(self.choices, np.float64).reshape(-1, 5)
        if not c.shape[0] or not (c[:, 2] > 0).all():
            raise ValueError("Track.choices: expected at least one row, every weight > 0")
        self.choices = c
        self._p = c[:, 2] / c[:, 2].sum()
        self._stream = None  # the recording's frame-major stream (kinematic_rows), opened on first use

    @property
    def played(self) -> list:
        """``[(character, clip), ...]`` the people of this track can play."""
        return [(int(a), int(b)) for a, b in self.choices[:, :2]]

    def frame_at(self, tau: float) -> float:
        """The recorded frame at ``tau`` seconds after the recording's first frame."""
        rec = self.recording
        return rec.first_frame + float(tau) * rec.frame_rate

    def kinematics(self, persons: np.ndarray, frame: float) -> tuple:
        """``(xy (k, 2), velocity (k, 2))`` of ``persons`` at ``frame``, floor plane, metres and m/s
        (:meth:`kinematic_rows`)."""
        out = self.kinematic_rows(persons, frame)
        return out[:, :2], out[:, 2:]

    def kinematic_rows(self, persons: np.ndarray, frame: float) -> np.ndarray:
        """(k, 4) float64 rows (x, y, vx, vy) of ``persons`` at ``frame``: position and velocity, floor plane
        (module docstring), from the recording's frame-major stream (``sim.replay.frames``): a frame later than
        the last asked reads only the recorded frames passed since; an earlier one reads from the start again."""
        rec = self.recording
        return self.stream().rows(persons, frame, self.smoothing_frames(), rec.frame_rate)

    def stream(self) -> Stream:
        """The recording's frame-major stream (``sim.replay.frames``), opened on first use; the velocity's
        half-window is ``SMOOTHING_S`` seconds (:meth:`smoothing_frames`)."""
        if self._stream is None:
            rec = self.recording
            self._stream = Stream(rec.frame_table(), rec.first, rec.last, rec.first_xy)
        return self._stream

    def smoothing_frames(self) -> float:
        """``SMOOTHING_S`` in recorded frames."""
        return SMOOTHING_S * self.recording.frame_rate

    def overall_heading(self, persons: np.ndarray) -> np.ndarray:
        """(k,) yaw from each person's first to last recorded position (0 when they never moved)."""
        rec = self.recording
        p = np.asarray(persons, np.int64)
        d = rec.last_xy[p] - rec.first_xy[p]
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
        still = np.hypot(v[:, 0], v[:, 1]) <= HEADING_MIN_SPEED
        st.heading[:] = np.arctan2(v[:, 0], v[:, 1])
        if still.any():
            st.heading[still] = self.overall_heading(p[still])
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


__all__ = ["HEADING_MIN_SPEED", "SMOOTHING_S", "Track"]
