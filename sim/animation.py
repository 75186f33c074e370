"""Effect ``animation``: advance every agent's clip time and wrap it.

Per step, for each agent ``i`` playing clip ``c`` of character ``h``::

    anim_time[i] += dt * rate * anim_rate[i]
    anim_time[i]  = anim_time[i] mod duration[h, c]        (looping clips)
                  = clamp(anim_time[i], 0, duration[h, c])  (one-shot clips)

A zero (or invalid) duration, or a character/clip index outside the table,
gives time 0, so no NaN/Inf ever reaches the state. Durations are gathered per
agent from a small (characters x clips) lookup table built at install time
(rebuilt if ``world.characters`` changes length).

The step is a numba kernel (``_advance_kernel``); :func:`advance_reference`
is the plain numpy reference the tests compare it with.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from sim.params import Param

PARAMS: dict[str, Param] = {
    "rate": Param("float", 1.0, min=0.0, max=100.0,
                  doc="global playback-rate multiplier applied on top of CrowdState.anim_rate"),
}


class ClipTable:
    """Durations and loop flags of every (character, clip) pair.

    duration : (C, M) float64, seconds (0 for missing clips)
    loop : (C, M) bool
    speed : (C, M) float64, natural ground speed of skinned clips (m/s, 0 if none)
    """

    def __init__(self, characters):
        self.n_characters = len(characters)
        clip_lists = [_clips_of(c) for c in characters]
        m = max([len(c) for c in clip_lists] + [1])
        C = max(len(characters), 1)
        self.duration = np.zeros((C, m), np.float64)
        self.loop = np.ones((C, m), np.bool_)
        self.speed = np.zeros((C, m), np.float64)
        for i, clips in enumerate(clip_lists):
            for k, clip in enumerate(clips):
                d = float(getattr(clip, "duration", 0.0) or 0.0)
                self.duration[i, k] = d if np.isfinite(d) and d > 0 else 0.0
                self.loop[i, k] = bool(getattr(clip, "loop", True))
                s = float(getattr(clip, "speed", 0.0) or 0.0)
                self.speed[i, k] = s if np.isfinite(s) and s > 0 else 0.0

    def gather(self, character: np.ndarray, clip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(duration (n,) float64, loop (n,) bool) per agent; invalid indices -> (0, True)."""
        ch = np.asarray(character, np.int64)
        cl = np.asarray(clip, np.int64)
        ok = (ch >= 0) & (ch < self.duration.shape[0]) & (cl >= 0) & (cl < self.duration.shape[1])
        chs, cls = np.where(ok, ch, 0), np.where(ok, cl, 0)
        return np.where(ok, self.duration[chs, cls], 0.0), np.where(ok, self.loop[chs, cls], True)


def _clips_of(character) -> list:
    clips = getattr(character, "clips", None)
    if clips is None:
        clips = getattr(character, "animations", None) or {}
    return list(clips.values())


def advance_reference(anim_time, anim_rate, character, clip, table: ClipTable, dt: float, rate: float = 1.0) -> np.ndarray:
    """Numpy reference of one animation step: the new anim_time (n,) float64."""
    dur, loop = table.gather(character, clip)
    t = np.asarray(anim_time, np.float64) + dt * rate * np.asarray(anim_rate, np.float64)
    t = np.where(np.isfinite(t), t, 0.0)
    ok = dur > 0
    safe = np.where(ok, dur, 1.0)
    wrapped = np.where(loop, np.mod(t, safe), np.clip(t, 0.0, safe))
    # np.mod may return exactly ``safe`` for tiny negative t; keep [0, duration)
    wrapped = np.where(loop & (wrapped >= safe), 0.0, wrapped)
    return np.where(ok, wrapped, 0.0)


@njit(cache=True, parallel=True)
def _advance_kernel(anim_time, anim_rate, character, clip, duration, loop, step):
    n = anim_time.shape[0]
    C, M = duration.shape
    for i in prange(n):
        h = character[i]
        c = clip[i]
        d = 0.0
        lp = True
        if h >= 0 and h < C and c >= 0 and c < M:
            d = duration[h, c]
            lp = loop[h, c]
        t = anim_time[i] + step * float(anim_rate[i])
        if not np.isfinite(t) or not (d > 0.0):
            anim_time[i] = 0.0
            continue
        if lp:
            t = t - np.floor(t / d) * d
            if t >= d or t < 0.0:
                t = 0.0
        else:
            t = min(max(t, 0.0), d)
        anim_time[i] = t


def advance(state, table: ClipTable, dt: float, rate: float = 1.0) -> None:
    """Advance ``state.anim_time`` in place by one step (numba kernel)."""
    if state.n == 0:
        return
    _advance_kernel(state.anim_time, state.anim_rate, state.character, state.clip,
                    table.duration, table.loop, float(dt) * float(rate))


def install(world, cfg: dict) -> None:
    """Effect ``animation``: adds step ``"animation"``.

    Publishes ``world.resources["animation"]``, the :class:`ClipTable`
    (durations, loop flags and ground speeds per character and clip).
    """
    rate = float(cfg.get("rate", 1.0))
    world.resources["animation"] = ClipTable(world.characters)

    def step(w, dt):
        table = w.resources.get("animation")
        if not isinstance(table, ClipTable) or table.n_characters != len(w.characters):
            table = w.resources["animation"] = ClipTable(w.characters)
        advance(w.state, table, dt, rate)

    world.schedule.add_step("animation", step)
