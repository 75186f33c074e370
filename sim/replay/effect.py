"""Effect ``replay``: recorded people moved by their recording, entering at their first recorded frame and leaving
after their last (issue 46). Installed by the engine when a scene has a ``[[placement]] kind = "trajectories"``
(never listed in ``effects``).

Each step (sub-step) ``replay`` computes the recording's time (``sim.replay.track``'s clock), removes the agents
whose person's recording ended and adds those whose recording began (``sim.population.apply``: stable ids, the
other agents' arrays follow), then sets every recorded agent's position (floor plane), velocity, heading and
animation rate from its recording. It runs after every other step that moves agents and before ``animation`` and
``terrain_follow``, so the scene's other effects never move recorded people (simulated agents still see them:
avoidance avoids them), their clips advance by their walk along their heading and their height follows the terrain.

Resource ``world.resources["replay"]``: the :class:`Replay` (its tracks, which agent is which recorded person,
the frame's entered and left counts). A placement with ``feet = "planted"`` (the default) and a character with
feet adds step ``replay_feet`` after ``animation`` and resource ``world.resources["replay_feet"]``
(``sim.replay.planting``: the stance foot held where it landed, the drawn body at most 20 cm off the recording).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sim.angles import atan2_fast
from sim.params import Param, ParamError
from sim.replay.frames import kinematics
from sim.replay.recording import FRAME_EPS
from sim.replay.track import HEADING_MIN_SPEED, Track

#: the effect takes no scene-file keys (the placements carry the recordings)
PARAMS: dict[str, Param] = {}


class Replay:
    """The scene's tracks and, per agent, its track (-1: not recorded) and person within it."""

    def __init__(self, tracks: list, track: np.ndarray, person: np.ndarray, frame_dt: float):
        self.tracks = tracks
        self.track = np.asarray(track, np.int32)
        self.person = np.asarray(person, np.int64)
        self.frame_dt = float(frame_dt)
        self.entered = 0  # this frame's counts (take_frame_counts)
        self.left = 0
        self.total_entered = 0
        self.total_left = 0
        # persons that entered so far per track: a person enters once
        self.started = [np.zeros(t.recording.persons, bool) for t in tracks]
        for k, t in enumerate(tracks):
            self.started[k][self.person[self.track == k]] = True
        # per track, its persons by first and by last recorded frame and how many of each the clock has passed:
        # a frame in which nobody's recording begins or ends costs no pass over the agents
        self._by_first = [np.argsort(t.recording.first, kind="stable") for t in tracks]
        self._first_sorted = [t.recording.first[o] for t, o in zip(tracks, self._by_first)]
        self._last_sorted = [np.sort(t.recording.last) for t in tracks]
        self._passed_first = [0] * len(tracks)
        self._passed_last = [0] * len(tracks)
        self._rows = None  # per track, its agents' rows (None: find them again; the population changed)

    def remap_agents(self, src, state=None) -> None:
        from sim.population import remap_rows

        self.track = remap_rows(self.track, src, -1)  # entered agents: no track yet (step fills its own)
        self.person = remap_rows(self.person, src, -1)
        self._rows = None

    def take_frame_counts(self) -> dict:
        out = {"entered": self.entered, "left": self.left}
        self.entered = self.left = 0
        return out

    def summary(self) -> dict:
        return {"sources": [t.recording.source for t in self.tracks], "entered": self.total_entered,
                "left": self.total_left}

    # -- the step ------------------------------------------------------------------------------------------------
    def step(self, world, h: float) -> None:
        from sim.population import apply
        from sim.state import CrowdState

        tau = world.time + h - self.frame_dt
        frames = [t.frame_at(tau) for t in self.tracks]
        keep = None
        new, new_track, new_person = [], [], []
        for k, (t, f) in enumerate(zip(self.tracks, frames)):
            began, ended = self._passed(k, f)
            if ended:  # someone's recording ended: who leaves (Recording.alive), one pass over the agents
                alive = t.recording.alive(f)
                mine = self.track == k
                keep = np.ones(world.state.n, bool) if keep is None else keep
                keep[mine] = alive[self.person[mine]]
            if not began:
                continue
            cand = self._by_first[k][self._passed_first[k] - began:self._passed_first[k]]
            cand = cand[~self.started[k][cand]]
            enter = np.sort(cand[t.recording.alive(f)[cand]]) if cand.size else cand
            self.started[k][cand] = True  # (one whose recording began and ended between two frames never enters)
            if enter.size:
                new.append(t.agents(enter, f))
                new_track.append(np.full(enter.size, k, np.int32))
                new_person.append(enter)
        left = 0 if keep is None else int((~keep).sum())
        entered = sum(s.n for s in new)
        if left or entered:
            from sim.placement import concat_states

            added = concat_states(new) if new else CrowdState.empty(0)
            apply(world, None if not left else np.flatnonzero(keep), added)  # remaps track/person (-1 for new)
            self._rows = None
            if entered:
                self.track[-entered:] = np.concatenate(new_track)
                self.person[-entered:] = np.concatenate(new_person)
            self.left += left
            self.entered += entered
            self.total_left += left
            self.total_entered += entered
        self._move(world, frames)

    def _passed(self, k: int, f: float) -> tuple:
        """``(began, ended)``: how many of track ``k``'s persons' recordings began (first frame at or before
        ``f``) and ended (last frame before ``f``) since the last call (``Recording.alive``'s tolerance)."""
        a = int(np.searchsorted(self._first_sorted[k], f + FRAME_EPS, side="right"))
        b = int(np.searchsorted(self._last_sorted[k], f - FRAME_EPS, side="left"))
        began, ended = max(a - self._passed_first[k], 0), max(b - self._passed_last[k], 0)
        self._passed_first[k] = max(a, self._passed_first[k])
        self._passed_last[k] = max(b, self._passed_last[k])
        return began, ended

    def _move(self, world, frames: list) -> None:
        st = world.state
        speeds = np.ascontiguousarray(_clip_speeds(world), np.float64)
        if self._rows is None:
            self._rows = [np.flatnonzero(self.track == k) for k in range(len(self.tracks))]
        for k, (t, f) in enumerate(zip(self.tracks, frames)):
            idx = self._rows[k]
            if not idx.size:
                continue
            w = t.smoothing_frames()
            arrays = t.stream().seek(f, w)
            _place_kernel(idx, self.person, *arrays, float(f), float(w), float(t.recording.frame_rate), speeds,
                          st.character, st.clip, float(HEADING_MIN_SPEED), st.position, st.velocity, st.heading,
                          st.anim_rate)


@njit(cache=True, parallel=True)
def _place_kernel(idx, person, first, last, first_xy, sa, s, sb, frame, w, rate, speeds, character, clip,
                  min_speed, position, velocity, heading, anim_rate):  # pragma: no cover - compiled
    """Agents ``idx`` (persons ``person[idx]``) to their recorded floor positions and velocities at ``frame``
    (``sim.replay.frames.kinematics`` of the stream's arrays, read as they are placed); the heading follows the
    velocity above ``min_speed`` (kept below it: no spin standing); the clip advances by the walk along the
    heading over its natural speed (``speeds`` (C, M), by the agent's character and clip; a step back plays it
    backwards; 1 without a natural speed)."""
    C, M = speeds.shape
    for a in prange(idx.shape[0]):
        i = idx[a]
        x, y, vx, vy = kinematics(person[i], first, last, first_xy, sa, s, sb, frame, w, rate)
        position[i, 0] = x
        position[i, 2] = y
        velocity[i, 0] = vx
        velocity[i, 1] = 0.0
        velocity[i, 2] = vy
        speed = math.sqrt(vx * vx + vy * vy)
        if speed > min_speed:  # facing the walk: its speed is all along the heading
            heading[i] = atan2_fast(vx, vy)
            along = speed
        else:
            along = vx * math.sin(heading[i]) + vy * math.cos(heading[i])
        h, c = character[i], clip[i]
        n = speeds[h, c] if 0 <= h < C and 0 <= c < M else 0.0
        anim_rate[i] = along / n if n > 0 else 1.0


def _clip_speeds(world) -> np.ndarray:
    """(C, M) natural ground speeds of the characters' clips (``sim.animation.ClipTable``)."""
    from sim.animation import ClipTable

    table = world.resources.get("animation")
    if not isinstance(table, ClipTable) or table.n_characters != len(world.characters):
        table = ClipTable(world.characters)
    return table.speed


def install(world, cfg: dict) -> None:
    """Effect ``replay``: adds step ``"replay"`` (after every step installed before it, before ``animation`` and
    ``terrain_follow``) and ``world.resources["replay"]``.

    cfg: ``dt`` (the frame's seconds: the recording's clock, ``sim.replay.track``). The tracks come from the
    state: ``world.state.tracks`` = ``[(first agent, count, Track), ...]`` (``sim.placement.concat_states``).
    """
    entries = getattr(world.state, "tracks", None) or []
    if not entries:
        raise ParamError("effects", "effect 'replay' needs a [[placement]] of kind 'trajectories'")
    dt = float(cfg.get("dt", 0.0))
    if not dt > 0:
        raise ParamError("effects", "effect 'replay' needs the scene's dt")
    n = world.state.n
    track = np.full(n, -1, np.int32)
    person = np.full(n, -1, np.int64)
    tracks = []
    for k, (first, count, t, persons) in enumerate(entries):
        if not isinstance(t, Track):
            raise ParamError("effects", "effect 'replay': a track is not a sim.replay.Track")
        tracks.append(t)
        track[first:first + count] = k
        person[first:first + count] = persons
    replay = Replay(tracks, track, person, dt)
    world.resources["replay"] = replay
    others = tuple(s.name for s in world.schedule.steps if s.name not in ("animation", "terrain_follow"))
    world.schedule.add_step("replay", replay.step, after=others, before=("animation", "terrain_follow"))
    planted = np.array([t.feet == "planted" for t in tracks], bool)
    if planted.any():
        from sim.replay.planting import FeetTable, Planting

        table = FeetTable(world.characters)
        if table.any:
            plant = Planting(table, n)
            world.resources["replay_feet"] = plant

            def plant_feet(world, h):
                plant.step(world.state, replay.track, planted, h)

            world.schedule.add_step("replay_feet", plant_feet, after=("replay", "animation"),
                                    before=("terrain_follow",))
