"""How far a replayed person's feet slide (issue 47, item 3): the stance foot, measured from the skinned feet.

A person walks without sliding when the foot on the ground stays put in the world while it bears the weight. The
replay advances each person's walk clip by their recorded ground speed over the clip's natural speed
(``sim.replay.track``; the generated humanoid's ``Clip.speed`` is itself measured from its stance foot,
``sim.procedural``). What is left to slide comes from what the recording does that a straight walk at constant
speed does not: turning, speeding up, standing, the sway of a tracked head.

Measure, per person and foot: the foot's contact point is the lower of its foot and toe joints in the skinned
skeleton (``Skeleton.joint_positions`` of the clip at the person's animation time), carried into the world by the
person's instance transform (``lod.full.pack.model_rows``: yaw about +Y, 0 facing +Z, uniform scale). A *stance* is
a run of at least :data:`MIN_STANCE_FRAMES` frames in which the contact point is within :data:`STANCE_HEIGHT` of
its lowest height over the clip; a *step's drift* is how far (floor plane) the contact point moved from the first
to the last frame of its stance. :func:`stance_drifts` gives every step's drift of one person's frames.
"""
from __future__ import annotations

import numpy as np

#: a foot is on the ground while its contact point is within this of its lowest height over the clip, metres
STANCE_HEIGHT = 0.01
#: fewest frames of a stance that counts as a step
MIN_STANCE_FRAMES = 3
#: clip samples over which the lowest height of a contact point is taken
CLIP_SAMPLES = 256


def feet_joints(skeleton) -> list:
    """``[(foot, toe), ...]`` joint indices of the feet of a skeleton with joints ``l_foot``/``l_toe`` and
    ``r_foot``/``r_toe`` (the generated humanoid), or ``[]``."""
    names = list(getattr(skeleton, "names", []) or [])
    out = []
    for side in ("l", "r"):
        if f"{side}_foot" in names and f"{side}_toe" in names:
            out.append((names.index(f"{side}_foot"), names.index(f"{side}_toe")))
    return out


def contact_points(skeleton, clip, times, feet) -> np.ndarray:
    """(N, F, 3) model-space contact point of each foot of ``feet`` at clip times ``times``: its foot or toe joint,
    whichever is lower."""
    pos = skeleton.joint_positions(*clip.sample_times(skeleton, np.asarray(times, np.float64)))
    out = np.empty((pos.shape[0], len(feet), 3))
    for k, (foot, toe) in enumerate(feet):
        a, b = pos[:, foot], pos[:, toe]
        out[:, k] = np.where((a[:, 1] <= b[:, 1])[:, None], a, b)
    return out


def stance_drifts(skeleton, clip, position, heading, scale, anim_time) -> np.ndarray:
    """Every step's drift (metres) of one person over consecutive frames (module docstring).

    position : (N, 3) world positions; heading : (N,) yaw; scale : (N,) uniform scale; anim_time : (N,) seconds
    into ``clip``. Returns (S,) float64, one per stance of either foot that lies wholly inside the frames.
    """
    return stances(skeleton, clip, position, heading, scale, anim_time)[:, 0]


def stances(skeleton, clip, position, heading, scale, anim_time) -> np.ndarray:
    """(S, 3) float64 rows (drift metres, first frame, frames) of every step of one person (:func:`stance_drifts`)."""
    feet = feet_joints(skeleton)
    if not feet or len(anim_time) < MIN_STANCE_FRAMES:
        return np.zeros((0, 3))
    model = contact_points(skeleton, clip, anim_time, feet)  # (N, F, 3)
    lowest = contact_points(skeleton, clip, np.linspace(0.0, clip.duration, CLIP_SAMPLES), feet)[:, :, 1].min(0)
    h = np.asarray(heading, np.float64)[:, None]
    s = np.asarray(scale, np.float64)[:, None]
    c, n = np.cos(h) * s, np.sin(h) * s
    px, pz = model[:, :, 0], model[:, :, 2]
    pos = np.asarray(position, np.float64)
    wx = c * px + n * pz + pos[:, 0:1]
    wz = -n * px + c * pz + pos[:, 2:3]
    out = []
    for k in range(len(feet)):
        down = model[:, k, 1] <= lowest[k] + STANCE_HEIGHT
        edges = np.flatnonzero(np.diff(np.r_[0, down.astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2]):  # stance frames a .. b-1
            if a == 0 or b == len(down) or b - a < MIN_STANCE_FRAMES:
                continue  # cut by the recording's ends, or too short to be a step
            out.append((float(np.hypot(wx[b - 1, k] - wx[a, k], wz[b - 1, k] - wz[a, k])), a, b - a))
    return np.asarray(out, np.float64).reshape(-1, 3)


def replay_drifts(engine, frames: int) -> np.ndarray:
    """Step the engine ``frames`` frames and return the drift of every step of every recorded person
    (:func:`stance_drifts` over each person's frames; people whose character has no such feet are left out)."""
    return replay_steps(engine, frames)[:, 0]


def replay_steps(engine, frames: int) -> np.ndarray:
    """(S, 2) rows (drift metres, the person's mean recorded ground speed over the stance, m/s) of every step of
    every recorded person over ``frames`` frames of ``engine`` (:func:`replay_drifts`)."""
    w = engine.world
    rec: dict = {}
    for _ in range(frames):
        engine.step()
        st = engine.drawn_state()  # (planted feet: the drawn positions, sim.replay.planting)
        v = w.state.velocity
        for a, i in enumerate(st.ids.tolist()):
            rec.setdefault(i, []).append((st.position[a].copy(), float(st.heading[a]), float(st.scale[a]),
                                          float(st.anim_time[a]), int(st.character[a]), int(st.clip[a]),
                                          float(np.hypot(v[a, 0], v[a, 2]))))
    out = []
    for rows in rec.values():
        ch = w.characters[rows[0][4]]
        clips = list(getattr(ch, "clips", {}).values())
        skeleton = getattr(ch, "skeleton", None)
        if skeleton is None or not clips:
            continue
        s = stances(skeleton, clips[rows[0][5]], np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                    np.array([r[2] for r in rows]), np.array([r[3] for r in rows]))
        speed = np.array([r[6] for r in rows])
        out.append(np.column_stack([s[:, 0], [speed[int(a):int(a + n)].mean() for _, a, n in s]]).reshape(-1, 2))
    return np.concatenate(out) if out else np.zeros((0, 2))
