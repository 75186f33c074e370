"""A scene's plan: its characters built and its agents placed, nothing installed, no GL (``crowd validate``,
the engine's first step, the benchmarks that need the start positions).

:func:`plan` refuses, in one sentence naming the scene and key, what a run would refuse while building: a scene
too big for the machine (``crowd.memory``), a character file the code cannot load (``crowd.characters``), an
unknown clip, a placement its builder rejects, agents outside a routing area (``crowd.start_check``).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from crowd.characters import build_scene_character, clip_duration, clip_names
from crowd.errors import SceneError
from crowd.scene import Scene
from crowd.start_check import check_walkable
from sim.params import ParamError

#: show a progress bar for character building when the scene has at least this many characters
#: or this many triangles in all
PROGRESS_MIN_CHARACTERS = 3
PROGRESS_MIN_TRIANGLES = 200_000


@dataclass
class Plan:
    """Characters and the initial CrowdState of a scene (built, nothing installed).

    characters : list of sim.character.Character, index = CrowdState.character
    state : sim.state.CrowdState of all placements concatenated
    agents_per_placement : list of int
    """

    scene: Scene
    characters: list
    state: object
    agents_per_placement: list = field(default_factory=list)
    big: bool = False  # long builds: show progress bars

    def triangles(self, character_index: int) -> int:
        ch = self.characters[character_index]
        if ch.kind == "skinned":
            return int(ch.mesh.n_triangles)
        anims = list(ch.animations.values())
        return int(max((max(s.indices.shape[0] for s in a.segments) for a in anims if a.segments), default=0))

    def triangles_per_frame(self) -> int:
        """Triangles drawn per frame at full detail (lod mode "none", nothing culled)."""
        counts = np.bincount(self.state.character, minlength=len(self.characters))
        return int(sum(int(counts[i]) * self.triangles(i) for i in range(len(self.characters))))

    def summary_lines(self) -> list:
        s = self.scene
        lines = [f"characters: {len(self.characters)} ("
                 + ", ".join(f"{c.name}: {self.triangles(i)} triangles, clips {', '.join(clip_names(c)) or '-'}"
                             for i, c in enumerate(self.characters)) + ")",
                 f"agents: {self.state.n} in {len(self.agents_per_placement)} placement group(s) "
                 f"({', '.join(map(str, self.agents_per_placement))})",
                 f"effects: {', '.join(s.effect_names) or 'none'}",
                 *([f"props: {sum(p.instances for p in s.props)} of {len(s.props)} mesh file(s) ("
                    + ", ".join(f"{p.name}: {p.instances} x {p.triangles} triangles" for p in s.props) + ")"]
                   if s.props else []),
                 f"triangles per frame (full detail, before culling): {self.triangles_per_frame():,}",
                 f"frames: {s.frames} at dt {s.dt:g} s x {s.substeps} substep(s); "
                 f"{s.render.size[0]}x{s.render.size[1]}; lod {s.lod_mode!r}; output {s.output_dir}"]
        return lines


def plan(scene: Scene, quiet: bool = True) -> Plan:
    """Build a scene's characters and agents; check clip names.

    Raises
    ------
    crowd.errors.SceneError
        An unknown clip (``placement[i].clip``) or a placement its builder rejects.
    sim.errors.AssetError
        A broken glTF file.
    """
    from crowd.memory import guard
    from sim.placement import PLACEMENTS, concat_states

    guard(scene)  # refuse a scene too big for the machine before building anything
    specs = scene.characters
    big = len(specs) >= PROGRESS_MIN_CHARACTERS or sum(c.triangles or 0 for c in specs) >= PROGRESS_MIN_TRIANGLES
    chars = []
    for i, spec in enumerate(progress_bar(specs, "characters", disable=quiet or not big)):
        chars.append(build_scene_character(scene.path, i, spec))
    guard(scene, chars)  # again with the built characters, before allocating the agents
    seeds = np.random.SeedSequence(scene.seed).spawn(len(scene.placements))
    states, counts = [], []
    for p, ss in zip(scene.placements, seeds):
        where = f"placement[{p.index}]"
        ch = chars[p.character]
        names = clip_names(ch)
        if not names:
            raise SceneError(scene.path, f"{where}.character",
                             f"character {scene.characters[p.character].name!r} has no animation clip")
        if p.clip is None:
            ci = 0
        elif p.clip in names:
            ci = names.index(p.clip)
        else:
            raise SceneError(scene.path, f"{where}.clip", f"unknown clip {p.clip!r} of character "
                             f"{scene.characters[p.character].name!r}; accepted: {', '.join(map(repr, names))}")
        build = PLACEMENTS[p.kind][1]
        params = p.params
        if p.kind == "trajectories":  # each recorded person's character, clip and scale, chosen by weight
            params = {**p.params, "choice_table": _choice_table(scene, chars, p, where)}
        try:
            st = build(params, p.character, ci, np.random.default_rng(ss), clip_duration(ch, ci))
        except ParamError as e:
            raise SceneError(scene.path, f"{where}.{e.key}", e.message) from None
        if p.kind != "trajectories":  # (a recording's agents carry their character's scale: sim.replay)
            st.scale[:] = st.scale * np.float32(scene.characters[p.character].scale)
        states.append(st)
        counts.append(st.n)
    state = concat_states(states)
    check_walkable(scene, state)  # crowd validate refuses what crowd run would (crowd.start_check)
    return Plan(scene, chars, state, counts, big)


def _choice_table(scene: Scene, chars: list, p, where: str) -> list:
    """``[(character, clip, weight, character scale, clip duration), ...]`` of a trajectories placement's
    character choice (``params["choices"]``): each character plays the placement's clip (its first without one)."""
    out = []
    for c, w in p.params.get("choices") or [(p.character, 1.0)]:
        names = clip_names(chars[c])
        if not names:
            raise SceneError(scene.path, f"{where}.character",
                             f"character {scene.characters[c].name!r} has no animation clip")
        if p.clip is not None and p.clip not in names:
            raise SceneError(scene.path, f"{where}.clip", f"unknown clip {p.clip!r} of character "
                             f"{scene.characters[c].name!r}; accepted: {', '.join(map(repr, names))}")
        k = names.index(p.clip) if p.clip is not None else 0
        out.append((int(c), k, float(w), float(scene.characters[c].scale), float(clip_duration(chars[c], k) or 0.0)))
    return out


def progress_bar(it, desc: str, disable: bool, total: int | None = None):
    """tqdm over ``it`` on a terminal's stderr (nothing elsewhere or when ``disable``), closed when it ends."""
    from tqdm import tqdm

    return tqdm(it, desc=desc, total=total, disable=disable or not sys.stderr.isatty(), leave=False,
                file=sys.stderr, dynamic_ncols=True)
